"""Climbs in the vehicle's timing and in the mission: ArduCopter's 3D S-curve limits, a leg with
climbs timed as ArduCopter times its track, waypoints at their planned altitudes, a take-off to
q0's, climbs and descents within WPNAV_SPEED_UP and WPNAV_SPEED_DN along the predicted flight,
and bad input refused."""

from __future__ import annotations

import json
import math

import numpy as np
from pymavlink import mavwp
import pytest
from test_altitude import recomputed

from uav_comm_planner import paper_scenario
from uav_comm_planner.core.altitude import AltitudeLimits
from uav_comm_planner.core.model import flown_path
from uav_comm_planner.core.optimizer import plan_along
from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.mission.altitude import plan_altitude_for_vehicle
from uav_comm_planner.tools import cli
from uav_comm_planner.tools.serialize import scenario_from_dict
from uav_comm_planner.vehicle.climbs import (check_climb_rate, ClimbLimits, kinematic_limit,
                                             leg_limits)
from uav_comm_planner.vehicle.flyable import flown_result, schedule_flight, VehiclePlan
from uav_comm_planner.vehicle.geodesy import geodetic_to_enu, Home
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink.files import read_mission_file, write_mission_file
from uav_comm_planner.vehicle.mavlink.items import build_mission_items
from uav_comm_planner.vehicle.timing import leg_time, Profile

WAYPOINT, TAKEOFF = 16, 22
HOME = Home(-35.363262, 149.165237, 584.0)


@pytest.mark.parametrize('horizontal, vertical', [
    (100.0, 0.0), (100.0, 10.0), (100.0, -10.0), (100.0, 60.0), (10.0, -30.0), (0.0, 5.0),
    (0.0, -5.0), (3.0, 1.2)])
def test_kinematic_limit_is_the_largest_magnitude_within_both_limits(horizontal, vertical):
    largest = kinematic_limit(horizontal, vertical, 10.0, 2.5, 1.5)
    length = math.hypot(horizontal, vertical)
    # Independently: scan magnitudes, keep those whose parts are within the limits.
    scan = np.linspace(0.0, 50.0, 500_001)
    fits = ((scan * horizontal / length <= 10.0 + 1e-12)
            & (scan * abs(vertical) / length <= (2.5 if vertical > 0 else 1.5) + 1e-12))
    assert largest == pytest.approx(scan[fits].max(), abs=1e-4)


@pytest.mark.parametrize('rise', [0.0, 8.0, -8.0, 25.0, -30.0])
def test_a_leg_with_a_climb_takes_the_time_of_arducopters_3d_track(rise):
    limits, climb = VehicleLimits(), ClimbLimits()
    path = np.array([[0.0, 0.0], [120.0, 90.0]])             # 150 m over the ground
    heights = np.array([40.0, 40.0 + rise])
    cruise, own = leg_limits(path, heights, limits, climb)
    speed = min(cruise, 8.0)
    horizontal = Profile.rest_to_rest(150.0, speed, own)
    # ArduCopter's own view: the track along the 3D segment with its kinematic limits.
    track = math.hypot(150.0, rise)
    along = replace_limits(limits, kinematic_limit(150.0, rise, limits.max_accel_mpss,
                                                   climb.accel_mpss, climb.accel_mpss))
    expected = leg_time(track, kinematic_limit(150.0, rise, speed, climb.up_mps,
                                               climb.down_mps), along)
    assert horizontal.duration_s == pytest.approx(expected, rel=1e-9)
    # The climb the cruise asks is within the vehicle's vertical limit.
    assert speed * abs(rise) / 150.0 <= (climb.up_mps if rise > 0 else climb.down_mps)


def replace_limits(limits: VehicleLimits, accel: float) -> VehicleLimits:
    return VehicleLimits(max_speed_mps=limits.max_speed_mps, max_accel_mpss=accel,
                         max_jerk_mpsss=limits.max_jerk_mpsss, jerk_time_s=limits.jerk_time_s)


def climbing_plan():
    """A plan along case I's straight line at 4 m/s whose altitude climbs 30 -> 90 m and comes
    back down, at 1 m/s."""
    scenario = paper_scenario('I', max_speed_mps=10.0, horizon_s=500.0, num_slots=100)
    t = scenario.times_s
    q = np.column_stack([np.linspace(20.0, 1980.0, len(t)), np.zeros(len(t))])
    altitudes = np.clip(30.0 + 1.0 * np.minimum(t, t[-1] - t), 30.0, 90.0)
    result = plan_along(scenario, q, name='climbs')
    return result, altitudes


def test_the_mission_carries_every_waypoints_altitude_and_takes_off_to_q0s(tmp_path):
    result, altitudes = climbing_plan()
    schedule = schedule_flight(result, VehicleLimits(), altitudes=altitudes)
    points = flown_path(result.trajectory, result.scenario)
    heights = np.concatenate([altitudes[:1], altitudes, altitudes[-1:]])
    timed = VehiclePlan(result, flown_result(result, schedule), schedule, VehicleLimits())
    items = build_mission_items(timed, HOME)
    assert items[1].command == TAKEOFF and items[1].z == pytest.approx(altitudes[0], abs=0.005)
    waypoints = [item for item in items[2:] if item.command == WAYPOINT]
    east, north, _ = geodetic_to_enu(np.array([w.x for w in waypoints]),
                                     np.array([w.y for w in waypoints]), HOME.altitude_m, HOME)
    for x, y, item in zip(east, north, waypoints):
        nearest = int(np.argmin(np.hypot(points[:, 0] - x, points[:, 1] - y)))
        assert np.hypot(*(points[nearest] - (x, y))) < 0.1
        assert item.z == pytest.approx(heights[nearest], abs=0.005)   # whole centimetres
    assert {round(item.z, 3) for item in waypoints} == {30.0, 35.0, 90.0}   # the profile's bends
    # Both files keep the altitudes, read back as written.
    for name in ('m.waypoints', 'm.plan'):
        path = write_mission_file(items, tmp_path / name, HOME)
        assert [item.z for item in read_mission_file(path)][1:] == pytest.approx(
            [item.z for item in items][1:], abs=1e-6)


def test_the_predicted_flight_climbs_and_descends_within_the_vehicles_limits():
    result, altitudes = climbing_plan()
    climb = ClimbLimits()
    schedule = schedule_flight(result, VehicleLimits(), altitudes=altitudes, climb=climb)
    t = np.arange(0.0, schedule.flight.end_s, 0.05)
    up = schedule.flight.altitudes(t)
    rate = np.diff(up) / 0.05
    print(f'\nfastest climb {rate.max():.3f} m/s, descent {-rate.min():.3f} m/s')
    assert rate.max() <= climb.up_mps + 1e-6
    assert -rate.min() <= climb.down_mps + 1e-6
    # Along the track the altitude is the plan's where the plan passes (the waypoints keep its
    # altitude profile within the 1 m path tolerance).
    x = schedule.flight.positions(t)[:, 0]
    points = flown_path(result.trajectory, result.scenario)[:, 0]
    planned = np.interp(x, points, np.concatenate([altitudes[:1], altitudes, altitudes[-1:]]))
    print(f'altitude along the track within {np.abs(up - planned).max():.2f} m of the plan')
    assert np.abs(up - planned).max() <= 1.0 + 1e-6


def test_a_level_flight_has_no_altitudes():
    result, _ = climbing_plan()
    schedule = schedule_flight(result, VehicleLimits())
    assert schedule.flight.altitudes([0.0, 10.0]) is None
    assert all(stop.altitude_m is None for stop in schedule.stops)


def test_a_vertical_limit_slows_a_leg_that_would_climb_too_fast():
    path = np.array([[0.0, 0.0], [100.0, 0.0]])
    cruise, own = leg_limits(path, np.array([30.0, 80.0]), VehicleLimits(), ClimbLimits())
    assert cruise == pytest.approx(0.95 * 2.5 / 0.5)            # 50 m up over 100 m
    assert own.max_accel_mpss == pytest.approx(1.0 / 0.5)       # WPNAV_ACCEL_Z / slope
    assert own.max_jerk_mpsss == pytest.approx(1.0 / math.sqrt(1.25))


@pytest.mark.parametrize('values', [dict(up_mps=0.0), dict(down_mps=-1.0),
                                    dict(accel_mpss=math.nan), dict(up_mps='fast')])
def test_bad_climb_limits_are_a_typed_error(values):
    with pytest.raises(InvalidScenarioError, match='climb'):
        ClimbLimits(**values)


SLOW = paper_scenario('I', max_speed_mps=10.0, horizon_s=400.0, num_slots=50)


def test_a_plan_climbing_faster_than_the_vehicle_descends_is_refused():
    check_climb_rate(1.5, ClimbLimits())
    with pytest.raises(InvalidScenarioError, match='WPNAV_SPEED_DN'):
        check_climb_rate(2.5, ClimbLimits())
    with pytest.raises(InvalidScenarioError, match='WPNAV_SPEED_DN'):
        plan_altitude_for_vehicle(SLOW, AltitudeLimits((30.0, 90.0), 2.5))
    with pytest.raises(InvalidScenarioError, match='ardupilot only'):
        plan_altitude_for_vehicle(SLOW, AltitudeLimits((30.0, 90.0), 1.0),
                                  firmware='px4')


def test_command_line_writes_a_mission_with_altitudes_and_states_it_as_flown(tmp_path, capsys):
    mission, result_file = tmp_path / 'm.waypoints', tmp_path / 'r.json'
    status = cli.main(['plan', '--nodes', '300,0', '--nodes', '900,100', '--start', '0,0',
                       '--goal', '1200,0', '--speed', '10', '--horizon', '240', '--slots', '24',
                       '--bandwidth', '1e6', '--noise-dbm', '-145', '--budget', '0.1',
                       '--channel', 'los:urban', '--altitude-range', '30,120',
                       '--mission', str(mission), '--json', str(result_file)])
    out, _ = capsys.readouterr()
    assert status == 0 and 'as the vehicle flies it' in out
    data = json.loads(result_file.read_text())
    flown = data['flown']
    scenario = scenario_from_dict(data)
    # The stated throughput is the gain written out at the flown positions and altitudes.
    assert flown['min_throughput'] == pytest.approx(recomputed(
        'urban', flown['trajectory'], flown['altitudes_m'], flown['power'], scenario), rel=1e-6)
    assert flown['min_throughput'] <= data['min_throughput'] * (1 + 1e-9)
    assert flown['min_throughput'] >= flown['alternative_throughput']   # never below level
    loader = mavwp.MAVWPLoader()
    loader.load(str(mission))
    rows = [loader.wp(i) for i in range(loader.count())]
    assert rows[1].command == TAKEOFF
    waypoints = [row for row in rows if row.command == WAYPOINT][1:]
    assert rows[1].z == pytest.approx(waypoints[0].z) == pytest.approx(
        data['altitudes_m'][0], abs=0.005)
    assert all(30.0 - 1e-6 <= row.z <= 120.0 + 1e-6 for row in waypoints)
    climbs = np.diff(data['altitudes_m'])
    assert np.abs(climbs).max() <= 1.5 * scenario.slot_s + 1e-6   # the vehicle's descent rate
