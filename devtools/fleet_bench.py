"""Benchmark of the fleet's plan: K = 1, 2, 3 UAVs over the same random drop.

Nodes uniform in a 2 km square (``random_scenario(N, M, seed, side_m=2000)``, slots of 1 s),
UAV k from (0, y_k) to (2000, y_k), y evenly spaced over [0, 2000] (K = 1: the drop's own
(0, 0) -> (2000, 2000)), d_min = 100 m. Prints, per K, the plan's min throughput, its time,
the start kept, the best single-UAV plan and the closest approach of two UAVs.

``python -m devtools.fleet_bench`` (N = 20, M = 500; ``--quick``: N = 6, M = 60); ``make bench``
prints the same table in its section on fleets.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Sequence

from uav_comm_planner.core.drops import random_scenario
from uav_comm_planner.core.fleet import FleetScenario, plan_fleet
from uav_comm_planner.core.fleet.model import closest_approach_m

SIDE_M = 2000.0
SEPARATION_M = 100.0


def fleet_of(count: int, num_nodes: int, num_slots: int, seed: int) -> FleetScenario:
    """The benchmark's fleet of ``count`` UAVs (module docstring)."""
    base = random_scenario(num_nodes, num_slots, seed, side_m=SIDE_M)
    if count == 1:
        return FleetScenario(base, (base.start_m,), (base.goal_m,), SEPARATION_M)
    heights = [SIDE_M * k / (count - 1) for k in range(count)]
    return FleetScenario(base, tuple((0.0, y) for y in heights),
                         tuple((SIDE_M, y) for y in heights), SEPARATION_M)


def fleet_table(quick: bool = False, seed: int = 1) -> str:
    """The benchmark's table: one row per K (module docstring)."""
    num_nodes, num_slots = (6, 60) if quick else (20, 500)
    lines = [f'{"K":>2}{"N":>4}{"M":>5}{"min (bit/s)":>13}{"time (s)":>10}{"best single":>13}'
             f'{"closest (m)":>13}  start']
    for count in (1, 2, 3):
        fleet = fleet_of(count, num_nodes, num_slots, seed)
        began = time.perf_counter()
        result = plan_fleet(fleet)
        elapsed = time.perf_counter() - began
        single = max(result.single_throughputs.values(), default=math.nan)
        closest = closest_approach_m(result.trajectories)
        lines.append(f'{count:>2}{num_nodes:>4}{num_slots:>5}{result.min_throughput:>13.4f}'
                     f'{elapsed:>10.1f}{single:>13.4f}{closest:>13.1f}  {result.start}')
    return '\n'.join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='python -m devtools.fleet_bench',
                                     description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='N = 6, M = 60')
    parser.add_argument('--seed', type=int, default=1)
    args = parser.parse_args(argv)
    print(fleet_table(args.quick, args.seed), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
