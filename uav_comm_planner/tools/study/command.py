"""The command line of a Monte Carlo study: ``uav-comm-planner montecarlo`` (and
``python -m uav_comm_planner.tools.study``): its options, the design they describe, the run,
its summary and the figures.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
import sys
from typing import Sequence

from uav_comm_planner.core.drops import AREAS
from uav_comm_planner.core.fading import DEFAULT_K_DB, DEFAULT_SAMPLES, Fading, FADING_MODELS
from uav_comm_planner.errors import PlannerError
from uav_comm_planner.tools.plots import make_folder
from uav_comm_planner.tools.study.design import ENDPOINTS, SETTINGS, StudyDesign, StudyError
from uav_comm_planner.tools.study.methods import METHODS
from uav_comm_planner.tools.study.runner import (format_run, INSTALL_HINT, MAX_BATCH,
                                                 measure_scaling, require_extra, run_study)
from uav_comm_planner.tools.study.tables import open_table, read_table, saved_design, summary

DESCRIPTION = ('Monte Carlo study: random scenarios planned by every method on Dask, '
               'streamed to a Parquet or CSV table; resumable; CDF and gain figures')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``uav-comm-planner montecarlo``."""
    design = parser.add_argument_group(
        'study design', 'settings take a value (5), a grid (1,2,5: every value, crossed with '
        'the other grids) or a range drawn per scenario (4:12, or 0.5:20:log); write negative '
        'values as --noise-dbm=-170:-160')
    design.add_argument('--cases', type=int, default=None,
                        help='random drops per grid point (default 100)')
    design.add_argument('--seed', type=int, default=None, help='study seed (default 0)')
    for name, setting in SETTINGS.items():
        default = 'M seconds' if setting.default is None else setting.default
        design.add_argument(setting.flag, dest=f'draw_{name}', metavar='VALUE|A,B|LOW:HIGH',
                            default=None, help=f'{setting.help} (default {default})'
                            if setting.default is not None else setting.help)
    design.add_argument('--area', choices=AREAS, default=None,
                        help='nodes uniform in the square or in the disc inscribed in it '
                             '(default square)')
    design.add_argument('--endpoints', choices=tuple(ENDPOINTS), default=None,
                        help='start and goal: diagonal (0,0)->(side,side), across '
                             '(0,side/2)->(side,side/2), centre (a loop from the centre), '
                             'random (both uniform in the area); default diagonal')
    design.add_argument('--methods', default=None, metavar='NAME,NAME',
                        help=f'methods to run, of {",".join(METHODS)} (default all)')
    design.add_argument('--fading', choices=FADING_MODELS, default=None,
                        help='also judge every plan by Monte Carlo over this fading '
                             '(docs/channel.md): its ergodic min throughput and spread per case')
    design.add_argument('--fading-samples', type=int, default=None, metavar='N',
                        help=f'draws of the fading per case (default {DEFAULT_SAMPLES})')
    design.add_argument('--rician-k-db', type=float, default=None, metavar='K',
                        help=f'Rician factor of a line-of-sight link, dB (default '
                             f'{DEFAULT_K_DB:g})')
    run = parser.add_argument_group('running')
    run.add_argument('--out', type=Path, default=None, metavar='TABLE.parquet|TABLE.csv',
                     help='the table: a .parquet folder of parts or a .csv file; an existing '
                          'table of the same study is resumed (default study.parquet)')
    run.add_argument('--workers', type=int, default=None,
                     help='worker processes of the embedded cluster (default: one per core)')
    run.add_argument('--scheduler', default=None, metavar='tcp://HOST:8786',
                     help='run on this existing Dask cluster instead')
    run.add_argument('--batch', type=int, default=None,
                     help=f'scenarios per task (default: about 8 tasks per worker, at most '
                          f'{MAX_BATCH})')
    run.add_argument('--limit', type=int, default=None,
                     help='plan at most this many rows now; the next run goes on')
    run.add_argument('--quiet', action='store_true', help='no progress line')
    figures = parser.add_argument_group('figures (PDF or PNG by suffix)')
    figures.add_argument('--figure', type=Path, default=None, metavar='CDF.pdf|CDF.png',
                         help='the CDF of the min throughput of every method')
    figures.add_argument('--figures-dir', type=Path, default=None, metavar='DIR',
                         help='write cdf, gain and time figures into DIR')
    figures.add_argument('--figure-format', choices=('pdf', 'png'), default='pdf',
                         help='format of the figures in --figures-dir (default pdf)')
    figures.add_argument('--gain-against', choices=tuple(SETTINGS), default=None,
                         help='setting on the gain figure\'s x axis (default: the first '
                              'swept setting, N when nothing is swept)')
    scaling = parser.add_argument_group('measuring')
    scaling.add_argument('--scaling', action='store_true',
                         help='instead of a table: time the study (in a temporary folder) '
                              'with 1 worker and with --workers (default all cores), '
                              'alternating, and print scenarios/s and the speed-up')
    scaling.add_argument('--repeats', type=int, default=3,
                         help='rounds of --scaling (default 3)')
    scaling.add_argument('--quick', action='store_true',
                         help='a small design (40 drops, N 2:4, M 20) unless set otherwise')


QUICK = {'cases': 40, 'draw_nodes': '2:4', 'draw_slots': '20', 'draw_side_m': '800'}


def design_from_args(args: argparse.Namespace, saved: StudyDesign | None) -> StudyDesign:
    """The design the options describe. With none of the design options, an existing
    table's own design (``--cases`` may still change it)."""
    options = {name: getattr(args, f'draw_{name}') for name in SETTINGS}
    others = {name: getattr(args, name) for name in ('seed', 'area', 'endpoints', 'methods',
                                                     'fading', 'fading_samples', 'rician_k_db')}
    if saved is not None and all(v is None for v in (*options.values(), *others.values())):
        if args.cases is None:
            return saved
        return StudyDesign(cases=args.cases, seed=saved.seed, draws=saved.draws,
                           area=saved.area, endpoints=saved.endpoints, methods=saved.methods,
                           fading=saved.fading)
    if args.quick:
        for key, value in QUICK.items():
            if key.startswith('draw_') and options[key[5:]] is None:
                options[key[5:]] = value
    draws = {name: value for name, value in options.items() if value is not None}
    if options['horizon_s'] is None:
        draws['horizon_s'] = None
    cases = args.cases if args.cases is not None else QUICK['cases'] if args.quick else 100
    methods = tuple(m.strip() for m in others['methods'].split(',')) \
        if others['methods'] else tuple(METHODS)
    return StudyDesign(cases=cases, seed=0 if others['seed'] is None else others['seed'],
                       draws=draws, area=others['area'] or 'square',
                       endpoints=others['endpoints'] or 'diagonal', methods=methods,
                       fading=_fading(others))


def _fading(options: dict) -> Fading | None:
    """The fading --fading asks for; --fading-samples or --rician-k-db alone are refused."""
    if options['fading'] is None:
        given = [flag for flag, name in (('--fading-samples', 'fading_samples'),
                                         ('--rician-k-db', 'rician_k_db'))
                 if options[name] is not None]
        if given:
            raise StudyError(f'{given[0]} needs --fading rician|rayleigh')
        return None
    return Fading(options['fading'],
                  DEFAULT_K_DB if options['rician_k_db'] is None else options['rician_k_db'],
                  DEFAULT_SAMPLES if options['fading_samples'] is None
                  else options['fading_samples'])


def draw_figures(args: argparse.Namespace, out: Path) -> list[Path]:
    """The figures the options ask for, from the table at ``out``."""
    if args.figure is None and args.figures_dir is None:
        return []
    # The figures (scipy.stats, then matplotlib) load only when one is asked for.
    from uav_comm_planner.tools.study import plots
    design, rows = read_table(out)
    written = []
    if args.figure is not None:
        written.append(plots.cdf_figure(design, rows, args.figure))
    if args.figures_dir is not None:
        written += plots.all_figures(design, rows, args.figures_dir,
                                     fmt=args.figure_format, against=args.gain_against)
    return written


def command(args: argparse.Namespace) -> int:
    """``uav-comm-planner montecarlo``: exit 0 done, 2 bad input, 130 interrupted."""
    out = args.out or Path('study.parquet')
    require_extra(parquet=args.scaling or out.suffix.lower() == '.parquet')
    for path in (args.figure,):
        if path is not None and path.suffix.lower() not in ('.pdf', '.png'):
            raise StudyError(f'--figure {str(path)!r}: name a .pdf or .png file')
    if args.figure is not None or args.figures_dir is not None:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise StudyError(f'figures need matplotlib: {INSTALL_HINT}') from None
    # Made before the study runs, so that a folder that cannot be made fails at once.
    for folder in (args.figure.parent if args.figure else None, args.figures_dir):
        if folder is not None:
            make_folder(folder)
    if args.scaling:
        if args.repeats < 1:
            raise StudyError(f'--repeats must be >= 1, got {args.repeats}')
        design = design_from_args(args, None)
        counts = sorted({1, args.workers or os.cpu_count() or 1})
        print(f'scaling of {design.total_rows} scenarios ({", ".join(design.swept) or "fixed"}'
              f' swept), {args.repeats} rounds, workers {counts}', flush=True)
        measure_scaling(design, counts, args.repeats, batch_size=args.batch)
        return 0
    design = design_from_args(args, saved_design(out))
    try:
        run = run_study(design, out, workers=args.workers, scheduler=args.scheduler,
                        batch_size=args.batch, limit=args.limit,
                        progress=None if args.quiet else sys.stderr)
    except KeyboardInterrupt:
        _, done = open_table(out, design)
        print(f'\ninterrupted: {len(done)} of {design.total_rows} rows are in {out}; run the '
              'same command to go on', file=sys.stderr)
        return 130
    print(format_run(run))
    design, rows = read_table(out)
    print(summary(design, rows))
    for path in draw_figures(args, out):
        print(f'wrote {path}')
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``python -m uav_comm_planner.tools.study``: the montecarlo options."""
    parser = argparse.ArgumentParser(prog='python -m uav_comm_planner.tools.study',
                                     description=DESCRIPTION)
    add_arguments(parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m uav_comm_planner.tools.study``; a bad input ends with one line and status 2."""
    args = build_parser().parse_args(argv)
    try:
        return command(args)
    except PlannerError as exc:
        print(f'montecarlo: error: {exc}', file=sys.stderr)
        return 2
