"""Benchmark: the reference path against the fast path, and the default plan against the letter's.

* Speed: Algorithm 1 from the straight line (the letter's settings, baselines off) on the
  reference path (cvxpy + Clarabel for both steps, problems rebuilt every step) and on the fast
  path (water-filling power step, SCA step on one Clarabel solver updated in place), timed in
  alternation in one process. Every fast plan builds its own Clarabel solver; the sparsity
  pattern of its cone program, a function of N and M only, is kept between plans as in a
  running planner, and a third column times plans that build it again (the first plan of a
  size) and builds its Clarabel solvers again. Peak
  memory is the growth of the peak resident set (VmHWM) of a freshly spawned process that
  plans once, so it counts the solvers' native memory too.
* Scaling: the fast path for N = 20 and a growing number of slots M, with slots of 1 s and
  over one 200 s flight, with the least-squares exponent of M on a log-log scale.
* Speed of the default plan: the same settings on the reference path and on the fast path
  (loose steps and the solvers kept between plans only help the fast path).
* Replans in flight: the node's replan of the rest of a mission, warm and with the full search
  (:mod:`devtools.replans`), for ArduCopter and for PX4.
* Quality: on seeded random drops, the default plan against the letter's Algorithm 1 and the
  best known plan, with the dual upper bound (:mod:`uav_comm_planner.core.bound`) and its gap.
* Fleets: K = 1, 2, 3 UAVs planned jointly over one drop, N = 20, M = 500
  (:mod:`devtools.fleet_bench`).

Run ``make bench`` or, from the checkout, ``python -m devtools.bench`` (``--quick`` for a
smaller run).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
import functools
import math
import multiprocessing
import os
import platform
import statistics
import sys
import time
from typing import Callable, Sequence, TextIO

import numpy as np
from scipy.special import betaincinv

from devtools.energy_bench import energy_table
from devtools.fleet_bench import fleet_table
from devtools.flights import flight_cases, fly_case, format_flights
from devtools.replans import (format_replan_drops, format_replans, measure_replan_drops,
                              measure_replans, REPLAN_POINTS)
from devtools.sitl import why_not_runnable
from uav_comm_planner.core.drops import random_scenario
from uav_comm_planner.core.sca.program import clear_programs
from uav_comm_planner.core.sca.fast import SOLVERS
from uav_comm_planner.core.optimizer import alternate, plan, PlanResult
from uav_comm_planner.core.steps import step_solvers
from uav_comm_planner.core.scenario import paper_scenario, Scenario, SolverSettings
from uav_comm_planner.core.tours import random_tours, scenario_seed

REFERENCE = dict(power_method='conic', trajectory_method='cvxpy')
FAST = dict(power_method='waterfilling', trajectory_method='clarabel')
LOW_SNR = dict(bandwidth_hz=1e6, reference_gain=1e-6)
#: A drop counts as within the best known when the default is at most this share below it.
WITHIN_BEST = 1e-3
#: The share of drops the default should be within :data:`WITHIN_BEST` of the best known in.
QUALITY_TARGET = 0.95
#: Drops of each radio in the quality sections: enough that 95 % of them means at most two
#: misses (with 12, one miss is already 92 %).
QUALITY_DROPS = 40


@dataclass(frozen=True)
class SizeCase:
    """One row of the speed table: a scenario and how many timed pairs to run."""

    label: str
    scenario: Scenario
    repeats: int


def size_cases(quick: bool) -> list[SizeCase]:
    """The speed table: the letter's case I and random scenes of 10, 30 and 50 nodes."""
    cases = [SizeCase('letter case I', paper_scenario('I'), 3 if quick else 21),
             SizeCase('N=10, M=200', random_scenario(10, 200, 10, side_m=1500.0),
                      1 if quick else 7)]
    if not quick:
        cases += [SizeCase('N=30, M=500', random_scenario(30, 500, 30, side_m=2500.0), 3),
                  SizeCase('N=50, M=1000', random_scenario(50, 1000, 50, side_m=3000.0), 2)]
    return cases


def timed_plan(scenario: Scenario, settings: SolverSettings, methods: dict[str, str], *,
               cold: bool = False) -> tuple[float, PlanResult]:
    """Wall time of one plan. The fast path keeps the sparsity pattern of its cone program (a
    function of N and M only) between plans, as a running planner does; ``cold`` drops it
    first, so the plan also builds it, as the first plan of each size does."""
    if cold:
        clear_programs()
        SOLVERS.clear()
    began = time.perf_counter()
    result = plan(scenario, settings, **methods)
    return time.perf_counter() - began, result


def _status_kib(field: str) -> int:
    """A memory figure of this process from /proc/self/status (VmRSS, VmHWM...), KiB."""
    with open('/proc/self/status') as status:
        for line in status:
            if line.startswith(f'{field}:'):
                return int(line.split()[1])
    raise OSError(f'{field} is not in /proc/self/status')


def _peak_growth_kib(function: Callable[..., object], args: tuple) -> float:
    """In a fresh process: the peak resident set while ``function(*args)`` ran, over the one
    before it (after the imports), KiB; NaN if the peak cannot be reset.

    The high-water mark is reset first (clear_refs 5): a spawned process inherits its
    parent's peak, so ru_maxrss would report the parent's size.
    """
    try:
        with open('/proc/self/clear_refs', 'w') as clear_refs:
            clear_refs.write('5')
        before = _status_kib('VmRSS')
    except OSError:
        return math.nan
    function(*args)
    return _status_kib('VmHWM') - before


def peak_memory_mib(function: Callable[..., object], *args: object) -> float:
    """Peak memory ``function(*args)`` adds, MiB, measured in a freshly spawned interpreter.

    A fresh process has no free heap left over from earlier runs, so the growth of its peak
    resident set is what the call needed, the solvers' native memory included. ``function``
    must be picklable. NaN where /proc does not offer the figures (not Linux).
    """
    if not os.path.exists('/proc/self/status'):
        return math.nan
    with multiprocessing.get_context('spawn').Pool(1) as pool:
        return pool.apply(_peak_growth_kib, (function, args)) / 1024.0


@dataclass(frozen=True)
class SpeedRow:
    label: str
    repeats: int
    reference_s: float
    fast_s: float
    fast_cold_s: float
    reference_value: float
    fast_value: float
    reference_mib: float
    fast_mib: float
    steps: str

    @property
    def ratio(self) -> float:
        return self.reference_s / self.fast_s

    @property
    def cold_ratio(self) -> float:
        return self.reference_s / self.fast_cold_s

    @property
    def relative_difference(self) -> float:
        return abs(self.fast_value - self.reference_value) / abs(self.reference_value)


def measure_speed(case: SizeCase, settings: SolverSettings) -> SpeedRow:
    """Median plan times, timed in alternation (reference, fast, fast from cold), and the
    objectives of both paths."""
    runs = (('reference', REFERENCE, False), ('fast', FAST, False), ('fast_cold', FAST, True))
    times: dict[str, list[float]] = {name: [] for name, _, _ in runs}
    values, steps = {}, {}
    for _ in range(case.repeats):
        for name, methods, cold in runs:
            seconds, result = timed_plan(case.scenario, settings, methods, cold=cold)
            times[name].append(seconds)
            values[name] = result.min_throughput
            steps[name] = f'{result.outer_iterations}/{result.trajectory_steps}'
    memory = {}
    for name, methods in (('reference', REFERENCE), ('fast', FAST)):
        memory[name] = peak_memory_mib(functools.partial(plan, **methods), case.scenario,
                                       settings)
    median = {name: statistics.median(seconds) for name, seconds in times.items()}
    return SpeedRow(case.label, case.repeats, median['reference'], median['fast'],
                    median['fast_cold'], values['reference'], values['fast'],
                    memory['reference'], memory['fast'],
                    f"{steps['reference']} {steps['fast']}")


def format_speed(rows: Sequence[SpeedRow]) -> str:
    lines = ['case            runs  reference_s    fast_s    ratio  fast_cold_s  cold_ratio  '
             'reference_bps    fast_bps  rel_diff  ref_MiB  fast_MiB  outer/sca_steps(ref fast)']
    for r in rows:
        lines.append(f'{r.label:<15} {r.repeats:>4} {r.reference_s:>12.4f} {r.fast_s:>9.4f} '
                     f'{r.ratio:>7.1f}x {r.fast_cold_s:>12.4f} {r.cold_ratio:>10.1f}x '
                     f'{r.reference_value:>14.8f} {r.fast_value:>11.8f} '
                     f'{r.relative_difference:>9.1e} {r.reference_mib:>8.1f} {r.fast_mib:>9.1f}  '
                     f'{r.steps}')
    return '\n'.join(lines)


def measure_scaling(slot_counts: Sequence[int], settings: SolverSettings, repeats: int, *,
                    horizon_s: float | None) -> tuple[list[tuple[int, float, int]], float]:
    """Fast-path median plan time for N = 20 nodes in 2 km x 2 km and M slots; fitted exponent.

    ``horizon_s`` None gives delta = 1 s (T = M seconds, a longer flight for larger M); a
    number gives one flight of that length cut into ever finer slots. Returns rows
    (M, seconds, SCA steps) and the slope of log(time) against log(M).
    """
    rows = []
    for m in slot_counts:
        scenario = random_scenario(20, m, 20, side_m=2000.0, horizon_s=horizon_s)
        runs = [timed_plan(scenario, settings, FAST) for _ in range(repeats)]
        rows.append((m, statistics.median(s for s, _ in runs), runs[-1][1].trajectory_steps))
    slope = np.polyfit(np.log([m for m, _, _ in rows]), np.log([s for _, s, _ in rows]), 1)[0]
    return rows, float(slope)


def format_scaling(rows: Sequence[tuple[int, float, int]], exponent: float) -> str:
    lines = ['    M    fast_s  sca_steps  us_per_slot_and_step']
    for m, seconds, steps in rows:
        lines.append(f'{m:>5} {seconds:>9.4f} {steps:>10} {1e6 * seconds / (m * steps):>21.1f}')
    lines.append(f'fitted exponent of M (least squares, log-log): {exponent:.2f}')
    return '\n'.join(lines)


def quality_drop(seed: int, *, low_snr: bool, max_slots: int = 399) -> Scenario:
    """A random drop like the study's: N 3-20 nodes, M 51-``max_slots`` slots of 0.5-2 s,
    V 20-100 m/s, nodes in a square of side 0.5-2 km (shrunk to fit the flight) flown corner to
    corner; the letter's radio settings, or B = 1 MHz, beta0 = -60 dB with ``low_snr``."""
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(3, 21)), int(rng.integers(51, max_slots + 1))
    speed, slot = float(rng.uniform(20.0, 100.0)), float(rng.uniform(0.5, 2.0))
    side = float(min(rng.uniform(500.0, 2000.0), 0.7 * speed * m * slot / math.sqrt(2.0)))
    return random_scenario(n, m, rng, side_m=side, horizon_s=m * slot, max_speed_mps=speed,
                           **(LOW_SNR if low_snr else {}))


def best_of_random_tours(scenario: Scenario, count: int = 20) -> float:
    """The best min throughput of Algorithm 1 run to convergence (full SCA loops, relative
    tolerance) from each of ``count`` random tours other than the default's screened ones,
    bit/s."""
    settings = SolverSettings(compute_baselines=False, screened_tours=0, fast_steps=False)
    power_solver, trajectory_solver = step_solvers(scenario, FAST['power_method'],
                                                   FAST['trajectory_method'])
    tours = random_tours(scenario, count, seed=scenario_seed(scenario) + 1)
    return max(alternate(scenario, q, settings, power_solver=power_solver,
                         trajectory_solver=trajectory_solver).min_throughput
               for q in tours.values())


@dataclass(frozen=True)
class QualityRow:
    letter: PlanResult
    default: PlanResult
    tours_best: float

    @property
    def best_known(self) -> float:
        """The best of the default, the letter's and 20 other random tours, bit/s."""
        return max(self.tours_best, self.default.min_throughput, self.letter.min_throughput)

    @property
    def ratio(self) -> float:
        return self.default.min_throughput / self.letter.min_throughput

    @property
    def gap_to_best(self) -> float:
        return 1.0 - self.default.min_throughput / self.best_known

    @property
    def best_source(self) -> str:
        """Which run reached the best known: 'default', 'letter' or 'tours' (the 20 other
        random tours), the first of these on a tie."""
        values = {'default': self.default.min_throughput, 'letter': self.letter.min_throughput,
                  'tours': self.tours_best}
        return max(values, key=lambda name: values[name])


def share_lower_bound(hits: int, total: int, confidence: float = 0.9) -> float:
    """The one-sided Clopper-Pearson lower confidence bound of a share seen as ``hits`` of
    ``total``: the least share p for which ``hits`` or more of ``total`` would be seen with
    probability 1 - ``confidence``; 0 when ``hits`` is 0."""
    return 0.0 if hits == 0 else float(betaincinv(hits, total - hits + 1, 1.0 - confidence))


def compare_quality(num_cases: int, *, low_snr: bool, max_slots: int = 399,
                    first_seed: int = 1000) -> list[QualityRow]:
    """Default plan against the letter's Algorithm 1 and the best known on seeded drops
    (:func:`quality_drop`), with the default's tight upper bound."""
    rows = []
    for seed in range(first_seed, first_seed + num_cases):
        scenario = quality_drop(seed, low_snr=low_snr, max_slots=max_slots)
        letter = plan(scenario, SolverSettings.letter(compute_baselines=False))
        default = plan(scenario, SolverSettings(compute_baselines=False))
        rows.append(QualityRow(letter, default, best_of_random_tours(scenario)))
    return rows


def format_quality(rows: Sequence[QualityRow]) -> str:
    lines = [' N    M    letter_bps   default_bps      best_bps     bound_bps  '
             'default/letter  gap_to_best  gap_to_bound  old_gap  letter_s  default_s  start  '
             'best_from']
    for r in rows:
        d, size = r.default, r.default.scenario
        lines.append(
            f'{size.num_nodes:>2} {size.num_slots:>4} {r.letter.min_throughput:>13.6g} '
            f'{d.min_throughput:>13.6g} {r.best_known:>13.6g} {d.tight_upper_bound:>13.6g} '
            f'{r.ratio:>15.6f} {r.gap_to_best:>12.4%} {d.gap_to_tight_bound:>13.2%} '
            f'{d.gap_to_upper_bound:>8.1%} {r.letter.solve_time_s:>9.3f} '
            f'{d.solve_time_s:>10.3f}  {d.start:<7}  {r.best_source}')
    ratios = np.array([r.ratio for r in rows])
    gaps = np.array([r.gap_to_best for r in rows])
    within = int(np.sum(gaps <= WITHIN_BEST))
    verdict = 'met' if within >= QUALITY_TARGET * len(rows) else 'not met'
    lines.append(f'default below the letter in {int(np.sum(ratios < 1.0))} of {len(rows)} drops '
                 f'(min default/letter {ratios.min():.6f}, mean {ratios.mean():.4f}); within '
                 f'{100 * WITHIN_BEST:g} % of the best known in {within} of {len(rows)} '
                 f'({within / len(rows):.0%}, target {QUALITY_TARGET:.0%}: {verdict}; 90 % lower '
                 f'confidence bound {share_lower_bound(within, len(rows)):.0%}); gap to the best '
                 f'known mean {gaps.mean():.3%}, max {gaps.max():.3%}')
    tight = [r.default.gap_to_tight_bound for r in rows]
    lines.append(f'gap of the default to the dual bound: median {statistics.median(tight):.2%}, '
                 f'max {max(tight):.2%}; to the old bound (every channel at its best): median '
                 f'{statistics.median(r.default.gap_to_upper_bound for r in rows):.1%}')
    return '\n'.join(lines)


@dataclass(frozen=True)
class DefaultSpeedRow:
    label: str
    repeats: int
    reference_s: float
    default_s: float
    cold_s: float
    reference_value: float
    default_value: float

    @property
    def ratio(self) -> float:
        return self.reference_s / self.default_s


def measure_default_speed(case: SizeCase, fast_runs: int = 3) -> DefaultSpeedRow:
    """The default plan on the reference path and on the fast path, in alternation; the fast
    plan again with no cached solver or cone structure (the first plan of a size). Each of
    the ``repeats`` reference plans is followed by ``fast_runs`` pairs of fast plans."""
    settings = SolverSettings(compute_baselines=False)
    runs = (('reference', REFERENCE, False),
            *((('default', FAST, False), ('cold', FAST, True)) * fast_runs))
    times: dict[str, list[float]] = {name: [] for name, _, _ in runs}
    values = {}
    for _ in range(case.repeats):
        for name, methods, cold in runs:
            seconds, result = timed_plan(case.scenario, settings, methods, cold=cold)
            times[name].append(seconds)
            values[name] = result.min_throughput
    median = {name: statistics.median(seconds) for name, seconds in times.items()}
    return DefaultSpeedRow(case.label, case.repeats, median['reference'], median['default'],
                           median['cold'], values['reference'], values['default'])


def format_default_speed(rows: Sequence[DefaultSpeedRow]) -> str:
    lines = ['case            runs  reference_s  default_s    ratio   cold_s  reference_bps  '
             'default_bps']
    for r in rows:
        lines.append(f'{r.label:<15} {r.repeats:>4} {r.reference_s:>12.4f} {r.default_s:>10.4f} '
                     f'{r.ratio:>7.1f}x {r.cold_s:>8.4f} {r.reference_value:>14.8g} '
                     f'{r.default_value:>12.8g}')
    return '\n'.join(lines)


def default_size_cases(quick: bool) -> list[SizeCase]:
    """The default plan's speed table: the letter's case I and N = 20, M = 500."""
    if quick:
        return [SizeCase('letter case I', paper_scenario('I'), 2),
                SizeCase('N=10, M=200', random_scenario(10, 200, 10, side_m=1500.0), 1)]
    return [SizeCase('letter case I', paper_scenario('I'), 5),
            SizeCase('N=20, M=500', random_scenario(20, 500, 20, side_m=2000.0), 1)]


def side_by_side(cases: Sequence[SizeCase]) -> str:
    """The letter's method (both steps by cvxpy + Clarabel, rebuilt every step, from the
    straight line: the reference path at the letter's settings), the letter mode (the same
    Algorithm 1 on the fast path, ``SolverSettings.letter()``) and the default plan, timed in
    alternation in one process ('runs' rounds, after one untimed plan of each); medians, each
    mode's speed-up over the letter's method, and the default's min throughput against the
    letter's."""
    letter = SolverSettings.letter(compute_baselines=False)
    modes = (("letter's method", letter, REFERENCE), ('letter mode', letter, FAST),
             ('default', SolverSettings(compute_baselines=False), FAST))
    lines = ["case            runs  letter's_method_s  letter_mode_s  speed-up  default_s  "
             'speed-up  default_vs_letter']
    for case in cases:
        times: dict[str, list[float]] = {name: [] for name, _, _ in modes}
        values = {}
        for round_ in range(case.repeats + 1):
            for name, settings, methods in modes:
                seconds, result = timed_plan(case.scenario, settings, methods)
                values[name] = result.min_throughput
                if round_:      # the first round builds the solvers and the cone structure
                    times[name].append(seconds)
        median = {name: statistics.median(seconds) for name, seconds in times.items()}
        method, mode, default = (median[name] for name, _, _ in modes)
        lines.append(f'{case.label:<15} {case.repeats:>4} {method:>18.4f} {mode:>14.4f} '
                     f'{method / mode:>8.1f}x {default:>10.4f} {method / default:>8.1f}x '
                     f'{values["default"] / values[modes[0][0]] - 1:>+17.3%}')
    return '\n'.join(lines)


DESCRIPTION = ("time the reference and fast paths; compare the default plan with the letter's "
               'Algorithm 1')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The benchmark's options (``python -m devtools.bench``, ``make bench``)."""
    parser.add_argument('--quick', action='store_true',
                        help='small sizes and few runs (a smoke test, not the documented run)')
    parser.add_argument('--sitl', metavar='ARDUCOPTER',
                        help='ArduCopter SITL binary for the flight section (default: '
                             '$UAV_COMM_PLANNER_SITL, else arducopter on the PATH)')
    parser.add_argument('--no-flights', action='store_true',
                        help='leave out the flights on ArduCopter SITL')


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='python -m devtools.bench',
                                     description=DESCRIPTION)
    add_arguments(parser)
    return parser


def run(quick: bool = False, out: TextIO | None = None, *, flights: bool = True,
        sitl: str | None = None) -> None:
    """Run every section and print its table to ``out`` (standard output by default)."""
    out = out or sys.stdout

    def section(title: str, body: str) -> None:
        print(f'\n== {title}\n{body}', file=out, flush=True)

    print(f'uav_comm_planner benchmark{" (quick)" if quick else ""}: Python '
          f'{platform.python_version()}, {os.cpu_count()} CPUs, {platform.machine()}',
          file=out, flush=True)
    letter = SolverSettings.letter(compute_baselines=False)
    speed = [measure_speed(case, letter) for case in size_cases(quick)]
    section("Speed: Algorithm 1 from the straight line, letter's settings, median of 'runs' "
            'alternating triples (reference, fast, fast from cold: the cone structure of the '
            'size built again); memory: peak RSS growth of one plan in a fresh process',
            format_speed(speed))
    slots = (50, 100, 200) if quick else (100, 200, 500, 1000, 2000)
    for horizon_s, title in ((None, 'slots of 1 s (T = M seconds)'),
                             (200.0, 'one 200 s flight cut into M slots')):
        scaling, exponent = measure_scaling(slots, letter, 1 if quick else 3,
                                            horizon_s=horizon_s)
        section(f"Scaling: fast path, letter's settings, N = 20, {title}",
                format_scaling(scaling, exponent))
    section("Speed: the default plan (letter's run, screened tours, fast steps), median of "
            "'runs' reference plans, each followed by 3 pairs of fast plans (kept solvers, and "
            'no cached solver or cone structure)', format_default_speed(
                [measure_default_speed(case) for case in default_size_cases(quick)]))
    section("Side by side: the letter's method (cvxpy + Clarabel rebuilt every step, straight "
            "start), the letter mode and the default plan, median of 'runs' alternating rounds; "
            "target: the default at least 20x the letter's method",
            side_by_side(default_size_cases(quick)))
    section('Replans in flight: the node\'s replan of the rest of an N = 20, M = 500 mission '
            '(ArduCopter limits, mission items built), warm (the plan in force continued) and '
            'with the full search, median of 2 alternating pairs; target under 150 ms',
            format_replans(measure_replans((1,) if quick else (1, 2, 3),
                                           points=REPLAN_POINTS[1:2] if quick else REPLAN_POINTS))
            + '\n' + format_replan_drops(measure_replan_drops(range(100, 103 if quick else 140))))
    section('Replans in flight for PX4: the same missions at PX4\'s 5 m/s, slots of 4 s (PX4\'s '
            'leg timing and mission items)',
            format_replans(measure_replans((1,) if quick else (1, 2, 3),
                                           points=REPLAN_POINTS[1:2] if quick else REPLAN_POINTS,
                                           firmware='px4')))
    section('Fleets: K = 1, 2, 3 UAVs planned jointly over one drop (orthogonal channels, '
            'd_min = 100 m; devtools/fleet_bench.py), one plan each',
            fleet_table(quick))
    section('Energy: one drop planned with the airframe zeng2019, without and within an energy '
            'budget (devtools/energy_bench.py), one plan each', energy_table(quick))
    cases, max_slots = (3, 80) if quick else (QUALITY_DROPS, 199)
    drops = (f'random drops: N 3-20, M 51-{max_slots}, slots 0.5-2 s, V 20-100 m/s; best known: '
             'the best of the default, the letter and 20 other random tours run to '
             'convergence; bound: the dual bound at the default plan')
    section(f"Quality: default plan vs the letter's Algorithm 1, {drops}; letter's radio "
            'settings', format_quality(compare_quality(cases, low_snr=False,
                                                       max_slots=max_slots)))
    section('Quality, low SNR: B = 1 MHz, beta0 = -60 dB',
            format_quality(compare_quality(cases, low_snr=True, max_slots=max_slots)))
    if flights:
        title = ('Flown: vehicle-aware plans on ArduCopter SITL, autopilot time; the plan '
                 'states the throughput of its predicted flight')
        reason = why_not_runnable(sitl)
        if reason:
            section(title, f'skipped: {reason}')
        else:
            rows = [(case, *fly_case(case, sitl)) for case in flight_cases(quick)]
            section(title, format_flights(rows))


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    run(quick=args.quick, flights=not args.no_flights, sitl=args.sitl)
    return 0


if __name__ == '__main__':
    sys.exit(main())
