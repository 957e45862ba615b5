"""Benchmark: the reference path against the fast path, and the default plan against the letter's.

* Speed: Algorithm 1 from the straight line (the letter's settings, baselines off) on the
  reference path (cvxpy + Clarabel for both steps, problems rebuilt every step) and on the fast
  path (water-filling power step, SCA step on one Clarabel solver updated in place), timed in
  alternation in one process. Every fast plan builds its own Clarabel solver; the sparsity
  pattern of its cone program, a function of N and M only, is kept between plans as in a
  running planner, and a third column times plans that build it again (the first plan of a
  size). Peak
  memory is the growth of the peak resident set (VmHWM) of a freshly spawned process that
  plans once, so it counts the solvers' native memory too.
* Scaling: the fast path for N = 20 and a growing number of slots M, with slots of 1 s and
  over one 200 s flight, with the least-squares exponent of M on a log-log scale.
* Quality: on random scenarios, the default plan (both starts, relative tolerance) against
  the letter's Algorithm 1, with the upper bound of every plan.

Run ``uav-comm-planner bench`` or ``python -m uav_comm_planner.tools.bench`` (``--quick`` for a
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

from uav_comm_planner.core.drops import random_scenario
from uav_comm_planner.core.fast_trajectory import cone_layout
from uav_comm_planner.core.optimizer import plan, PlanResult
from uav_comm_planner.core.scenario import paper_scenario, Scenario, SolverSettings
from uav_comm_planner.tools.flights import flight_cases, fly_case, format_flights
from uav_comm_planner.vehicle.sitl import why_not_runnable

REFERENCE = dict(power_method='conic', trajectory_method='cvxpy')
FAST = dict(power_method='waterfilling', trajectory_method='clarabel')
LOW_SNR = dict(bandwidth_hz=1e6, reference_gain=1e-6)


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
        cone_layout.cache_clear()
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


@dataclass(frozen=True)
class QualityRow:
    num_nodes: int
    letter: PlanResult
    default: PlanResult

    @property
    def ratio(self) -> float:
        return self.default.min_throughput / self.letter.min_throughput


def compare_quality(num_cases: int, radio: dict[str, float]) -> list[QualityRow]:
    """Default plan against the letter's Algorithm 1 on random 2 km x 2 km scenes, M = 120."""
    rows = []
    for seed in range(num_cases):
        n = 4 + seed % 9
        scenario = random_scenario(n, 120, 1000 + seed, side_m=2000.0, **radio)
        letter = plan(scenario, SolverSettings.letter(compute_baselines=False))
        default = plan(scenario, SolverSettings(compute_baselines=False))
        rows.append(QualityRow(n, letter, default))
    return rows


def format_quality(rows: Sequence[QualityRow]) -> str:
    lines = [' N   letter_bps   default_bps   ratio  start     letter_gap  default_gap  '
             'letter_s  default_s']
    for r in rows:
        lines.append(
            f'{r.num_nodes:>2} {r.letter.min_throughput:>12.6g} {r.default.min_throughput:>13.6g} '
            f'{r.ratio:>7.4f}  {r.default.start:<8} {r.letter.gap_to_upper_bound:>11.1%} '
            f'{r.default.gap_to_upper_bound:>12.1%} {r.letter.solve_time_s:>9.3f} '
            f'{r.default.solve_time_s:>10.3f}')
    ratios = np.array([r.ratio for r in rows])
    worse = int(np.sum(ratios < 1.0))
    hover = sum(r.default.start == 'hover' for r in rows)
    lines.append(f'default / letter: mean {ratios.mean():.4f}, min {ratios.min():.6f}, '
                 f'max {ratios.max():.4f}; worse in {worse} of {len(rows)} cases; '
                 f'hover start kept in {hover}')
    lines.append('mean gap to the upper bound: letter '
                 f'{np.mean([r.letter.gap_to_upper_bound for r in rows]):.1%}, default '
                 f'{np.mean([r.default.gap_to_upper_bound for r in rows]):.1%}')
    return '\n'.join(lines)


DESCRIPTION = ("time the reference and fast paths; compare the default plan with the letter's "
               'Algorithm 1')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The benchmark's options, for ``python -m uav_comm_planner.tools.bench`` and the CLI."""
    parser.add_argument('--quick', action='store_true',
                        help='small sizes and few runs (a smoke test, not the documented run)')
    parser.add_argument('--sitl', metavar='ARDUCOPTER',
                        help='ArduCopter SITL binary for the flight section (default: '
                             '$UAV_COMM_PLANNER_SITL, else arducopter on the PATH)')
    parser.add_argument('--no-flights', action='store_true',
                        help='leave out the flights on ArduCopter SITL')


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='python -m uav_comm_planner.tools.bench',
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
    cases = 4 if quick else 20
    section("Quality: default plan vs the letter's Algorithm 1, random 2 km x 2 km, M = 120, "
            "letter's radio settings", format_quality(compare_quality(cases, {})))
    section('Quality, low SNR: B = 1 MHz, beta0 = -60 dB',
            format_quality(compare_quality(cases, LOW_SNR)))
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
