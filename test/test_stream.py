"""The streamed reference against independent computations: it passes the plan's points at
the slot times, and its speed, acceleration and jerk, measured by finite differences of its
own positions on a fine grid, stay within the vehicle's limits (in wind, its airspeed too)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from uav_comm_planner import paper_scenario
from uav_comm_planner.core.model import flown_path
from uav_comm_planner.core.smooth_motion import least_acceleration, MotionBounds, smooth_motion
from uav_comm_planner.errors import InfeasibleHorizonError
from uav_comm_planner.mission.policy import plan_for_vehicle
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.stream import (resume_item, STREAM_ACCEL_ALLOWANCE,
                                             stream_reference, STREAM_SPEED_MARGIN)

#: Finite-difference step, seconds.
STEP_S = 0.005
#: Room for the finite differences and the bound's sampling (relative).
SLACK = 2e-3


def differences(reference):
    """Speed and acceleration of the reference from its positions alone (central
    differences), and the jerk from its accelerations."""
    t = np.arange(STEP_S, reference.duration_s - STEP_S, STEP_S)
    before, here, after = (reference.state(t + shift)[0] for shift in (-STEP_S, 0.0, STEP_S))
    velocity = (after - before) / (2 * STEP_S)
    accel = (after - 2 * here + before) / STEP_S ** 2
    return t, velocity, accel


@pytest.fixture(scope='module')
def still_air():
    scenario = paper_scenario('I', max_speed_mps=10.0, horizon_s=400.0, num_slots=100)
    vehicle = plan_for_vehicle(scenario, VehicleLimits())
    return vehicle, stream_reference(vehicle.flown, vehicle.limits)


def test_the_reference_passes_every_slot_point_at_its_time(still_air):
    vehicle, reference = still_air
    scenario = vehicle.flown.scenario
    points = flown_path(np.asarray(vehicle.flown.trajectory), scenario)
    times = scenario.slot_s * np.arange(len(points))
    np.testing.assert_allclose(reference.state(times)[0], points, atol=1e-9)
    # At rest at q0 and qF, and before and after them.
    position, velocity, accel = reference.state(np.array([-1.0, 0.0, times[-1], times[-1] + 5]))
    np.testing.assert_allclose(velocity, 0.0, atol=1e-9)
    np.testing.assert_allclose(position[[0, 1]], [points[0]] * 2, atol=1e-9)
    np.testing.assert_allclose(position[[2, 3]], [points[-1]] * 2, atol=1e-9)


def test_speed_acceleration_and_jerk_are_within_the_vehicle_limits(still_air):
    vehicle, reference = still_air
    limits = vehicle.limits
    t, velocity, accel = differences(reference)
    speed = np.linalg.norm(velocity, axis=1).max()
    top = limits.cruise_speed_mps * (1 + STREAM_SPEED_MARGIN)
    print(f'speed {speed:.4f} m/s (limit {top:g}), acceleration '
          f'{np.linalg.norm(accel, axis=1).max():.4f} m/s/s (limit {limits.max_accel_mpss:g})')
    assert speed <= top * (1 + SLACK)
    assert np.linalg.norm(accel, axis=1).max() <= limits.max_accel_mpss * (1 + SLACK)
    # The model's own velocity and acceleration are those of its positions.
    _, model_velocity, model_accel = reference.state(t)
    np.testing.assert_allclose(model_velocity, velocity, atol=1e-3)
    # (The acceleration jumps at the knots, C1 pieces: compare away from them.)
    phase = np.remainder(t, reference.knot_s)
    away = np.minimum(phase, reference.knot_s - phase) > 2 * STEP_S
    np.testing.assert_allclose(model_accel[away], accel[away], atol=1e-3)
    # Jerk: the acceleration changes by at most J per second.
    if reference.jerk_limited:
        knots = np.arange(len(reference.positions) - 1) * reference.knot_s
        mid = reference.state(knots + reference.knot_s / 2)[2]
        start = reference.state(knots + 1e-9)[2]
        jerk = np.linalg.norm(mid - start, axis=1) / (reference.knot_s / 2)
        assert jerk.max() <= limits.max_jerk_mpsss * (1 + SLACK)


def test_in_wind_the_airspeed_stays_within_the_airframes():
    scenario = paper_scenario('I', ground_nodes_m=((300.0, 250.0), (700.0, -200.0)),
                              goal_m=(900.0, 0.0), max_speed_mps=10.0, horizon_s=300.0,
                              num_slots=60, wind_speed_mps=6.0, wind_from_deg=90.0)
    vehicle = plan_for_vehicle(scenario, VehicleLimits())
    reference = stream_reference(vehicle.flown, vehicle.limits)
    _, velocity, _ = differences(reference)
    wind = vehicle.flown.scenario.wind_mps
    airspeed = np.linalg.norm(velocity - wind, axis=1).max()
    allowed = vehicle.flown.scenario.airspeed_mps + vehicle.limits.gust_margin_mps
    print(f'airspeed at most {airspeed:.3f} m/s, allowed {allowed:g}')
    assert airspeed <= allowed * (1 + SLACK)
    points = flown_path(np.asarray(vehicle.flown.trajectory), vehicle.flown.scenario)
    np.testing.assert_allclose(reference.points, points, atol=1e-9)


def test_points_that_ask_for_too_much_are_refused_with_the_limits():
    points = np.array([[0.0, 0.0], [40.0, 0.0], [0.0, 0.0]])
    with pytest.raises(InfeasibleHorizonError, match='acceleration 1 m/s/s'):
        smooth_motion(points, 4.0, MotionBounds(speed_mps=100.0, accel_mpss=1.0))
    # Reachable at rest-to-rest: 40 m in 4 s needs at least 4 D / h^2 = 10 m/s/s.
    positions, _ = smooth_motion(np.array([[0.0, 0.0], [40.0, 0.0]]), 4.0,
                                 MotionBounds(speed_mps=100.0, accel_mpss=10.5))
    assert positions[-1] == pytest.approx([40.0, 0.0])
    with pytest.raises(InfeasibleHorizonError):
        smooth_motion(np.array([[0.0, 0.0], [40.0, 0.0]]), 4.0,
                      MotionBounds(speed_mps=100.0, accel_mpss=9.5))


def test_the_least_acceleration_motion_between_two_rests_is_the_known_one():
    """Rest to rest over D in T with no active bound: the least integral of a^2 is
    12 D^2 / T^3 (the cubic), and with free knots between it stays that cubic."""
    D, T = 30.0, 6.0
    positions, velocities = smooth_motion(np.array([[0.0, 0.0], [D, 0.0]]), T,
                                          MotionBounds(speed_mps=100.0, accel_mpss=100.0))
    t = np.linspace(0.0, T, len(positions))
    cubic = D * (3 * (t / T) ** 2 - 2 * (t / T) ** 3)
    np.testing.assert_allclose(positions[:, 0], cubic, atol=1e-5)
    np.testing.assert_allclose(velocities[:, 0], 6 * D / T * (t / T) * (1 - t / T), atol=1e-5)


def test_the_stream_resumes_the_mission_at_the_next_waypoint_ahead(still_air):
    vehicle, reference = still_air
    stops = [stop.position_m for stop in vehicle.schedule.stops]
    waypoints = [(10 + index, position) for index, position in enumerate(stops)]
    # Just after leaving q0 the next waypoint is the second stop; at the end, the last.
    assert resume_item(waypoints, reference, 5.0) == 11
    assert resume_item(waypoints, reference, reference.duration_s + 1.0) == waypoints[-1][0]
    middle = resume_item(waypoints, reference, reference.duration_s / 2)
    assert 11 <= middle <= waypoints[-1][0]
    assert not math.isnan(middle)


@pytest.fixture(scope='module')
def px4_at_10():
    """A PX4 plan at 10 m/s (MPC_XY_CRUISE 10, PX4's MPC_ACC_HOR 3 m/s/s) whose points no
    motion within 3 m/s/s passes at their times."""
    from uav_comm_planner.mission.request import vehicle_limits

    scenario = paper_scenario('I', ground_nodes_m=((-150.0, 150.0), (150.0, 350.0)),
                              start_m=(0.0, 10.0), goal_m=(0.0, 400.0), horizon_s=120.0,
                              num_slots=30, altitude_m=30.0, max_speed_mps=10.0)
    limits = vehicle_limits({'max_speed_mps': 10.0}, firmware='px4')
    assert limits.max_accel_mpss == 3.0
    return plan_for_vehicle(scenario, limits, firmware='px4')


def test_a_px4_plan_needing_more_than_its_acceleration_streams_with_the_least_that_passes(
        px4_at_10):
    vehicle = px4_at_10
    limits = vehicle.limits
    with pytest.raises(InfeasibleHorizonError, match='acceleration 3 m/s/s'):
        stream_reference(vehicle.flown, limits)         # ArduCopter's GUIDED: no more asked
    reference = stream_reference(vehicle.flown, limits,
                                 accel_allowance=STREAM_ACCEL_ALLOWANCE['px4'])
    assert reference.accel_raised
    raised = reference.bounds.accel_mpss
    assert limits.max_accel_mpss < raised <= 2.0 * limits.max_accel_mpss
    # The least: a little less (below the headroom) passes no motion.
    points = flown_path(np.asarray(vehicle.flown.trajectory), vehicle.flown.scenario)
    with pytest.raises(InfeasibleHorizonError):
        smooth_motion(points, vehicle.flown.scenario.slot_s,
                      MotionBounds(reference.bounds.speed_mps, raised / 1.03,
                                   wind_mps=reference.bounds.wind_mps,
                                   airspeed_mps=reference.bounds.airspeed_mps))
    # It passes every point at its time and keeps the raised bound, by finite differences.
    times = vehicle.flown.scenario.slot_s * np.arange(len(points))
    np.testing.assert_allclose(reference.state(times)[0], points, atol=1e-9)
    _, velocity, accel = differences(reference)
    assert np.linalg.norm(accel, axis=1).max() <= raised * (1 + SLACK)
    assert np.linalg.norm(velocity, axis=1).max() <= reference.bounds.speed_mps * (1 + SLACK)


def test_a_stream_needing_more_than_the_allowance_is_refused_with_what_it_needs(px4_at_10):
    # Rest to rest over 40 m in 4 s: the least peak acceleration of a cubic is 6 D / T^2,
    # 15 m/s/s with one piece; free knots between lower it towards bang-bang's 4 D / T^2.
    points = np.array([[0.0, 0.0], [40.0, 0.0]])
    bounds = MotionBounds(speed_mps=100.0, accel_mpss=3.0)
    assert least_acceleration(points, 4.0, bounds, pieces=1) == pytest.approx(15.0, rel=1e-4)
    assert 10.0 <= least_acceleration(points, 4.0, bounds) < 15.0
    with pytest.raises(InfeasibleHorizonError, match='no smooth motion'):
        least_acceleration(points, 4.0, MotionBounds(speed_mps=9.0, accel_mpss=3.0))
    with pytest.raises(InfeasibleHorizonError, match=r'the points need 3\.\d+ m/s/s, more '
                                                     r'than the 3\.15 m/s/s'):
        stream_reference(px4_at_10.flown, px4_at_10.limits, accel_allowance=1.05)
