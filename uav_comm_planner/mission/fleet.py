"""A fleet's plan as each vehicle's mission: UAV k's part as a single UAV's plan, the missions
kept apart as the autopilot times them, and one mission file name per vehicle.

The command line (``plan --uavs K --mission``) and the node (``uavs`` >= 2) both make their
missions here, so that the same fleet gives the same plans and the same missions on either
route.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from pathlib import PurePath

import numpy as np

from uav_comm_planner.core.fleet import FleetScenario, FleetSettings, plan_fleet
from uav_comm_planner.core.fleet.planner import FleetPlan
from uav_comm_planner.core.model import average_rates
from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.errors import InvalidScenarioError, PlannerError
from uav_comm_planner.vehicle.flyable import schedule_flight
from uav_comm_planner.vehicle.limits import VehicleLimits


def fleet_mission_paths(path: PurePath, count: int) -> list[PurePath]:
    """m.waypoints -> m_uav1.waypoints, ..., m_uavK.waypoints (the same folder and format)."""
    return [path.with_name(f'{path.stem}_uav{k}{path.suffix}') for k in range(1, count + 1)]


def uav_result(result: FleetPlan, k: int) -> PlanResult:
    """UAV k's part (0-based) as a single UAV's plan: its trajectory and power, the rates it
    alone gives, for the mission export."""
    vehicle = result.fleet.vehicle(k)
    rates = average_rates(result.trajectories[k], result.power[k], vehicle)
    return PlanResult(scenario=vehicle, trajectory=result.trajectories[k], times=result.times,
                      power=result.power[k], rates=rates, min_throughput=float(rates.min()),
                      history=(), start=result.start)


#: The missions' timed flights are compared at this share of a slot.
MISSION_SAMPLES_PER_SLOT = 20


def missions_closest_approach(result: FleetPlan, limits: VehicleLimits, firmware: str
                              ) -> tuple[float, float, tuple[int, int]] | None:
    """The least distance between two vehicles flying their missions as the autopilot times
    them (:func:`~uav_comm_planner.vehicle.flyable.schedule_flight`, every vehicle from its q0
    at the same moment), metres, with when (seconds) and which pair (1-based); None for one
    vehicle. The plan keeps d_min at its slot times; the autopilot's timing of a waypoint
    mission is not the plan's, so this is what the missions themselves keep."""
    count = result.fleet.num_uavs
    if count < 2:
        return None
    flights = [schedule_flight(uav_result(result, k), limits, firmware=firmware).flight
               for k in range(count)]
    scenario = result.fleet.scenario
    end = max(flight.end_s for flight in flights)
    times = np.arange(0.0, end + scenario.slot_s, scenario.slot_s / MISSION_SAMPLES_PER_SLOT)
    tracks = [flight.positions(times) for flight in flights]
    closest = (math.inf, 0.0, (1, 2))
    for j, k in itertools.combinations(range(count), 2):
        gap = np.linalg.norm(tracks[j] - tracks[k], axis=1)
        at = int(gap.argmin())
        if gap[at] < closest[0]:
            closest = (float(gap[at]), float(times[at]), (j + 1, k + 1))
    return closest


#: Plans the missions may take: each next one keeps more than d_min at its slots.
MISSION_PLANS = 4


def plan_for_missions(fleet: FleetScenario, settings: FleetSettings, limits: VehicleLimits,
                      firmware: str) -> tuple[FleetPlan, str]:
    """A plan whose missions, as the autopilot times them (:func:`missions_closest_approach`),
    keep d_min, and the line that says so: planned at d_min first, then, while the missions
    come closer, at a separation raised by one and a half times their shortfall each time (at
    most :data:`MISSION_PLANS` plans). Refuses (PlannerError) when none does."""
    required = planned = fleet.min_separation_m
    found = None
    for _ in range(MISSION_PLANS):
        try:
            attempt = dataclasses.replace(fleet, min_separation_m=planned)
        except InvalidScenarioError:        # the ends themselves are closer than that
            break
        result = plan_fleet(attempt, settings)
        found = missions_closest_approach(result, limits, firmware)
        if found is None:
            return result, 'one vehicle: no separation to keep'
        gap, at, (j, k) = found
        if gap >= required:
            return result, (f'missions as {firmware} times them: closest approach {gap:.1f} m '
                            f'(UAV {j} and UAV {k} at {at:.1f} s), d_min {required:g} m, '
                            f'planned with {planned:.1f} m at the slots')
        planned += max(1.5 * (required - gap), 1.0)
    gap, at, (j, k) = found
    raise PlannerError(
        f'the missions, flown as {firmware} times them (every vehicle from its q0 at the same '
        f'moment), bring UAV {j} and UAV {k} within {gap:.1f} m of each other at {at:.1f} s, '
        f'below d_min = {required:g} m, even planned with more separation: fly the plan '
        f'streamed (docs/fleet.md), or move the vehicles\' ends apart')


__all__ = ['fleet_mission_paths', 'MISSION_PLANS', 'missions_closest_approach',
           'plan_for_missions', 'uav_result']
