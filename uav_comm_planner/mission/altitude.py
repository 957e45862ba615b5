"""A plan with altitudes made for the vehicle: its mission carries every waypoint's altitude.

:func:`plan_altitude_for_vehicle` plans trajectory, altitudes and power
(:func:`~uav_comm_planner.core.altitude.plan_with_altitude`), times the flight for ArduCopter
with its climbs (:func:`~uav_comm_planner.vehicle.flyable.schedule_flight` with the altitudes,
:mod:`~uav_comm_planner.vehicle.climbs`), and states what the nodes get where the vehicle is
predicted to be at the slot times, at the altitude it is predicted to fly, with the power
optimal there. The mission takes off to q0's altitude. A flight that cannot keep the horizon
is planned again slower (:data:`~uav_comm_planner.vehicle.flyable.SLOWER_PLANNING`), as a
level plan for the vehicle is.
"""

from __future__ import annotations

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
    min_throughput: the one to state.
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
            return _as_flown(ideal, mission, climb, began)
    raise error


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
