"""Benchmark of the energy-aware plan: one random drop planned with and without an energy budget.

Nodes uniform in a 2 km square (``random_scenario(N, M, 20, side_m=2000)``, slots of 1 s), the
airframe ``zeng2019``. Two default plans, timed one after the other: the plan with the airframe
(its top airspeed bounds the airspeed, no budget), and the same drop with an energy budget
half-way between that plan's horizon energy and the straight line's at uniform speed (a plan
the budget admits). Prints each plan's time, min throughput and horizon energy.

``python -m devtools.energy_bench`` (N = 20, M = 500; ``--quick``: N = 6, M = 150); ``make bench``
prints the same table in its section on energy.
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Sequence

import numpy as np

from uav_comm_planner.core.drops import random_scenario
from uav_comm_planner.core.energy import horizon_energy_j, JOULES_PER_WH
from uav_comm_planner.core.initial import straight_line
from uav_comm_planner.core.optimizer import plan
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.vehicle.airframe import airframe_named

AIRFRAME = 'zeng2019'
SEED = 20


def _timed(scenario: Scenario) -> tuple[float, float, float]:
    """Seconds, min throughput (bit/s) and horizon energy (Wh) of the default plan."""
    began = time.perf_counter()
    result = plan(scenario, SolverSettings(compute_baselines=False))
    elapsed = time.perf_counter() - began
    energy = horizon_energy_j(np.asarray(result.trajectory), scenario, scenario.airframe)
    return elapsed, result.min_throughput, energy / JOULES_PER_WH


def energy_table(quick: bool = False) -> str:
    """The benchmark's table (module docstring)."""
    num_nodes, num_slots = (6, 150) if quick else (20, 500)
    airframe = airframe_named(AIRFRAME)
    scenario = random_scenario(num_nodes, num_slots, SEED, side_m=2000.0).replace(
        airframe=airframe)
    straight_wh = horizon_energy_j(straight_line(scenario), scenario, airframe) / JOULES_PER_WH
    free = _timed(scenario)
    budget_wh = 0.5 * (free[2] + straight_wh)
    kept = _timed(scenario.replace(energy_budget_wh=budget_wh))
    lines = [f'N = {num_nodes}, M = {num_slots}, airframe {AIRFRAME}; the straight line at '
             f'uniform speed {straight_wh:.2f} Wh',
             f'{"plan":<28}{"time (s)":>9}{"min (bit/s)":>13}{"energy (Wh)":>13}']
    for name, (seconds, rate, energy) in (('airframe, no budget', free),
                                          (f'budget {budget_wh:.2f} Wh', kept)):
        lines.append(f'{name:<28}{seconds:>9.2f}{rate:>13.4f}{energy:>13.2f}')
    return '\n'.join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='python -m devtools.energy_bench',
                                     description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='N = 6, M = 150')
    args = parser.parse_args(argv)
    print(energy_table(args.quick), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
