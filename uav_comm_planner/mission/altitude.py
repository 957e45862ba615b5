"""A plan with altitudes made for the vehicle: its mission carries every waypoint's altitude.

:func:`plan_altitude_for_vehicle` plans trajectory, altitudes and power
(:func:`~uav_comm_planner.core.altitude.plan_with_altitude`), times the flight for ArduCopter
with its climbs (:func:`~uav_comm_planner.vehicle.flyable.schedule_flight` with the altitudes,
:mod:`~uav_comm_planner.vehicle.climbs`), and states what the nodes get where the vehicle is
predicted to be at the slot times, at the altitude it is predicted to fly, with the power
optimal there. The mission takes off to q0's altitude. A flight that cannot keep the horizon
is planned again slower (:data:`~uav_comm_planner.vehicle.flyable.SLOWER_PLANNING`), as a
level plan for the vehicle is. The level plan at the best fixed altitude, made for the vehicle
(:func:`~uav_comm_planner.mission.policy.plan_for_vehicle`), is planned too, and the plan
stated is the better of the two as flown: with a vehicle too, a plan with altitudes is never
below the best fixed altitude's.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
import time

import numpy as np

from uav_comm_planner.core.altitude import (AltitudeLimits, AltitudePlan, plan_with_altitude,
                                            rates_3d, snr_per_watt_3d)
from uav_comm_planner.core.model import flown_path
from uav_comm_planner.core.optimizer import plan_along
from uav_comm_planner.core.power import waterfilling_power
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.errors import InfeasibleHorizonError, InvalidScenarioError
from uav_comm_planner.mission.policy import plan_for_vehicle
from uav_comm_planner.vehicle.climbs import check_climb_rate, ClimbLimits
from uav_comm_planner.vehicle.flyable import (check_speed, flown_result, schedule_flight,
                                              SLOWER_PLANNING, VehiclePlan)
from uav_comm_planner.vehicle.limits import VehicleLimits

#: The firmwares whose climbs are timed (PX4's vertical limits are not modelled).
FIRMWARES_WITH_CLIMBS = ('ardupilot',)
#: The name of the horizontal plan that carries the altitudes' mission.
ALTITUDES = 'with altitudes'


@dataclass(frozen=True)
class AltitudeVehiclePlan:
    """A plan with altitudes as the vehicle flies it.

    ideal: the optimiser's plan; mission: the horizontal plan with the timed flight whose
    waypoints carry their altitudes (what :func:`~uav_comm_planner.vehicle.mavlink.items.
    build_mission_items` takes); trajectory (M, 2) and altitudes (M,) metres: the vehicle's
    predicted position at the slot times; power (N, M) watts, optimal there; rates (N,) bit/s;
    min_throughput: the one to state; level: whether the level plan at the best fixed altitude
    was kept (it flies better than the plan with altitudes); alternative_throughput: what the
    other of the two states.
    """

    ideal: AltitudePlan
    mission: VehiclePlan
    climb: ClimbLimits
    trajectory: np.ndarray
    altitudes: np.ndarray
    power: np.ndarray
    rates: np.ndarray
    min_throughput: float
    solve_time_s: float
    level: bool = False
    alternative_throughput: float = float('nan')

    @property
    def scenario(self) -> Scenario:
        return self.ideal.scenario

    def planned_points(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The points the vehicle must reach, q0, the slots' predicted positions and qF:
        (M + 2, 2) metres, their altitudes (M + 2,) metres and their times (M + 2,) s from the
        start of the hold at q0."""
        scenario = self.scenario
        points = flown_path(self.trajectory, scenario)
        heights = np.concatenate([self.altitudes[:1], self.altitudes, self.altitudes[-1:]])
        first = self.mission.schedule.stops[0].altitude_m
        last = self.mission.schedule.stops[-1].altitude_m
        if first is not None:
            heights[0], heights[-1] = first, last
        return points, heights, scenario.slot_s * np.arange(len(points), dtype=float)


def plan_altitude_for_vehicle(scenario: Scenario, altitude_limits: AltitudeLimits,
                              limits: VehicleLimits | None = None,
                              climb: ClimbLimits | None = None,
                              settings: SolverSettings | None = None, *,
                              firmware: str = 'ardupilot') -> AltitudeVehiclePlan:
    """Plan ``scenario`` with altitudes in ``altitude_limits`` for a vehicle with ``limits``
    and ``climb`` (ArduCopter's defaults when None); module docstring. Raises
    :class:`~uav_comm_planner.errors.InvalidScenarioError` for a climb rate faster than the
    vehicle climbs or descends, or a firmware whose climbs are not timed, and
    :class:`~uav_comm_planner.errors.InfeasibleHorizonError` when no plan, even at the slowest
    planning speed tried, is flown on time."""
    began = time.perf_counter()
    if firmware not in FIRMWARES_WITH_CLIMBS:
        raise InvalidScenarioError(f'a plan with altitudes is timed for '
                                   f'{", ".join(FIRMWARES_WITH_CLIMBS)} only, not {firmware!r}')
    limits = VehicleLimits() if limits is None else limits
    climb = ClimbLimits() if climb is None else climb
    if not isinstance(climb, ClimbLimits):
        raise InvalidScenarioError(f'climb must be ClimbLimits, got {type(climb).__name__}')
    check_speed(scenario, limits)
    check_climb_rate(altitude_limits.max_climb_mps, climb)
    error: InfeasibleHorizonError | None = None
    for share in (1.0, *SLOWER_PLANNING):
        slower = scenario.replace(max_speed_mps=scenario.max_speed_mps * share)
        ideal = plan_with_altitude(slower, altitude_limits, settings)
        carrier = plan_along(slower.replace(altitude_m=ideal.fixed_altitude_m),
                             ideal.trajectory, SolverSettings(compute_baselines=False),
                             name=ALTITUDES)
        for stop_at_hovers in (True, False):
            try:
                schedule = schedule_flight(carrier, limits, firmware=firmware,
                                           stop_at_hovers=stop_at_hovers,
                                           altitudes=ideal.altitudes, climb=climb)
            except InfeasibleHorizonError as exc:
                error = exc
                continue
            mission = VehiclePlan(carrier, flown_result(carrier, schedule), schedule, limits)
            return _better(_as_flown(ideal, mission, climb, began),
                           _level(scenario, ideal, limits, settings, firmware), began)
    raise error


def _level(scenario: Scenario, ideal: AltitudePlan, limits: VehicleLimits,
           settings: SolverSettings | None, firmware: str) -> VehiclePlan | None:
    """The level plan at ``ideal``'s best fixed altitude made for the vehicle (None when the
    vehicle cannot fly it on time)."""
    try:
        return plan_for_vehicle(scenario.replace(altitude_m=ideal.fixed_altitude_m), limits,
                                settings, firmware=firmware)
    except InfeasibleHorizonError:
        return None


def _better(climbing: AltitudeVehiclePlan, level: VehiclePlan | None,
            began: float) -> AltitudeVehiclePlan:
    """The plan with altitudes, or the level one where it flies better."""
    if level is None:
        return climbing
    flown = level.flown
    if flown.min_throughput <= climbing.min_throughput:
        return dataclasses.replace(climbing, alternative_throughput=flown.min_throughput,
                                   solve_time_s=time.perf_counter() - began)
    altitudes = np.full(flown.scenario.num_slots, flown.scenario.altitude_m)
    return dataclasses.replace(
        climbing, mission=level, trajectory=flown.trajectory, altitudes=altitudes,
        power=flown.power, rates=flown.rates, min_throughput=flown.min_throughput, level=True,
        alternative_throughput=climbing.min_throughput,
        solve_time_s=time.perf_counter() - began)


def _as_flown(ideal: AltitudePlan, mission: VehiclePlan, climb: ClimbLimits,
              began: float) -> AltitudeVehiclePlan:
    """The plan at the predicted positions and altitudes, with the power optimal there."""
    scenario = ideal.scenario
    flight = mission.schedule.flight
    q = flight.positions(scenario.times_s)
    h = flight.altitudes(scenario.times_s)
    p = waterfilling_power(snr_per_watt_3d(q, h, scenario), scenario.power_budget_w).p
    rates = rates_3d(q, h, p, scenario)
    return AltitudeVehiclePlan(ideal=ideal, mission=mission, climb=climb, trajectory=q,
                               altitudes=h, power=p, rates=rates,
                               min_throughput=float(rates.min()),
                               solve_time_s=time.perf_counter() - began)


__all__ = ['AltitudeVehiclePlan', 'FIRMWARES_WITH_CLIMBS', 'plan_altitude_for_vehicle']
