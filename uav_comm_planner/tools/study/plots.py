"""Figures of a Monte Carlo study, drawn from its table; matplotlib is imported only here, and
only when a figure is drawn.

* :func:`cdf_figure`: the empirical CDF of min_n R_n of every method over the scenarios.
* :func:`gain_figure`: the mean gain of each optimised method over each baseline,
  100 (R_method / R_baseline - 1) %, against a setting, with 95 % confidence intervals.
* :func:`time_figure`: the solve time of each optimised method against M.

Only rows with status 'ok' (every method succeeded) are drawn, so that each method is shown
on the same scenarios.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

import numpy as np
from scipy import stats

from uav_comm_planner.errors import PlannerError
from uav_comm_planner.tools.plots import _pyplot, save_figure
from uav_comm_planner.tools.study.design import SETTINGS, StudyDesign
from uav_comm_planner.tools.study.methods import BASELINES, METHODS

#: Confidence level of the intervals.
CONFIDENCE = 0.95
#: A setting with more distinct values than this is grouped into this many equal-count bins.
MAX_GROUPS = 8
STYLES = {'default': 'o-', 'letter': 's--'}
LINES = {'default': '-', 'letter': '--', 'straight': ':', 'static': '-.',
         'bound': (0, (6, 2, 1, 2))}


def _ok(rows: Sequence[dict]) -> list[dict]:
    ok = [row for row in rows if row['status'] == 'ok']
    if not ok:
        raise PlannerError('the study has no row where every method succeeded; nothing to draw')
    return ok


def optimised_methods(design: StudyDesign) -> list[str]:
    """The methods that plan a trajectory (not a baseline, not the bound)."""
    return [m for m in design.methods if m not in BASELINES and m != 'bound']


def mean_interval(values: np.ndarray, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Sample mean and the half-width of its Student-t interval, t_{(1+c)/2, n-1} s / sqrt(n)
    (NaN half-width for one value)."""
    values = np.asarray(values, dtype=float)
    mean = float(values.mean())
    if values.size < 2:
        return mean, float('nan')
    spread = float(values.std(ddof=1)) / np.sqrt(values.size)
    return mean, float(stats.t.ppf(0.5 + confidence / 2.0, values.size - 1) * spread)


def groups(x: np.ndarray, max_groups: int = MAX_GROUPS) -> list[np.ndarray]:
    """Index arrays of the rows sharing each value of ``x`` (sorted), or of ``max_groups``
    equal-count bins of it when it takes more values (a drawn range)."""
    values = np.unique(x)
    if values.size <= max_groups:
        return [np.flatnonzero(x == value) for value in values]
    order = np.argsort(x, kind='stable')
    return [chunk for chunk in np.array_split(order, max_groups) if chunk.size]


def gain_table(design: StudyDesign, rows: Sequence[dict], against: str
               ) -> dict[tuple[str, str], list[tuple[float, float, float, int]]]:
    """{(method, baseline): [(x, mean gain %, CI half-width %, n), ...]} by group of the
    setting ``against`` (x is the group's mean setting)."""
    ok = _ok(rows)
    x = np.array([row[against] for row in ok], dtype=float)
    index_groups = groups(x)
    table = {}
    for method in optimised_methods(design):
        for baseline in (b for b in BASELINES if b in design.methods):
            value = np.array([row[f'{method}_bps'] for row in ok])
            base = np.array([row[f'{baseline}_bps'] for row in ok])
            gain = 100.0 * (value / np.where(base > 0, base, np.nan) - 1.0)
            points = []
            for members in index_groups:
                finite = members[np.isfinite(gain[members])]
                if finite.size:
                    mean, half = mean_interval(gain[finite])
                    points.append((float(x[finite].mean()), mean, half, int(finite.size)))
            table[(method, baseline)] = points
    return table


def cdf_figure(design: StudyDesign, rows: Sequence[dict], path: str | os.PathLike) -> Path:
    """Empirical CDF of the min throughput of every method over the study's scenarios."""
    ok = _ok(rows)
    plt = _pyplot()
    figure, ax = plt.subplots(figsize=(6.4, 4.6))
    lowest, highest = np.inf, 0.0
    for method in design.methods:
        values = np.sort([row[f'{method}_bps'] for row in ok])
        fraction = np.arange(1, values.size + 1) / values.size
        ax.step(values, fraction, where='post', label=METHODS[method].label,
                linestyle=LINES.get(method, '-'))
        positive = values[values > 0]
        if positive.size:
            lowest, highest = min(lowest, positive[0]), max(highest, positive[-1])
    if highest > 0 and highest / lowest > 30:
        ax.set_xscale('log')
    ax.set(xlabel='min average throughput (bit/s)', ylabel='fraction of scenarios',
           title=f'CDF over {len(ok)} random scenarios', ylim=(0, 1.02))
    ax.grid(True, alpha=0.3)
    ax.legend(loc='best', fontsize=8)
    figure.tight_layout()
    return save_figure(figure, path)


def gain_figure(design: StudyDesign, rows: Sequence[dict], path: str | os.PathLike, *,
                against: str = 'nodes') -> Path:
    """Mean gain over each baseline against ``against``, with 95 % confidence intervals."""
    if against not in SETTINGS:
        raise PlannerError(f'cannot draw against {against!r}; choose one of {list(SETTINGS)}')
    table = gain_table(design, rows, against)
    baselines = [b for b in BASELINES if b in design.methods]
    if not table or not baselines:
        raise PlannerError('the gain figure needs an optimised method and a baseline')
    plt = _pyplot()
    figure, axes = plt.subplots(1, len(baselines), figsize=(6.0 * len(baselines), 4.4),
                                squeeze=False)
    for ax, baseline in zip(axes[0], baselines):
        for method in optimised_methods(design):
            x, mean, half, _ = np.array(table[(method, baseline)]).T
            ax.errorbar(x, mean, yerr=np.nan_to_num(half), fmt=STYLES.get(method, 'o-'),
                        capsize=3, label=METHODS[method].label)
        ax.set(xlabel=f'{SETTINGS[against].help}', ylabel='mean gain (%)',
               title=f'over the {METHODS[baseline].label}')
        ax.grid(True, alpha=0.3)
        ax.legend(loc='best', fontsize=8)
    figure.suptitle(f'mean gain with {100 * CONFIDENCE:.0f} % confidence intervals')
    figure.tight_layout()
    return save_figure(figure, path)


def time_figure(design: StudyDesign, rows: Sequence[dict], path: str | os.PathLike) -> Path:
    """Solve time of each optimised method against M: every scenario, and the mean per group
    with its 95 % confidence interval."""
    ok = _ok(rows)
    methods = optimised_methods(design)
    if not methods:
        raise PlannerError('the time figure needs an optimised method')
    plt = _pyplot()
    figure, ax = plt.subplots(figsize=(6.4, 4.6))
    slots = np.array([row['slots'] for row in ok], dtype=float)
    for method in methods:
        seconds = np.array([row[f'{method}_s'] for row in ok], dtype=float)
        dots = ax.plot(slots, seconds, '.', alpha=0.25)[0]
        points = [(slots[m].mean(), *mean_interval(seconds[m])) for m in groups(slots)]
        x, mean, half = np.array(points).T
        ax.errorbar(x, mean, yerr=np.nan_to_num(half), fmt=STYLES.get(method, 'o-'),
                    color=dots.get_color(), capsize=3, label=METHODS[method].label)
    ax.set_yscale('log')
    ax.set(xlabel='number of slots M', ylabel='solve time (s)',
           title='solve time per scenario (one worker core)')
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(loc='best', fontsize=8)
    figure.tight_layout()
    return save_figure(figure, path)


def default_against(design: StudyDesign) -> str:
    """The first swept setting, N when nothing is swept."""
    swept = [name for name in design.swept if name != 'side_m'] or design.swept
    return swept[0] if swept else 'nodes'


def all_figures(design: StudyDesign, rows: Sequence[dict], folder: str | os.PathLike, *,
                fmt: str = 'pdf', against: str | None = None) -> list[Path]:
    """cdf.FMT, gain_vs_SETTING.FMT and time_vs_slots.FMT in ``folder``."""
    folder = Path(folder)
    against = against or default_against(design)
    written = [cdf_figure(design, rows, folder / f'cdf.{fmt}')]
    if optimised_methods(design):
        if any(b in design.methods for b in BASELINES):
            written.append(gain_figure(design, rows, folder / f'gain_vs_{against}.{fmt}',
                                       against=against))
        written.append(time_figure(design, rows, folder / f'time_vs_slots.{fmt}'))
    return written
