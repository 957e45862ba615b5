"""The node's parts that need no ROS context: parameters, messages, worker, remaining horizon."""

from __future__ import annotations

from dataclasses import fields
import math
from pathlib import Path
import re
import threading

import numpy as np
import pytest
import yaml

from uav_comm_planner import (InfeasibleHorizonError, InvalidScenarioError, paper_scenario, plan,
                              Scenario, SolverSettings)
from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.ros.fleet_params import FleetNodeSettings
from uav_comm_planner.ros.handoff import LatestOnlyWorker
from uav_comm_planner.ros.messages import (ground_nodes_of, headings, marker_array, nanoseconds_of,
                                           path_message, pose_array, power_message)
from uav_comm_planner.ros.params import (config_from_parameters, NodeSettings, NOT_PARAMETERS,
                                         PARAMETER_NAMES, parameter_specs)
from uav_comm_planner.ros.publishing import summary_line
from uav_comm_planner.vehicle.airframe import airframe_named
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.limits import VehicleLimits

CONFIG = Path(__file__).resolve().parent.parent / 'config' / 'planner.yaml'
WAIT_S = 30.0


def test_every_settings_field_is_a_parameter():
    exposed = {(spec.owner, spec.field) for spec in parameter_specs()}
    wanted = {(owner, f.name) for owner in (Scenario, SolverSettings, NodeSettings,
                                            VehicleLimits, FleetNodeSettings)
              for f in fields(owner)}
    assert exposed == wanted - set(NOT_PARAMETERS)
    assert set(NOT_PARAMETERS) <= wanted
    names = [spec.name for spec in parameter_specs()]
    assert len(names) == len(set(names))
    assert 'ground_nodes' in names and PARAMETER_NAMES['ground_nodes_m'] == 'ground_nodes'


def test_defaults_are_the_letters_case_one_flown_by_a_multirotor():
    config = config_from_parameters({})
    # ArduPilot's default airframe (the measured SITL quad) states the energy.
    assert config.scenario == paper_scenario('I', max_speed_mps=10.0, horizon_s=400.0,
                                             num_slots=100,
                                             airframe=airframe_named('arducopter-sitl-quad'))
    assert config.vehicle == VehicleLimits() and config.node.vehicle_aware
    assert config.settings == SolverSettings()
    assert config.node == NodeSettings()
    assert config.node.frame_id == 'map' and config.node.mission_file == ''


def test_descriptors_carry_units_and_ranges():
    specs = {spec.name: spec for spec in parameter_specs()}
    for spec in specs.values():
        assert spec.descriptor().description, spec.name
    altitude = specs['altitude_m'].descriptor()
    assert '(m)' in altitude.description
    # H = 0 is refused, so no range that includes it (a descriptor's range is inclusive).
    assert not altitude.floating_point_range
    assert altitude.additional_constraints == 'greater than 0, at most 100000'
    budget = specs['power_budget_w'].descriptor()
    assert not budget.floating_point_range and 'greater than 0' in budget.additional_constraints
    assert specs['fence_margin_m'].descriptor().floating_point_range[0].from_value == 0.0
    assert specs['num_slots'].descriptor().integer_range[0].from_value == 1
    assert 'land' in specs['mission_end'].descriptor().additional_constraints


#: Left to the firmware when not given, so commented out in the shipped file: a parameters file
#: makes every value it holds explicit (given at start-up), which would fix them for PX4 too.
FIRMWARE_DEFAULTED = {'home_latitude_deg', 'home_longitude_deg', 'home_altitude_m',
                      'vehicle_max_speed_mps', 'vehicle_max_accel_mpss', 'vehicle_max_jerk_mpsss'}


def test_shipped_config_lists_every_parameter_with_its_default():
    text = CONFIG.read_text()
    shipped = yaml.safe_load(text)['uav_comm_planner']['ros__parameters']
    defaults = {spec.name: spec.default for spec in parameter_specs()}
    assert shipped == {name: value for name, value in defaults.items()
                       if name not in FIRMWARE_DEFAULTED}
    for spec in parameter_specs():
        if spec.name in FIRMWARE_DEFAULTED:
            commented = re.search(rf'^    # {spec.name}: (.*)$', text, re.M)
            assert commented and yaml.safe_load(commented.group(1)) == spec.default, spec.name
        else:
            assert type(shipped[spec.name]) is type(spec.default), spec.name


def test_the_shipped_config_leaves_px4_its_own_home_and_limits():
    shipped = yaml.safe_load(CONFIG.read_text())['uav_comm_planner']['ros__parameters']
    px4 = {**shipped, 'mission_firmware': 'px4', 'max_speed_mps': 5.0, 'horizon_s': 500.0}
    config = config_from_parameters(px4, explicit=set(px4))
    assert config.node.home == Home(47.397742, 8.545594, 489.0)
    assert config.vehicle.max_speed_mps == 5.0 and config.vehicle.max_accel_mpss == 3.0


def test_the_default_home_is_the_mission_firmware_s_simulator_home():
    cmac, zurich = Home(-35.363262, 149.165237, 584.0), Home(47.397742, 8.545594, 489.0)
    assert config_from_parameters({}).node.home == cmac
    px4 = {'mission_firmware': 'px4', 'max_speed_mps': 5.0, 'horizon_s': 500.0}
    assert config_from_parameters(px4, explicit=set(px4)).node.home == zurich
    # Explicit home parameters always win, ArduPilot's simulator home for PX4 included.
    given = {**px4, 'home_latitude_deg': 50.0, 'home_longitude_deg': 8.0,
             'home_altitude_m': 100.0}
    assert config_from_parameters(given).node.home == Home(50.0, 8.0, 100.0)
    one = {**px4, 'home_altitude_m': 100.0}     # one home parameter set: the rest default
    assert config_from_parameters(one, explicit=set(one)).node.home == \
        Home(-35.363262, 149.165237, 100.0)


def test_parameters_become_the_dataclasses():
    config = config_from_parameters({
        'ground_nodes': [1.0, 2.0, 30.0, 40.0], 'start_m': [5.0, 6.0], 'num_slots': 20,
        'max_nodes': 4, 'mission_end': 'rtl', 'frame_id': 'odom'})
    assert config.scenario.ground_nodes_m == ((1.0, 2.0), (30.0, 40.0))
    assert config.scenario.start_m == (5.0, 6.0)
    assert config.scenario.num_slots == 20
    assert config.settings.max_nodes == 4
    assert config.node.mission_end == 'rtl' and config.node.frame_id == 'odom'


@pytest.mark.parametrize('values, error, reason', [
    ({'ground_nodes': [1.0, 2.0, 3.0]}, InvalidScenarioError, 'even number'),
    ({'ground_nodes': []}, InvalidScenarioError, 'no ground nodes'),
    ({'ground_nodes': [0.0, math.nan]}, InvalidScenarioError, 'finite'),
    ({'start_m': [0.0, 0.0, 1.0]}, InvalidScenarioError, 'two values'),
    ({'max_nodes': 2}, InvalidScenarioError, 'too many ground nodes'),
    ({'horizon_s': 5.0}, InfeasibleHorizonError, 'goal unreachable'),
    ({'altitude_m': 0.0}, InvalidScenarioError, 'altitude_m'),
    ({'mission_end': 'crash'}, InvalidScenarioError, 'mission_end'),
    ({'mission_firmware': 'inav'}, InvalidScenarioError, 'mission_firmware'),
    ({'mission_file': 'flight.txt'}, InvalidScenarioError, '.waypoints'),
    ({'home_latitude_deg': 91.0}, InvalidScenarioError, 'home_latitude_deg'),
    ({'frame_id': ' '}, InvalidScenarioError, 'frame_id'),
])
def test_bad_parameters_are_refused_with_the_reason(values, error, reason):
    with pytest.raises(error, match=reason):
        config_from_parameters(values)


def hover_then_turn() -> PlanResult:
    """q0 (0, 0) -> (100, 0), hover, -> (100, 100) -> qF (100, 200) with delta = 1 s."""
    scenario = Scenario(ground_nodes_m=((100.0, 0.0), (100.0, 100.0)), horizon_s=3.0,
                        num_slots=3, start_m=(0.0, 0.0), goal_m=(100.0, 200.0))
    q = np.array([[100.0, 0.0], [100.0, 0.0], [100.0, 100.0]])
    power = np.array([[1.0, 2.0, 0.0], [0.0, 0.5, 1.5]])
    return PlanResult(scenario=scenario, trajectory=q, times=scenario.times_s, power=power,
                      rates=np.ones(2), min_throughput=1.0, history=())


def test_path_stamps_positions_and_headings():
    result = hover_then_turn()
    message = path_message(result, 'map', start_ns=7_500_000_000)
    assert message.header.frame_id == 'map'
    stamps = [nanoseconds_of(pose.header.stamp) for pose in message.poses]
    assert stamps == [7_500_000_000 + k * 1_000_000_000 for k in range(5)]
    xyz = [(p.pose.position.x, p.pose.position.y, p.pose.position.z) for p in message.poses]
    assert xyz == [(0.0, 0.0, 100.0), (100.0, 0.0, 100.0), (100.0, 0.0, 100.0),
                   (100.0, 100.0, 100.0), (100.0, 200.0, 100.0)]
    np.testing.assert_allclose(headings(result), [0.0, 0.0, math.pi / 2, math.pi / 2,
                                                  math.pi / 2])
    yaw = [2 * math.atan2(p.pose.orientation.z, p.pose.orientation.w) for p in message.poses]
    np.testing.assert_allclose(yaw, headings(result))


def test_power_schedule_is_slot_major():
    result = hover_then_turn()
    message = power_message(result)
    assert [(d.label, d.size, d.stride) for d in message.layout.dim] == [
        ('slot', 3, 6), ('node', 2, 2)]
    for n in range(2):
        for m in range(3):
            assert message.data[m * 2 + n] == result.power[n, m]


def test_markers_show_nodes_path_and_hover_points():
    markers = marker_array(hover_then_turn(), 'map', 0).markers
    assert [m.ns for m in markers] == ['ground_nodes', 'path', 'hover_points']
    assert [(p.x, p.y, p.z) for p in markers[0].points] == [
        (100.0, 0.0, 0.0), (100.0, 100.0, 0.0)]
    assert len(markers[1].points) == 5
    assert [(p.x, p.y) for p in markers[2].points] == [(100.0, 0.0)]
    assert all(m.color.a == 1.0 and m.header.frame_id == 'map' for m in markers)


def test_pose_array_round_trip_ignores_height():
    message = pose_array([(1.0, 2.0), (3.0, -4.0)], 'map')
    message.poses[0].position.z = 55.0
    assert ground_nodes_of(message) == [(1.0, 2.0), (3.0, -4.0)]


def test_worker_runs_the_newest_waiting_request_only():
    started, release, finished = threading.Event(), threading.Event(), threading.Event()
    ran: list[int] = []

    def job(request: int) -> None:
        ran.append(request)
        started.set()
        release.wait(WAIT_S)
        if request == 9:
            finished.set()

    worker = LatestOnlyWorker(job, name='test-worker')
    try:
        worker.submit(0)
        assert started.wait(WAIT_S)
        replaced = [worker.submit(k) for k in range(1, 10)]
        assert replaced == [False] + [True] * 8
        release.set()
        assert finished.wait(WAIT_S)
    finally:
        worker.stop()
    assert ran == [0, 9]


def test_summary_line_has_objective_baselines_and_time():
    result = plan(paper_scenario('I', num_slots=10, horizon_s=30.0))
    line = summary_line(result)
    assert line.startswith('plan: min throughput ')
    assert f'{result.baselines["straight"]:.4g}' in line
    assert f'{result.baselines["static"]:.4g}' in line
    assert 'planned in' in line and '\n' not in line
    assert result.min_throughput > result.baselines['static'] and 'ignores' not in line


def test_summary_line_says_the_static_point_ignores_launch_and_landing_when_it_is_higher():
    # Two nodes 300 m off the line from q0 to qF, and hardly more time than the flight takes:
    # the static point hovers over them all the time, which no flight from q0 to qF can.
    result = plan(paper_scenario('I', ground_nodes_m=((1000.0, 300.0), (1050.0, 300.0)),
                                 max_speed_mps=10.0, horizon_s=210.0, num_slots=42))
    assert result.min_throughput < result.baselines['static']
    line = summary_line(result)
    assert f'static point {result.baselines["static"]:.4g}, which ignores launch and landing' \
        in line


@pytest.mark.parametrize('values, message', [
    ({'vehicle_aware': 'no'}, 'vehicle_aware must be true or false'),
    ({'vehicle_params_file': 5}, 'vehicle_params_file must be a string'),
    ({'replan_delay_s': True}, 'replan_delay_s must be a positive finite number'),
])
def test_node_settings_of_the_wrong_type_are_refused(values, message):
    with pytest.raises(InvalidScenarioError, match=message):
        NodeSettings(**values)
