"""Benchmark of replans in flight: the node's replan of the rest of a mission, warm against
the full search, side by side.

A mission of N = 20 nodes and M = 500 slots is planned for an autopilot's default limits
(ArduCopter's 10 m/s and slots of 2 s, the node's vehicle-aware default; or PX4's 5 m/s and
slots of 4 s, with PX4's leg timing and mission items) as the node plans it. Its plan is begun on a
:class:`~uav_comm_planner.mission.progress.MissionProgress` as the node begins it, the clock
started at q0, and at a few times of the flight the UAV is put off the plan; the request is the
one the node builds (:meth:`~uav_comm_planner.mission.progress.MissionProgress.in_flight`) and
is planned by the node's pipeline (:func:`~uav_comm_planner.mission.pipeline.plan_mission`,
with mission items, as for a mission file or a link), once warm (the plan in force continued)
and once with the full search (the tours screened again), in alternation. Random replans of
other sizes (:func:`replan_drop`) compare the two on quality.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
import math
import statistics
import time
from typing import Sequence

import numpy as np

from uav_comm_planner.core.drops import random_scenario
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.mission.pipeline import MissionPlan, plan_mission
from uav_comm_planner.mission.progress import MissionProgress, planned_position
from uav_comm_planner.mission.request import InFlight, MissionRequest
from uav_comm_planner.vehicle.limits import VehicleLimits

#: The replans: (slots flown, metres east of the plan).
REPLAN_POINTS = ((100, 0.0), (100, 40.0), (300, 40.0))
#: A replan of this size should come back within this many seconds (the node's target).
TARGET_S = 0.150
#: A warm replan this share or more below the full search is counted as below it.
BELOW_SHARE = 1e-3


def replan_mission(seed: int, firmware: str = 'ardupilot') -> Scenario:
    """N = 20 nodes in a 2 km square, M = 500 slots, corner to corner, at the cruise of
    ``firmware``'s default limits: 10 m/s and slots of 2 s for ArduCopter, 5 m/s and slots of
    4 s for PX4 (the same flight at half the speed)."""
    cruise = VehicleLimits.for_firmware(firmware).cruise_speed_mps
    return random_scenario(20, 500, seed, side_m=2000.0, horizon_s=10000.0 / cruise,
                           max_speed_mps=cruise)


def _request(scenario: Scenario, firmware: str, **fields) -> MissionRequest:
    return MissionRequest(scenario, vehicle=VehicleLimits.for_firmware(firmware),
                          firmware=firmware, **fields)


@dataclass(frozen=True)
class ReplanRow:
    seed: int
    slots_flown: int
    off_plan_m: float
    full_s: float
    warm_s: float
    full_bps: float
    warm_bps: float

    @property
    def change(self) -> float:
        """The warm replan's whole-mission min throughput against the full search's, - 1."""
        return self.warm_bps / self.full_bps - 1.0


def _timed(scenario: Scenario, in_flight: InFlight, firmware: str) -> tuple[float, float]:
    began = time.perf_counter()
    planned = plan_mission(_request(scenario, firmware, in_flight=in_flight))
    return time.perf_counter() - began, planned.min_throughput


def _replan_row(seed: int, scenario: Scenario, first: MissionPlan, slots: int,
                offset_m: np.ndarray, repeats: int, firmware: str = 'ardupilot') -> ReplanRow:
    """The plan ``first`` of ``scenario`` begun as the node begins it, its clock started at
    q0, and the vehicle ``offset_m`` (2,) off it after ``slots`` slots: the node's request
    replanned warm and with the full search, in alternation ``repeats`` times (median wall
    times)."""
    progress = MissionProgress()
    progress.begin(scenario, first.result, planned=first.optimised)
    progress.start_clock(0.0)
    time_s = (slots + 0.5) * scenario.slot_s
    position = planned_position(first.result, time_s) + offset_m
    warm = progress.in_flight(scenario, time_s, tuple(position), None)
    requests = {True: warm, False: dataclasses.replace(warm, warm=False)}
    times: dict[bool, list[float]] = {True: [], False: []}
    values = {}
    for _ in range(repeats):
        for kind, in_flight in requests.items():
            seconds, values[kind] = _timed(scenario, in_flight, firmware)
            times[kind].append(seconds)
    return ReplanRow(seed, slots, float(np.linalg.norm(offset_m)),
                     statistics.median(times[False]), statistics.median(times[True]),
                     values[False], values[True])


def measure_replans(seeds: Sequence[int], repeats: int = 2,
                    points: Sequence[tuple[int, float]] = REPLAN_POINTS,
                    firmware: str = 'ardupilot') -> list[ReplanRow]:
    """Each mission of ``seeds`` (:func:`replan_mission` for ``firmware``) replanned at
    ``points``, warm and full in alternation ``repeats`` times (median wall times)."""
    rows = []
    for seed in seeds:
        scenario = replan_mission(seed, firmware)
        first = plan_mission(_request(scenario, firmware, items=False))
        rows += [_replan_row(seed, scenario, first, slots, np.array([east_m, 0.0]), repeats,
                             firmware) for slots, east_m in points]
    return rows


def replan_drop(seed: int) -> tuple[Scenario, int, np.ndarray]:
    """A random replan: N 4-20 nodes in a square of side 0.8-2 km, M 100-500 slots of at
    least 2 s at 10 m/s (ArduCopter's limits), the vehicle 0-50 m off the plan in a random
    direction after a tenth to two thirds of the slots: (mission, slots flown, offset (2,))."""
    rng = np.random.default_rng(seed)
    nodes, slots = int(rng.integers(4, 21)), int(rng.integers(100, 501))
    side = float(rng.uniform(800.0, 2000.0))
    horizon = max(2.0 * slots, side * math.sqrt(2.0) / 10.0 * 1.8)
    mission = random_scenario(nodes, slots, seed, side_m=side, horizon_s=horizon,
                              max_speed_mps=10.0)
    flown = int(rng.integers(slots // 10, slots * 2 // 3))
    angle = rng.uniform(0.0, 2.0 * math.pi)
    offset = float(rng.uniform(0.0, 50.0)) * np.array([math.cos(angle), math.sin(angle)])
    return mission, flown, offset


def measure_replan_drops(seeds: Sequence[int]) -> list[ReplanRow]:
    """Each :func:`replan_drop` of ``seeds`` replanned warm and with the full search, once
    each (the row's ``off_plan_m`` is the offset's length)."""
    rows = []
    for seed in seeds:
        mission, slots, offset = replan_drop(seed)
        first = plan_mission(MissionRequest(mission, items=False))
        rows.append(_replan_row(seed, mission, first, slots, offset, repeats=1))
    return rows


def format_replan_drops(rows: Sequence[ReplanRow]) -> str:
    changes = [r.change for r in rows]
    below = sum(change < -BELOW_SHARE for change in changes)
    warm_s = statistics.median(r.warm_s for r in rows)
    full_s = statistics.median(r.full_s for r in rows)
    return (f'{len(rows)} random replans: warm median {warm_s:.3f} s, full search '
            f'{full_s:.3f} s; warm more than {BELOW_SHARE * 100:g} % below the full search in '
            f'{below}; against '
            f'it mean {statistics.mean(changes):+.3%}, worst {min(changes):+.3%}, best '
            f'{max(changes):+.3%}')


def format_replans(rows: Sequence[ReplanRow]) -> str:
    lines = ['seed  flown  off_m   full_s   warm_s  speed-up  full_bps    warm_bps    change']
    for r in rows:
        lines.append(f'{r.seed:>4} {r.slots_flown:>6} {r.off_plan_m:>6.0f} {r.full_s:>8.3f} '
                     f'{r.warm_s:>8.3f} {r.full_s / r.warm_s:>8.1f}x {r.full_bps:>10.6f} '
                     f'{r.warm_bps:>10.6f} {r.change:>+9.3%}')
    warm = [r.warm_s for r in rows]
    changes = [r.change for r in rows]
    within = sum(seconds < TARGET_S for seconds in warm)
    lines.append(f'warm replan: median {statistics.median(warm):.3f} s (full search '
                 f'{statistics.median(r.full_s for r in rows):.3f} s), under '
                 f'{TARGET_S * 1e3:.0f} ms in {within} of {len(rows)}; min throughput against '
                 f'the full search: mean {statistics.mean(changes):+.3%}, worst '
                 f'{min(changes):+.3%}')
    return '\n'.join(lines)


__all__ = ['ReplanRow', 'REPLAN_POINTS', 'TARGET_S', 'format_replan_drops', 'format_replans',
           'measure_replan_drops', 'measure_replans', 'replan_drop', 'replan_mission']
