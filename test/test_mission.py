"""Mission export: files that pymavlink and QGroundControl load, on the plan's points and timing.

The checks read the written files back (mavwp's loader, json) and replay them kinematically
with their own code: leg length over the commanded speed, plus the holds.
"""

import json
import math
import os
from pathlib import Path
import re

import numpy as np
import pymap3d
from pymavlink import mavwp
import pytest

from uav_comm_planner import InvalidScenarioError, MissionExportError, paper_scenario, plan
from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.errors import MissionFileError, VehicleLinkError
from uav_comm_planner.mission.request import MissionRequest
from uav_comm_planner.vehicle.evaluation import distance_to_polyline
from uav_comm_planner.mission.policy import plan_for_vehicle
from uav_comm_planner.vehicle.flyable import (MERGE_RADIUS_M, MIN_SPEED_MPS, PATH_TOLERANCE_M,
                                              schedule_flight)
from uav_comm_planner.vehicle.geodesy import DEFAULT_HOME, enu_to_geodetic, geodetic_to_enu, Home
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink import files
from uav_comm_planner.vehicle.mavlink.files import export_mission, read_mission_file
from uav_comm_planner.vehicle.mavlink.items import build_mission_items, DEGREE_DECIMALS
from uav_comm_planner.vehicle.timing import ramp_time

WAYPOINT, TAKEOFF, LAND, RTL, CHANGE_SPEED = 16, 22, 21, 20, 178
#: The vehicle each firmware's mission is timed for: ArduCopter's defaults; PX4's MPC_ACC_HOR
#: and MPC_JERK_AUTO defaults (3 m/s/s, 4 m/s/s/s) with MPC_XY_CRUISE 10 m/s.
LIMITS = {'ardupilot': VehicleLimits(),
          'px4': VehicleLimits(max_speed_mps=10.0, max_accel_mpss=3.0, max_jerk_mpsss=4.0)}
POSITION_TOLERANCE_M = 0.5


def multirotor_case_one() -> Scenario:
    """The letter's case I at a multirotor's 10 m/s: 400 s in 100 slots of 4 s."""
    return paper_scenario('I', max_speed_mps=10.0, horizon_s=400.0, num_slots=100)


@pytest.fixture(scope='module')
def case_one() -> PlanResult:
    return plan(multirotor_case_one())


@pytest.fixture(scope='module')
def home() -> Home:
    return Home(*DEFAULT_HOME)


def synthetic_result(q, *, start=(0.0, 0.0), goal, horizon_s, speed=10.0) -> PlanResult:
    """A plan with a given trajectory q (M, 2); the power schedule plays no part in export."""
    q = np.asarray(q, dtype=float)
    scenario = Scenario(ground_nodes_m=((0.0, 50.0),), altitude_m=30.0, max_speed_mps=speed,
                        horizon_s=horizon_s, num_slots=len(q), start_m=start, goal_m=goal)
    return PlanResult(scenario=scenario, trajectory=q, times=scenario.times_s,
                      power=np.zeros((1, len(q))), rates=np.zeros(1), min_throughput=0.0,
                      history=())


def planned_path(result: PlanResult) -> tuple[np.ndarray, np.ndarray]:
    """q0, q[1..M], qF (M + 2, 2) and their times (M + 2,), from the result's own fields."""
    scenario = result.scenario
    path = np.vstack([scenario.start_m, result.trajectory, scenario.goal_m])
    times = np.concatenate([[0.0], result.times, [result.times[-1] + scenario.slot_s]])
    return path, times


def load(path: Path):
    loader = mavwp.MAVWPLoader()
    count = loader.load(str(path))
    return [loader.wp(i) for i in range(count)]


def to_enu(item, home: Home) -> np.ndarray:
    east, north, _ = pymap3d.geodetic2enu(item.x, item.y, home.altitude_m, home.latitude_deg,
                                          home.longitude_deg, home.altitude_m)
    return np.array([east, north])


def written(result, tmp_path, home, name='m.waypoints', **options):
    target = export_mission(result, tmp_path / name, home, **options)
    assert target == tmp_path / name
    return target


# The QGC WPL 110 file.

def test_waypoints_file_has_the_format_qgroundcontrol_and_mission_planner_read(
        case_one, home, tmp_path):
    target = written(case_one, tmp_path, home)
    lines = target.read_text().splitlines()
    assert lines[0] == 'QGC WPL 110'
    for number, line in enumerate(lines[1:]):
        fields = line.split('\t')
        assert len(fields) == 12, line
        assert not line.startswith('#')
        assert int(fields[0]) == number
    items = load(target)
    assert len(items) == len(lines) - 1
    home_row, takeoff = items[0], items[1]
    assert (home_row.command, home_row.frame) == (WAYPOINT, 0)
    assert (home_row.x, home_row.y, home_row.z) == pytest.approx(DEFAULT_HOME, abs=1e-6)
    assert (takeoff.command, takeoff.frame, takeoff.z) == (TAKEOFF, 3, 100.0)
    assert items[-1].command == LAND and items[-1].z == 0.0
    assert all(item.autocontinue == 1 for item in items)
    assert {item.frame for item in items if item.command == WAYPOINT} - {0} == {3}


def test_every_waypoint_lies_on_the_plan_and_covers_it(case_one, home, tmp_path):
    items = load(written(case_one, tmp_path, home))
    path, _ = planned_path(case_one)
    waypoints = np.array([to_enu(item, home) for item in items[2:] if item.command == WAYPOINT])
    gaps = np.linalg.norm(waypoints[:, None, :] - path[None, :, :], axis=-1)
    assert gaps.min(axis=1).max() <= POSITION_TOLERANCE_M
    # Every plan point lies near the line the mission flies: a hover within the merge radius
    # of its stop, a point in flight within the path tolerance of its leg.
    line = distance_to_polyline(path, waypoints)
    assert line.max() <= MERGE_RADIUS_M + PATH_TOLERANCE_M + POSITION_TOLERANCE_M
    assert np.allclose(waypoints[0], case_one.scenario.start_m, atol=POSITION_TOLERANCE_M)
    assert np.allclose(waypoints[-1], case_one.scenario.goal_m, atol=POSITION_TOLERANCE_M)
    land = to_enu(items[-1], home)
    assert np.allclose(land, case_one.scenario.goal_m, atol=POSITION_TOLERANCE_M)


@pytest.mark.parametrize('firmware', ['ardupilot', 'px4'])
def test_the_file_holds_the_schedule(case_one, home, tmp_path, firmware):
    """Waypoints, holds and speeds are the schedule's, in order; speeds change only where a
    leg starts, right after the stop it leaves."""
    schedule = schedule_flight(case_one, LIMITS[firmware], firmware=firmware)
    items = load(written(case_one, tmp_path, home, firmware=firmware, limits=LIMITS[firmware]))
    timed = items[2:-1]
    expected, in_force = [], None
    for index, stop in enumerate(schedule.stops):
        expected.append((WAYPOINT, tuple(stop.position_m), stop.hold_s))
        if index < len(schedule.legs):
            leg = schedule.legs[index]
            if leg.speed_mps != in_force:
                in_force = leg.speed_mps
                expected.append((CHANGE_SPEED, None, in_force))
            expected += [(WAYPOINT, tuple(vertex), 0.0) for vertex in leg.vertices[1:-1]]
    assert len(timed) == len(expected)
    for item, (command, position, value) in zip(timed, expected):
        assert item.command == command
        if command == CHANGE_SPEED:
            assert (item.param1, item.param2, item.param3) == pytest.approx((1.0, value, -1.0))
        else:
            assert item.param1 == pytest.approx(value, abs=0.005)
            assert to_enu(item, home) == pytest.approx(position, abs=POSITION_TOLERANCE_M)
    if firmware == 'ardupilot':
        assert all(float(item.param1).is_integer() for item in timed if item.command == WAYPOINT)


@pytest.mark.parametrize('firmware', ['ardupilot', 'px4'])
def test_a_plan_file_holds_its_numbers_rounded(tmp_path, capsys, firmware):
    """No float arithmetic's tail (a PX4 hold of 6.380000000002752 s): holds and speeds to
    1e-6, latitude and longitude to 1e-8 degree."""
    from uav_comm_planner.tools import cli
    target = tmp_path / 'm.plan'
    speed, horizon = ('5', '500') if firmware == 'px4' else ('10', '400')
    assert cli.main(['plan', '--case', 'I', '--speed', speed, '--horizon', horizon, '--slots',
                     '125', '--firmware', firmware, '--mission', str(target)]) == 0
    capsys.readouterr()
    text = target.read_text()
    assert re.findall(r'\d\.\d{9,}', text) == []
    holds = [item['params'][0] for item in json.loads(text)['mission']['items']
             if item['command'] == 16]
    assert any(0 < hold != round(hold) for hold in holds) == (firmware == 'px4')


def test_every_waypoint_has_the_coordinates_of_its_point_converted_alone(case_one, home):
    """The waypoints are converted to latitude and longitude in one call: each gets what
    pymap3d gives its point alone, to the digit the file keeps."""
    schedule = schedule_flight(case_one, LIMITS['ardupilot'])
    points = []
    for index, stop in enumerate(schedule.stops):
        points.append(stop.position_m)
        if index < len(schedule.legs):
            points += list(schedule.legs[index].vertices[1:-1])
    waypoints = [item for item in build_mission_items(case_one, home)[2:-1]
                 if item.command == WAYPOINT]
    assert len(waypoints) == len(points)
    for item, (east, north) in zip(waypoints, points):
        latitude, longitude, _ = pymap3d.enu2geodetic(
            float(east), float(north), 0.0, home.latitude_deg, home.longitude_deg,
            home.altitude_m, ell=pymap3d.Ellipsoid.from_name('wgs84'), deg=True)
        assert (item.x, item.y) == (round(float(latitude), DEGREE_DECIMALS),
                                    round(float(longitude), DEGREE_DECIMALS))


def test_hover_holds_where_the_plan_hovers(case_one, home, tmp_path):
    """Each node gets one stop whose hold is its planned hover less what a stop costs."""
    items = load(written(case_one, tmp_path, home))
    path, _ = planned_path(case_one)
    delta = case_one.scenario.slot_s
    legs = np.linalg.norm(np.diff(path, axis=0), axis=1)
    waypoints = [(to_enu(item, home), item.param1) for item in items[2:]
                 if item.command == WAYPOINT]
    limits = VehicleLimits()
    stop_cost = ramp_time(limits.cruise_speed_mps, limits) + 1.0
    for node in case_one.scenario.nodes:
        near = np.linalg.norm(path - node, axis=1) < 25.0
        hovering = ((legs < 0.5) & near[:-1] & near[1:]).sum() * delta
        assert hovering >= 30.0, 'case I hovers over every node'
        holds = [hold for position, hold in waypoints if np.linalg.norm(position - node) < 25.0]
        assert len(holds) == 1
        assert hovering - 2 * stop_cost - 1.0 <= holds[0] <= hovering


def test_speeds_stay_within_the_vehicles(case_one, home, tmp_path):
    items = load(written(case_one, tmp_path, home))
    speeds = [item.param2 for item in items if item.command == CHANGE_SPEED]
    assert speeds and max(speeds) <= VehicleLimits().cruise_speed_mps
    assert min(speeds) >= MIN_SPEED_MPS


def test_a_plan_faster_than_the_vehicle_is_refused_before_any_file(home, tmp_path):
    fast = plan(paper_scenario('I'))                      # the letter's 100 m/s
    with pytest.raises(MissionExportError, match=r'100 m/s is faster than the vehicle flies'):
        export_mission(fast, tmp_path / 'm.waypoints', home)
    assert list(tmp_path.iterdir()) == []
    quick = VehicleLimits(max_speed_mps=100.0, max_accel_mpss=50.0, max_jerk_mpsss=500.0,
                          jerk_time_s=0.01)
    assert export_mission(fast, tmp_path / 'm.waypoints', home, limits=quick).is_file()


def test_a_vehicle_plan_exports_its_own_schedule_for_its_firmware(home, tmp_path):
    vehicle_plan = plan_for_vehicle(multirotor_case_one(), LIMITS['px4'], firmware='px4')
    written(vehicle_plan, tmp_path, home, name='m.plan', firmware='px4')
    with pytest.raises(MissionExportError, match='timed for px4, not ardupilot'):
        export_mission(vehicle_plan, tmp_path / 'm.waypoints', home)


def test_rtl_ends_the_mission_when_asked(case_one, home, tmp_path):
    items = load(written(case_one, tmp_path, home, end='rtl'))
    assert items[-1].command == RTL
    assert items[-2].command == WAYPOINT
    assert np.allclose(to_enu(items[-2], home), case_one.scenario.goal_m, atol=0.5)


def test_a_plan_that_never_moves_is_one_hold_then_land(home, tmp_path):
    result = synthetic_result([(0.5, 0.0)] * 6, goal=(0.0, 0.5), horizon_s=12.0)
    items = load(written(result, tmp_path, home))
    commands = [item.command for item in items]
    assert commands == [WAYPOINT, TAKEOFF, WAYPOINT, LAND]
    assert items[2].param1 == pytest.approx(result.scenario.slot_s * 7)


# The QGroundControl .plan file.

@pytest.mark.parametrize('firmware, firmware_type', [('ardupilot', 3), ('px4', 12)])
def test_plan_file_has_every_field_qgroundcontrol_requires(case_one, home, tmp_path, firmware,
                                                           firmware_type):
    target = written(case_one, tmp_path, home, name='m.plan', firmware=firmware,
                     limits=LIMITS[firmware])
    document = json.loads(target.read_text())
    assert (document['fileType'], document['version']) == ('Plan', 1)
    assert document['groundStation'] == 'QGroundControl'
    assert document['geoFence'] == {'circles': [], 'polygons': [], 'version': 2}
    assert document['rallyPoints'] == {'points': [], 'version': 2}
    plan_mission = document['mission']
    assert plan_mission['version'] == 2
    assert plan_mission['firmwareType'] == firmware_type
    assert plan_mission['vehicleType'] == 2
    assert plan_mission['plannedHomePosition'] == pytest.approx(list(DEFAULT_HOME))
    for key in ('cruiseSpeed', 'hoverSpeed'):
        assert plan_mission[key] > 0
    for seq, item in enumerate(plan_mission['items'], start=1):
        assert item['type'] == 'SimpleItem' and item['autoContinue'] is True
        assert item['doJumpId'] == seq
        assert isinstance(item['command'], int) and isinstance(item['frame'], int)
        assert len(item['params']) == 7
        assert all(v is None or isinstance(v, (int, float)) for v in item['params'])
        if item['frame'] == 3:
            assert item['AltitudeMode'] == 1
            assert item['Altitude'] == item['params'][6]
            assert 'AMSLAltAboveTerrain' in item


@pytest.mark.parametrize('firmware', ['ardupilot', 'px4'])
def test_plan_file_holds_the_same_items_as_the_waypoints_file(case_one, home, tmp_path,
                                                              firmware):
    rows = load(written(case_one, tmp_path, home, firmware=firmware, limits=LIMITS[firmware]))
    document = json.loads(written(case_one, tmp_path, home, name='m.plan', firmware=firmware,
                                  limits=LIMITS[firmware]).read_text())
    entries = document['mission']['items']
    assert len(entries) == len(rows) - 1
    for row, entry in zip(rows[1:], entries):
        assert (entry['command'], entry['frame']) == (row.command, row.frame)
        mine = [math.nan if v is None else v for v in entry['params']]
        theirs = [row.param1, row.param2, row.param3, row.param4, row.x, row.y, row.z]
        assert np.allclose(mine, theirs, atol=1e-6, equal_nan=True)
    if firmware == 'px4':
        assert any(entry['params'][3] is None for entry in entries)


# Safe writing and clear errors.

@pytest.mark.parametrize('name', ['m.txt', 'mission', 'm.json'])
def test_an_unknown_extension_is_refused(case_one, home, tmp_path, name):
    with pytest.raises(MissionExportError, match=r'unknown mission format.*\.waypoints or \.plan'):
        export_mission(case_one, tmp_path / name, home)
    assert list(tmp_path.iterdir()) == []


def test_a_missing_folder_is_a_clear_error(case_one, home, tmp_path):
    with pytest.raises(MissionExportError, match='folder .*nowhere.* does not exist'):
        export_mission(case_one, tmp_path / 'nowhere' / 'm.waypoints', home)


def test_an_unwritable_path_is_a_clear_error(case_one, home, tmp_path):
    (tmp_path / 'taken.waypoints').mkdir()
    with pytest.raises(MissionExportError, match='it is a folder'):
        export_mission(case_one, tmp_path / 'taken.waypoints', home)
    (tmp_path / 'file').write_text('x')
    with pytest.raises(MissionExportError, match='is not a folder'):
        export_mission(case_one, tmp_path / 'file' / 'm.waypoints', home)


def test_a_folder_without_write_permission_is_a_clear_error(case_one, home, tmp_path,
                                                            monkeypatch):
    # Tests may run as root, whom chmod does not stop; refuse the temporary file instead.
    def refuse(*args, **kwargs):
        raise PermissionError(13, 'Permission denied', str(tmp_path))
    monkeypatch.setattr('tempfile.mkstemp', refuse)
    with pytest.raises(MissionExportError, match='cannot write .*Permission denied'):
        export_mission(case_one, tmp_path / 'm.waypoints', home)


@pytest.mark.parametrize('name, breaks', [
    ('m.waypoints', 'write_waypoints'), ('m.plan', 'plan_document'), ('m.plan', 'os.replace')])
def test_a_failed_write_keeps_the_old_file_byte_for_byte(case_one, home, tmp_path,
                                                         monkeypatch, name, breaks):
    target = written(case_one, tmp_path, home, name=name)
    before = target.read_bytes()

    def half_write(items, path, *args, **kwargs):
        Path(path).write_text('QGC WPL 110\n0\t1\t0\t16')
        raise OSError(28, 'No space left on device')

    def no_document(*args, **kwargs):
        raise ValueError('cannot serialise')

    def no_rename(*args, **kwargs):
        raise OSError(5, 'Input/output error')

    replacement = {'write_waypoints': half_write, 'plan_document': no_document,
                   'os.replace': no_rename}[breaks]
    if breaks == 'os.replace':
        monkeypatch.setattr(os, 'replace', replacement)
    else:
        monkeypatch.setattr(files, breaks, replacement)
    with pytest.raises(MissionExportError, match='previous file, if any, is unchanged'):
        export_mission(case_one, target, home, end='rtl')
    assert target.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


def test_rewriting_keeps_the_file_mode(case_one, home, tmp_path):
    target = written(case_one, tmp_path, home)
    assert target.stat().st_mode & 0o777 == 0o644
    target.chmod(0o640)
    written(case_one, tmp_path, home)
    assert target.stat().st_mode & 0o777 == 0o640


@pytest.mark.parametrize('options, message', [
    ({'end': 'hover'}, 'unknown mission end'),
    ({'firmware': 'inav'}, 'unknown firmware'),
    ({'limits': (10.0, 2.5)}, 'limits must be VehicleLimits'),
])
def test_bad_options_are_refused(case_one, home, tmp_path, options, message):
    with pytest.raises(MissionExportError, match=message):
        export_mission(case_one, tmp_path / 'm.waypoints', home, **options)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize('name, text, message', [
    ('m.txt', 'QGC WPL 110\n', 'a mission is a .waypoints'),
    ('m.waypoints', 'QGC WPL 999\n', 'not a QGC WPL 110 mission'),
    ('m.waypoints', 'QGC WPL 110\n', 'holds no mission item'),
    ('m.plan', '{"mission": {}}', 'not a QGroundControl .plan mission'),
    ('m.plan', '{"mission": {"plannedHomePosition": [1, 2, 3], "items": [{"type": "Survey"}]}}',
     'only simple items'),
    ('missing.plan', None, 'no such mission file'),
])
def test_a_mission_file_that_cannot_be_read_is_a_file_error(tmp_path, name, text, message):
    path = tmp_path / name
    if text is not None:
        path.write_text(text)
    with pytest.raises(MissionFileError, match=message) as refused:
        read_mission_file(path)
    assert not isinstance(refused.value, VehicleLinkError)


def test_a_written_mission_reads_back_as_its_items(case_one, home, tmp_path):
    """The .plan file keeps every row; the .waypoints file rounds coordinates to 6 decimals."""
    items = build_mission_items(case_one, home)
    assert read_mission_file(written(case_one, tmp_path, home, name='m.plan')) == items
    rows = read_mission_file(written(case_one, tmp_path, home))
    assert [(row.command, row.frame, row.params) for row in rows] == [
        (item.command, item.frame, item.params) for item in items]


# The geodetic anchor.

@pytest.mark.parametrize('values, message', [
    ((math.nan, 8.5, 400.0), 'latitude_deg must be a finite number'),
    ((47.0, math.inf, 400.0), 'longitude_deg must be a finite number'),
    ((91.0, 8.5, 400.0), r'latitude must be in \[-90, 90\]'),
    ((47.0, -180.5, 400.0), r'longitude must be in \[-180, 180\]'),
    ((47.0, 8.5, '400'), 'altitude_m must be a finite number'),
])
def test_home_is_validated(values, message):
    with pytest.raises(InvalidScenarioError, match=message):
        Home(*values)


def test_home_is_parsed_from_the_command_line_form():
    assert Home.parse(' -35.363262, 149.165237 ,584') == Home(*DEFAULT_HOME)
    for text in ('47.3,8.5', '47.3,8.5,abc', '47.3;8.5;400'):
        with pytest.raises(InvalidScenarioError, match='LAT,LON,ALT'):
            Home.parse(text)


def test_enu_anchor_is_wgs84_not_a_sphere(home):
    latitude, longitude, _ = enu_to_geodetic(np.array([0.0, 2000.0]), np.array([2000.0, 0.0]),
                                             0.0, home)
    # Meridian and prime-vertical radii of curvature of WGS84 at the home latitude.
    a, e2 = 6378137.0, 6.69437999014e-3
    s = math.sin(math.radians(home.latitude_deg))
    meridian = a * (1 - e2) / (1 - e2 * s * s) ** 1.5 + home.altitude_m
    normal = a / math.sqrt(1 - e2 * s * s) + home.altitude_m
    north_deg = math.degrees(2000.0 / meridian)
    east_deg = math.degrees(2000.0 / (normal * math.cos(math.radians(home.latitude_deg))))
    # A 6371 km sphere would be 1.2 m off northward over these 2 km; WGS84 is within 1 cm.
    assert (latitude[0] - home.latitude_deg) * math.radians(1) * meridian \
        == pytest.approx(north_deg * math.radians(1) * meridian, abs=0.01)
    assert (longitude[1] - home.longitude_deg) / east_deg == pytest.approx(1.0, abs=5e-6)
    east, north, _ = geodetic_to_enu(latitude, longitude, home.altitude_m, home)
    assert np.allclose(east, [0.0, 2000.0], atol=1e-3)
    assert np.allclose(north, [2000.0, 0.0], atol=1e-3)


def test_items_need_no_file(case_one, home):
    items = build_mission_items(case_one, home, end='rtl', firmware='px4', limits=LIMITS['px4'])
    assert items[0].current and items[0].frame == 0
    assert [items[1].command, items[-1].command] == [TAKEOFF, RTL]
    assert all(math.isnan(item.params[3]) for item in items if item.command == WAYPOINT
               and item.frame == 3)


# The command line, as a new user runs it.

def test_command_line_writes_a_mission_that_pymavlink_loads(tmp_path, capsys):
    from uav_comm_planner.tools import cli
    target = tmp_path / 'm.waypoints'
    status = cli.main(['plan', '--case', 'I', '--speed', '10', '--horizon', '400', '--slots',
                       '100', '--mission', str(target), '--home', '47.397742,8.545594,488'])
    out = capsys.readouterr().out
    assert status == 0 and f'wrote {target}' in out and 'as the vehicle flies it' in out
    items = load(target)
    assert [items[0].command, items[1].command, items[-1].command] == [WAYPOINT, TAKEOFF, LAND]
    expected = build_mission_items(plan_for_vehicle(multirotor_case_one()), Home(*DEFAULT_HOME))
    assert [item.command for item in items] == [item.command for item in expected]


@pytest.mark.parametrize('firmware, speed, horizon, home', [
    ('ardupilot', '10', '400', [-35.363262, 149.165237, 584.0]),    # ArduPilot SITL's CMAC
    ('px4', '5', '500', [47.397742, 8.545594, 489.0]),              # PX4 SITL's Zurich
])
def test_the_default_home_is_the_firmware_s_simulator_home(tmp_path, capsys, firmware, speed,
                                                           horizon, home):
    from uav_comm_planner.tools import cli
    command = ['plan', '--case', 'I', '--speed', speed, '--horizon', horizon, '--slots', '100',
               '--firmware', firmware, '--mission']
    assert cli.main([*command, str(tmp_path / 'default.plan')]) == 0
    default = json.loads((tmp_path / 'default.plan').read_text())['mission']
    assert default['plannedHomePosition'] == home
    assert MissionRequest(paper_scenario('I'), firmware=firmware).home == Home(*home)
    # An explicit home always wins, the other firmware's simulator home included.
    other = '47.397742,8.545594,489' if firmware == 'ardupilot' else '-35.363262,149.165237,584'
    assert cli.main([*command, str(tmp_path / 'given.plan'), f'--home={other}']) == 0
    given = json.loads((tmp_path / 'given.plan').read_text())['mission']
    assert given['plannedHomePosition'] == [float(v) for v in other.split(',')]
    capsys.readouterr()


def test_command_line_refuses_what_the_vehicle_cannot_fly(tmp_path, capsys):
    from uav_comm_planner.tools import cli
    target = tmp_path / 'm.waypoints'
    assert cli.main(['plan', '--case', 'I', '--mission', str(target)]) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and '100 m/s is faster than the vehicle flies: 10 m/s' in err
    assert cli.main(['plan', '--case', 'I', '--speed', '10', '--horizon', '201', '--slots',
                     '201', '--mission', str(target)]) == 2
    assert 'even the straight line from q0 to qF' in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_command_line_plans_with_a_parameter_file(tmp_path, capsys):
    from uav_comm_planner.tools import cli
    parameters = tmp_path / 'copter.param'
    parameters.write_text('WPNAV_SPEED,1500\nWPNAV_ACCEL,400\n')
    assert cli.main(['plan', '--case', 'I', '--speed', '15', '--horizon', '300', '--slots',
                     '100', '--vehicle-params', str(parameters), '--wp-jerk', '2']) == 0
    out = capsys.readouterr().out
    assert 'cruise 15 m/s' in out and 'acceleration 4 m/s/s, jerk 2 m/s/s/s' in out


def test_command_line_writes_a_px4_plan_that_returns_to_launch(tmp_path, capsys):
    from uav_comm_planner.tools import cli
    target = tmp_path / 'm.plan'
    # A southern latitude starts with '-', so argparse needs it attached with '='.
    status = cli.main(['plan', '--case', 'II', '--speed', '10', '--horizon', '400',
                       '--slots', '100', '--mission', str(target),
                       '--home=-35.363261,149.165230,584', '--mission-end', 'rtl',
                       '--firmware', 'px4', '--wp-speed', '10'])
    assert status == 0
    document = json.loads(target.read_text())
    assert document['mission']['firmwareType'] == 12
    assert document['mission']['plannedHomePosition'] == [-35.363261, 149.16523, 584.0]
    assert document['mission']['items'][-1]['command'] == RTL


@pytest.mark.parametrize('mission_file, message', [
    ('m.kml', 'unknown mission format'), ('nowhere/m.waypoints', 'does not exist')])
def test_command_line_refuses_a_bad_mission_file_before_planning(tmp_path, capsys, monkeypatch,
                                                                 mission_file, message):
    from uav_comm_planner.tools import cli
    monkeypatch.chdir(tmp_path)
    assert cli.main(['plan', '--case', 'I', '--mission', mission_file]) == 2
    out, err = capsys.readouterr()
    assert message in err and 'proposed' not in out
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize('home_text, message', [
    ('47.3,8.5', 'LAT,LON,ALT'), ('47.3,200,400', 'longitude must be in')])
def test_command_line_refuses_a_bad_home(tmp_path, capsys, home_text, message):
    from uav_comm_planner.tools import cli
    assert cli.main(['plan', '--mission', str(tmp_path / 'm.waypoints'), '--home',
                     home_text]) == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_px4_exports_a_plan_whose_slots_are_shorter_than_the_merge_radius(tmp_path, capsys):
    """V delta = 2 m: points within the 2 m merge radius once made PX4 legs faster than V."""
    from uav_comm_planner.tools import cli
    target = tmp_path / 'm.plan'
    assert cli.main(['plan', '--nodes', '40,60;120,-30;200,50', '--speed', '10', '--slots',
                     '400', '--horizon', '80', '--goal', '250,0', '--mission', str(target),
                     '--firmware', 'px4', '--wp-speed', '10']) == 0
    items = json.loads(target.read_text())['mission']['items']
    speeds = [item['params'][1] for item in items if item['command'] == CHANGE_SPEED]
    assert speeds and max(speeds) <= 10.0
    assert 'as the vehicle flies it' in capsys.readouterr().out


def test_a_px4_plan_without_limits_takes_px4s_default_limits(tmp_path, capsys):
    """MPC_XY_CRUISE 5, MPC_ACC_HOR 3, MPC_JERK_AUTO 4 (PX4 v1.16), not ArduCopter's defaults;
    a file or a flag still beats them."""
    from uav_comm_planner.mission.request import vehicle_limits
    from uav_comm_planner.tools import cli
    px4 = vehicle_limits(firmware='px4')
    assert (px4.max_speed_mps, px4.max_accel_mpss, px4.max_jerk_mpsss) == (5.0, 3.0, 4.0)
    assert vehicle_limits({'max_jerk_mpsss': 2.0}, firmware='px4').max_jerk_mpsss == 2.0
    ardupilot = vehicle_limits(firmware='ardupilot')
    assert (ardupilot.max_speed_mps, ardupilot.max_accel_mpss) == (10.0, 2.5)
    assert cli.main(['plan', '--case', 'I', '--speed', '5', '--horizon', '500', '--slots', '100',
                     '--firmware', 'px4', '--mission', str(tmp_path / 'm.plan')]) == 0
    out = capsys.readouterr().out
    assert 'cruise 5 m/s (the waypoint speed' in out
    assert 'acceleration 3 m/s/s, jerk 4 m/s/s/s' in out
