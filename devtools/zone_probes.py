"""The scaling probes of paths and plans round large no-fly zones, and of a long horizon: each
case built afresh and timed (wall and processor seconds), its figures printed, nothing
asserted (the machine is shared: the figures vary with its load).

    python -m devtools.zone_probes [case ...]

Cases: ``star400-paths`` (the paths round a 400-vertex star, graph built afresh),
``star1000-paths``, ``four-stars-paths`` (four 1000-vertex stars, 4000 vertices, the most
zones may have), ``star1000-plan``, ``four-stars-plan`` (whole default plans, case I with a
horizon of 80 s), ``slots-M`` (N = 1 node, M slots, no zones, for example ``slots-20000``).
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time

import numpy as np

from uav_comm_planner import paper_scenario
from uav_comm_planner.core.detour import GRAPHS, shortest_path
from uav_comm_planner.core.optimizer import plan
from uav_comm_planner.core.zones import KeepOutPolygon, Zones

STAR_CENTRES = ((500.0, 50.0), (900.0, -60.0), (1300.0, 80.0), (1700.0, -40.0))


def star(vertices: int, centre: tuple[float, float], outer: float,
         inner: float) -> KeepOutPolygon:
    """``vertices`` corners alternately ``outer`` and ``inner`` metres from ``centre``."""
    k = np.arange(vertices)
    radius = np.where(k % 2 == 0, outer, inner)
    angle = 2 * math.pi * k / vertices
    return KeepOutPolygon(np.column_stack([centre[0] + radius * np.cos(angle),
                                           centre[1] + radius * np.sin(angle)]))


def zones_of(case: str) -> Zones:
    if case.startswith('star400'):
        return Zones(keep_out=(star(400, (1000.0, 0.0), 300.0, 150.0),), margin_m=5.0)
    if case.startswith('star1000'):
        return Zones(keep_out=(star(1000, (1000.0, 0.0), 150.0, 100.0),), margin_m=5.0)
    return Zones(keep_out=tuple(star(1000, centre, 150.0, 100.0) for centre in STAR_CENTRES),
                 margin_m=5.0)


def timed(work) -> tuple[object, float, float]:
    wall, processor = time.perf_counter(), time.process_time()
    result = work()
    return result, time.perf_counter() - wall, time.process_time() - processor


def probe(case: str) -> str:
    """One case's figures, one line."""
    if case.startswith('slots-'):
        slots = int(case.split('-', 1)[1])
        scenario = dataclasses.replace(paper_scenario('I'), ground_nodes_m=((1000.0, 300.0),),
                                       num_slots=slots, horizon_s=float(slots))
        result, wall, processor = timed(lambda: plan(scenario))
        return (f'{case}: {wall:.1f} s ({processor:.1f} s of processor), plan '
                f'{result.solve_time_s:.1f} s, {result.trajectory_steps} trajectory steps')
    zones = zones_of(case)
    vertices = sum(len(zone.vertices_m) for zone in zones.keep_out)
    GRAPHS.clear()
    if case.endswith('-paths'):
        path, wall, processor = timed(lambda: shortest_path(
            zones, np.array([0.0, 0.0]), np.array([2000.0, 0.0])))
        length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
        return (f'{case}: {vertices} vertices, {wall:.2f} s ({processor:.2f} s of processor), '
                f'path {length:.2f} m with {len(path) - 2} corners')
    scenario = dataclasses.replace(paper_scenario('I'), zones=zones, horizon_s=80.0)
    result, wall, processor = timed(lambda: plan(scenario))
    return (f'{case}: {vertices} vertices, {wall:.1f} s ({processor:.1f} s of processor), '
            f'min rate {result.min_throughput:.4f}, {result.trajectory_steps} trajectory steps')


def main(argv: list[str] | None = None) -> None:
    cases = (sys.argv[1:] if argv is None else argv) or [
        'star400-paths', 'star1000-paths', 'four-stars-paths', 'star1000-plan',
        'four-stars-plan']
    for case in cases:
        print(probe(case), flush=True)


if __name__ == '__main__':
    main()
