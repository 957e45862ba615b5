"""A request whose straight line fits the horizon is never refused.

The straight line q0 -> qF flown rest to rest (the autopilot's S-curve at the fastest speed
the vehicle holds along it, in the wind given, plus the leg's latency) is computed here from
the timing model, independently of the planner; every request whose horizon is 1.05 to 3 times
that must get a flyable plan, in still air and in wind.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from uav_comm_planner import Scenario
from uav_comm_planner.mission.policy import plan_for_vehicle
from uav_comm_planner.vehicle.flyable import GOAL_TOLERANCE_SLOTS
from uav_comm_planner.vehicle.leg_models import MIN_STOP_HOLD_S
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.timing import LEG_LATENCY_S, Profile

LIMITS = VehicleLimits()
REQUESTS = 200


def straight_line_time_s(start, goal, wind_mps, airspeed_mps) -> float:
    """Rest to rest along the straight line at the fastest ground speed g <= cruise with
    ||g u - w|| <= V_air, plus the leg latency."""
    distance = math.dist(start, goal)
    u = (np.asarray(goal) - np.asarray(start)) / distance
    w = np.asarray(wind_mps)
    along = float(u @ w)
    air = along + math.sqrt(airspeed_mps ** 2 - float(w @ w) + along ** 2)
    speed = min(LIMITS.cruise_speed_mps, air)
    return (MIN_STOP_HOLD_S + Profile.rest_to_rest(distance, speed, LIMITS).duration_s
            + LEG_LATENCY_S)


def random_request(rng: np.random.Generator) -> Scenario:
    side = float(rng.uniform(150.0, 1500.0))
    start = tuple(rng.uniform(0.0, side, 2))
    goal = tuple(rng.uniform(0.0, side, 2))
    while math.dist(start, goal) < 20.0:
        goal = tuple(rng.uniform(0.0, side, 2))
    nodes = rng.uniform(0.0, side, (int(rng.integers(2, 7)), 2))
    windy = rng.random() < 0.5
    speed, from_deg = (float(rng.uniform(1.0, 6.0)), float(rng.uniform(0.0, 360.0))) \
        if windy else (0.0, 0.0)
    towards = math.radians(from_deg + 180.0)
    wind = speed * np.array([math.sin(towards), math.cos(towards)])
    line_s = straight_line_time_s(start, goal, wind, LIMITS.airspeed_mps if windy else 1e9)
    slots = int(rng.integers(30, 121))
    # The mission ends at (M + 1) delta = horizon (M + 1) / M; qF may come a quarter slot late.
    end_s = float(rng.uniform(1.05, 3.0)) * line_s
    horizon = end_s * slots / (slots + 1 + GOAL_TOLERANCE_SLOTS)
    return Scenario(ground_nodes_m=[tuple(w) for w in nodes], start_m=start, goal_m=goal,
                    max_speed_mps=LIMITS.max_speed_mps, horizon_s=horizon, num_slots=slots,
                    wind_speed_mps=speed, wind_from_deg=from_deg,
                    max_airspeed_mps=LIMITS.airspeed_mps if windy else None)


@pytest.mark.slow
def test_no_feasible_request_is_refused():
    rng = np.random.default_rng(19)
    refused = []
    fallbacks = 0
    for index in range(REQUESTS):
        scenario = random_request(rng)
        try:
            vehicle_plan = plan_for_vehicle(scenario, LIMITS)
        except Exception as exc:  # noqa: B902 - every refusal is reported with its request
            refused.append(f'request {index}: {type(exc).__name__}: {exc}')
            continue
        end_s = vehicle_plan.ideal.scenario.slot_s * (scenario.num_slots + 1)
        assert vehicle_plan.schedule.arrival_s <= end_s + GOAL_TOLERANCE_SLOTS * scenario.slot_s
        fallbacks += len(vehicle_plan.schedule.legs) == 1
    print(f'{REQUESTS} requests, none refused; {fallbacks} flown as one leg')
    assert refused == []


@pytest.mark.parametrize('firmware', ['ardupilot', 'px4'])
def test_the_quick_check_never_refuses_what_the_planning_flies(firmware):
    """check_goal_in_time (run when the parameters are set) against plan_for_vehicle on long
    slots (10 s, where the quarter slot qF may come late is more than the holds): for goals
    around the limit, a refusal by the check is a refusal by the planning too."""
    from uav_comm_planner.errors import InfeasibleHorizonError, InvalidScenarioError
    from uav_comm_planner.mission.request import check_goal_in_time
    limits = VehicleLimits.for_firmware(firmware)
    both = 0
    for distance in np.linspace(0.85, 0.999, 11) * limits.cruise_speed_mps * 110.0:
        scenario = Scenario(ground_nodes_m=((distance / 2, 50.0),), start_m=(0.0, 0.0),
                            goal_m=(float(distance), 0.0), num_slots=10, horizon_s=100.0,
                            max_speed_mps=limits.cruise_speed_mps)
        try:
            check_goal_in_time(scenario, limits, firmware)
        except InvalidScenarioError:
            with pytest.raises(InfeasibleHorizonError):
                plan_for_vehicle(scenario, limits, firmware=firmware)
            both += 1
    assert 0 < both < 11
