"""PX4's leg timing (:mod:`uav_comm_planner.vehicle.px4_timing`) against independent numbers.

The braking curve is checked against the equation it solves, the turn speed against the
figures PX4 SITL flew, a straight leg against the closed forms of its pieces (ramp, cruise at
the stretched speed), and the schedule PX4 plans are made with against its own rules: each
hold starts counting on entering the acceptance radius, the vehicle is at rest before the
next leg starts, and the ArduCopter schedule is the S-curve's as before.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from uav_comm_planner import paper_scenario, plan
from uav_comm_planner.vehicle import px4_timing
from uav_comm_planner.vehicle.flyable import schedule_flight
from uav_comm_planner.vehicle.leg_models import leg_model, LEG_MODELS, MIN_STOP_HOLD_S
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.px4_timing import (ACCEPTANCE_RADIUS_M, corner_speed,
                                                 MAX_POSITION_ERROR_M, px4_profile,
                                                 px4_reach_time, px4_speed_for_time,
                                                 stopping_speed, TRACKING_LAG_S)
from uav_comm_planner.vehicle.timing import LEG_LATENCY_S, Profile

PX4 = VehicleLimits(max_speed_mps=5.0, max_accel_mpss=3.0, max_jerk_mpsss=4.0)


@pytest.mark.parametrize('distance_m, end_mps', [(0.0, 0.0), (2.0, 0.0), (10.0, 1.5),
                                                 (300.0, 4.0)])
def test_the_braking_curve_solves_its_equation(distance_m, end_mps):
    # v^2 + b v = 2 A d + v_e^2 with b = 4 A^2 / J: braking at A after a delay of 2 A / J.
    accel, jerk = 3.0, 4.0
    v = stopping_speed(distance_m, end_mps, accel, jerk)
    b = 4 * accel ** 2 / jerk
    assert v >= 0.0
    assert v * v + b * v == pytest.approx(2 * accel * distance_m + end_mps ** 2, abs=1e-9)


def test_the_velocity_step_is_the_jerk_limited_ramp_and_composes():
    """From rest to V >= A^2 / J the ramp takes V / A + A / J seconds and loses half of it at
    V against flying at V all along; any step cut in two pieces gives the same state (the
    profile is time-optimal from wherever it is)."""
    step = px4_timing._velocity_step
    accel, jerk, speed, duration = 3.0, 4.0, 5.0, 20.0
    a, v, ds = step(0.0, 0.0, speed, accel, jerk, duration)
    ramp_s = speed / accel + accel / jerk
    assert (a, v) == (0.0, pytest.approx(speed, abs=1e-12))
    assert ds == pytest.approx(speed * duration - speed * ramp_s / 2.0, rel=1e-12)
    rng = np.random.default_rng(3)
    for _ in range(200):
        a0, v0, target = rng.uniform(-2.5, 2.5), rng.uniform(0.0, 8.0), rng.uniform(0.0, 8.0)
        whole, cut = rng.uniform(0.01, 3.0), rng.uniform(0.0, 1.0)
        a1, v1, ds1 = step(a0, v0, target, accel, jerk, whole * cut)
        a2, v2, ds2 = step(a1, v1, target, accel, jerk, whole * (1.0 - cut))
        assert np.allclose(step(a0, v0, target, accel, jerk, whole), (a2, v2, ds1 + ds2),
                           rtol=1e-9, atol=1e-9)


def test_the_turn_speed_is_what_px4_sitl_flew():
    # A 90 degree turn at R = 2 m was flown at 1.6-1.9 m/s, at R = 10 m at 3.7-4.3 m/s.
    assert corner_speed(math.pi / 2, 3.0) == pytest.approx(math.sqrt(3.0), rel=1e-9)
    assert corner_speed(math.pi / 2, 3.0, radius_m=10.0) == pytest.approx(math.sqrt(15.0))
    assert corner_speed(math.radians(180 - 20), 3.0) == pytest.approx(4.12, abs=0.01)


def test_a_straight_leg_cruises_at_the_stretched_speed_and_ends_at_rest():
    length = 1000.0
    profile = px4_profile(np.array([[0.0, 0.0], [length, 0.0]]), 5.0, PX4)
    t, s = profile.times_s, profile.distances_m
    assert np.all(np.diff(t) > 0) and np.all(np.diff(s) >= -1e-9)
    assert s[0] == 0.0 and s[-1] == pytest.approx(length, abs=0.11)
    # Cruising, the simulation jumps to where it brakes: a few hundred samples, not 10,000.
    assert len(t) < 1000
    cruise = 400.0 / (np.interp(700.0, s, t) - np.interp(300.0, s, t))
    assert cruise == pytest.approx(5.0 * (1 - TRACKING_LAG_S * 5.0 / MAX_POSITION_ERROR_M),
                                   rel=1e-3)
    # The hold starts counting in the acceptance radius, before the vehicle is at rest.
    enter = profile.distance(np.array([profile.hold_start_s]))[0]
    assert length - enter <= ACCEPTANCE_RADIUS_M + px4_timing.BRAKING_LEAD_S2 * 25 + 0.05
    assert profile.hold_start_s < profile.duration_s
    # Never faster than the rest-to-rest lower bound: cruise the whole leg at V.
    assert profile.hold_start_s > (length - ACCEPTANCE_RADIUS_M - 2.0) / 5.0


def test_a_sharp_turn_costs_time_and_a_slight_one_does_not():
    straight = px4_reach_time(np.array([[0.0, 0.0], [200.0, 0.0], [400.0, 0.0]]), 5.0, PX4)
    slight = np.array([[0.0, 0.0], [200.0, 0.0], [200.0 + 200 * math.cos(0.05),
                                                  200 * math.sin(0.05)]])
    sharp = np.array([[0.0, 0.0], [200.0, 0.0], [200.0, 200.0]])
    assert px4_reach_time(slight, 5.0, PX4) == pytest.approx(straight, abs=0.05)
    assert px4_reach_time(sharp, 5.0, PX4) > straight + 1.0


def test_the_speed_for_a_time_reaches_the_end_in_that_time():
    line = np.array([[0.0, 0.0], [300.0, 40.0]])
    for seconds in (70.0, 100.0, 150.0):
        speed = px4_speed_for_time(line, seconds, 5.0, PX4)
        assert px4_reach_time(line, speed, PX4) <= seconds
        assert px4_reach_time(line, speed - 0.01, PX4) > seconds - 0.05
    assert px4_speed_for_time(line, 10.0, 5.0, PX4) == 5.0     # too little time: at most V


def test_a_px4_schedule_counts_each_hold_from_the_acceptance_radius():
    result = plan(paper_scenario('I', max_speed_mps=5.0, horizon_s=600.0, num_slots=150))
    schedule = schedule_flight(result, PX4, firmware='px4')
    model = leg_model('px4')
    clock = 0.0
    for stop, leg in zip(schedule.stops, schedule.legs):
        assert leg.start_s == pytest.approx(clock + stop.hold_s + model.start_delay_s)
        clock = leg.start_s + leg.profile.hold_start_s
    assert schedule.arrival_s == pytest.approx(clock)
    for leg, following, stop in zip(schedule.legs, schedule.legs[1:], schedule.stops[1:]):
        assert following.start_s >= leg.end_s + MIN_STOP_HOLD_S - 1e-9   # at rest first
    end_s = result.scenario.slot_s * (result.scenario.num_slots + 1)
    assert schedule.arrival_s <= end_s + 0.25 * result.scenario.slot_s


@pytest.mark.parametrize('step_m', [2.2, 2.9])
def test_a_stop_within_reach_of_the_one_before_is_one_stop_for_px4(step_m):
    # Hover 40 s, 300 m in 60 s, hover 40 s, a step of step_m, hover 40 s, 300 m in 60 s: the
    # hovers are runs of their own (the step beyond the 2 m that merges points), but PX4 may
    # report the second reached while holding at the first (within NAV_ACC_RAD plus the
    # vehicle's wander): one stop, its hold the two hovers and the step. ArduCopter flies the
    # step.
    from test_flyable import straight_pieces

    result = straight_pieces(((0.0, 0.0), 20), ((300.0, 0.0), 30), ((0.0, 0.0), 20),
                             ((0.0, step_m), 1), ((0.0, 0.0), 20), ((300.0, 0.0), 30))
    ardupilot = schedule_flight(result, VehicleLimits(), firmware='ardupilot')
    px4 = schedule_flight(result, PX4, firmware='px4')
    assert len(ardupilot.stops) == 4
    assert len(px4.stops) == 3
    assert px4_timing.shortest_leg_m(PX4) == ACCEPTANCE_RADIUS_M + px4_timing.HOVER_WANDER_M
    middle = px4.stops[1].position_m
    assert 300.0 - 1e-9 <= middle[0] <= 300.0 + 1e-9 and 0.0 <= middle[1] <= step_m
    # Timed as the same plan with no step at all: one hover of 82 s.
    still = schedule_flight(straight_pieces(((0.0, 0.0), 20), ((300.0, 0.0), 30),
                                            ((0.0, 0.0), 41), ((300.0, step_m), 30)),
                            PX4, firmware='px4')
    assert [leg.start_s for leg in px4.legs] == pytest.approx(
        [leg.start_s for leg in still.legs], abs=0.2)
    assert px4.arrival_s == pytest.approx(still.arrival_s, abs=0.2)


def test_the_ardupilot_model_is_the_scurve_with_its_latency():
    model = LEG_MODELS['scurve']
    vertices = np.array([[0.0, 0.0], [120.0, 50.0], [400.0, 60.0]])
    length = float(np.linalg.norm(np.diff(vertices, axis=0), axis=1).sum())
    profile = model.profile(vertices, 8.0, VehicleLimits())
    reference = Profile.rest_to_rest(length, 8.0, VehicleLimits())
    assert profile.duration_s == pytest.approx(reference.duration_s)
    assert model.reached_s(profile) == pytest.approx(reference.duration_s + LEG_LATENCY_S / 2)
    assert model.start_delay_s == LEG_LATENCY_S / 2
    assert model.min_hold_s(None, 10.0, VehicleLimits()) == MIN_STOP_HOLD_S


def test_the_quick_refusal_and_the_horizon_it_asks_for_use_the_firmwares_leg_timing():
    """PX4 flies a 1000 m leg at 5 m/s about a second slower than ArduCopter's S-curve with the
    same limits: the check when parameters are set, and the horizon named when no plan flies,
    follow PX4's own timing."""
    from uav_comm_planner.errors import InfeasibleHorizonError, InvalidScenarioError
    from uav_comm_planner.mission.request import check_goal_in_time
    from uav_comm_planner.mission.policy import plan_for_vehicle

    limits = VehicleLimits.for_firmware('px4')
    line = np.array([[0.0, 0.0], [1000.0, 0.0]])
    px4_s = leg_model('px4').timed_s(leg_model('px4').profile(line, 5.0, limits))
    scurve_s = Profile.rest_to_rest(1000.0, 5.0, limits).duration_s
    assert px4_s > scurve_s + 0.5
    end_s = scurve_s + 0.1                  # (M + 1) delta: px4_s is beyond its quarter slot
    slots = 100
    scenario = paper_scenario('I', ground_nodes_m=[(500.0, 100.0)], start_m=(0.0, 0.0),
                              goal_m=(1000.0, 0.0), max_speed_mps=5.0, num_slots=slots,
                              horizon_s=end_s * slots / (slots + 1))
    check_goal_in_time(scenario, limits, 'ardupilot')
    with pytest.raises(InvalidScenarioError, match='cannot reach qF in time'):
        check_goal_in_time(scenario, limits, 'px4')
    with pytest.raises(InfeasibleHorizonError, match='lengthen horizon_s to') as refused:
        plan_for_vehicle(scenario, limits, firmware='px4')
    needed = float(str(refused.value).rsplit('lengthen horizon_s to ', 1)[1].split(' s')[0])
    flown = plan_for_vehicle(scenario.replace(horizon_s=needed), limits, firmware='px4')
    assert flown.schedule.arrival_s <= needed * (slots + 1) / slots + flown.ideal.scenario.slot_s


@pytest.mark.parametrize('speed', [0.5, 0.8, 1.2, 5.0, 10.0])
def test_the_hold_starts_the_step_the_vehicle_enters_the_acceptance_radius(speed):
    # Slow legs brake inside the radius, after the cruise the simulation jumps over: the
    # entry is still found to a step, by the profile and by the reach time alike.
    line = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 80.0]])
    profile = px4_profile(line, speed, PX4)
    radius = ACCEPTANCE_RADIUS_M + px4_timing.BRAKING_LEAD_S2 * speed * speed
    left = 180.0 - profile.distance(np.array([profile.hold_start_s]))[0]
    assert radius - speed * px4_timing.STEP_S - 1e-9 <= left <= radius
    assert px4_reach_time(line, speed, PX4) == profile.hold_start_s


def test_px4s_acceptance_radius_is_read_from_its_parameter_file_and_times_its_legs(tmp_path):
    from dataclasses import replace

    from uav_comm_planner.errors import InvalidScenarioError
    from uav_comm_planner.mission.request import vehicle_limits

    params = tmp_path / 'px4.params'
    # QGroundControl's export: SYSID COMPID NAME VALUE TYPE.
    params.write_text('1\t1\tMPC_ACC_HOR\t3.0\t9\n1\t1\tNAV_ACC_RAD\t6.0\t9\n')
    limits = vehicle_limits(parameter_file=params, firmware='px4')
    assert limits.acceptance_radius_m == 6.0
    assert vehicle_limits(firmware='px4').acceptance_radius_m is None    # PX4's 2 m
    wide = replace(PX4, acceptance_radius_m=6.0)
    # The hold starts on entering the radius it was given, not the default one.
    line = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 80.0]])
    for speed in (1.0, 5.0):
        profile = px4_profile(line, speed, wide)
        reach = 6.0 + px4_timing.BRAKING_LEAD_S2 * speed * speed
        left = 180.0 - profile.distance(np.array([profile.hold_start_s]))[0]
        assert reach - speed * px4_timing.STEP_S - 1e-9 <= left <= reach
        assert px4_reach_time(line, speed, wide) < px4_reach_time(line, speed, PX4)
    # A turn is flown faster through a wider radius (sqrt(P A R tan(alpha / 2))).
    sharp = np.array([[0.0, 0.0], [200.0, 0.0], [200.0, 200.0]])
    assert px4_profile(sharp, 5.0, wide).duration_s < px4_profile(sharp, 5.0, PX4).duration_s
    assert corner_speed(math.pi / 2, 3.0, 6.0) == pytest.approx(
        math.sqrt(0.5 * 3.0 * 6.0 * math.tan(math.pi / 4)))
    with pytest.raises(InvalidScenarioError, match='NAV_ACC_RAD'):
        replace(PX4, acceptance_radius_m=0.0)
