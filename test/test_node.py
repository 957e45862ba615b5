"""The planner node on real rclpy, driven through real topics and services in this process.

Each test starts the node on its own context and executor with a probe node beside it, and
spins until the expected messages arrive (with a generous deadline, never a timed assertion).
The last test runs the installed ``planner`` executable and hears its plan across processes.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path as FilePath
import signal
import subprocess
import sys
import threading
import time

from helpers import (DEADLINE_S, HORIZON_S, MAX_STEP_M, NEAR_M, NODES_A, NODES_B,
                     PROCESS_DEADLINE_S, SLOT_S, SLOTS, small_scenario)
from nav_msgs.msg import Path
import numpy as np
import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_srvs.srv import Trigger

from uav_comm_planner import (InfeasibleHorizonError, paper_scenario, plan, SolverError,
                              SolverSettings)
from uav_comm_planner.mission.plausible import CONFIRMING_SAMPLES
from uav_comm_planner.ros.messages import nanoseconds_of
from uav_comm_planner.ros.node import PlannerNode
from uav_comm_planner.ros.publishing import (OUTPUT_QOS, TOPIC_MARKERS, TOPIC_MIN_THROUGHPUT,
                                             TOPIC_PATH, TOPIC_POWER)
from uav_comm_planner.ros.send_ground_nodes import describe, GroundNodesSender
from uav_comm_planner.mission.policy import plan_for_vehicle


def flight_points(path: Path) -> np.ndarray:
    return np.array([[p.pose.position.x, p.pose.position.y] for p in path.poses])


def test_pose_array_gives_path_power_and_throughput_of_the_core(harness):
    h = harness()
    h.published(1)
    h.send_nodes(NODES_A)
    h.published(2)
    scenario = small_scenario()
    core = plan(scenario, SolverSettings())

    path = h.latest(TOPIC_PATH)
    assert path.header.frame_id == 'map'
    assert len(path.poses) == SLOTS + 2
    stamps = np.array([nanoseconds_of(p.header.stamp) for p in path.poses])
    assert np.all(np.abs(np.diff(stamps) - SLOT_S * 1e9) <= 1)
    points = flight_points(path)
    np.testing.assert_allclose(points[0], scenario.start_m)
    np.testing.assert_allclose(points[-1], scenario.goal_m)
    assert np.all(np.linalg.norm(np.diff(points, axis=0), axis=1) <= MAX_STEP_M * (1 + 1e-6))
    assert all(p.pose.position.z == scenario.altitude_m for p in path.poses)
    for node in NODES_A:
        assert np.linalg.norm(points - node, axis=1).min() < NEAR_M, node

    power = h.latest(TOPIC_POWER)
    assert [d.label for d in power.layout.dim] == ['slot', 'node']
    assert [d.size for d in power.layout.dim] == [SLOTS, 3]
    assert [d.stride for d in power.layout.dim] == [SLOTS * 3, 3]
    schedule = np.array(power.data).reshape(SLOTS, 3).T
    np.testing.assert_allclose(schedule, core.power, rtol=1e-6, atol=1e-9)
    assert h.latest(TOPIC_MIN_THROUGHPUT).data == pytest.approx(core.min_throughput, rel=1e-9)
    nodes_marker = h.latest(TOPIC_MARKERS).markers[0]
    assert [(p.x, p.y) for p in nodes_marker.points] == NODES_A


def test_heading_follows_the_flight(harness):
    h = harness()
    h.published(1)
    points = flight_points(h.latest(TOPIC_PATH))
    yaws = [2 * math.atan2(p.pose.orientation.z, p.pose.orientation.w)
            for p in h.latest(TOPIC_PATH).poses]
    moving = np.linalg.norm(np.diff(points, axis=0), axis=1) > 0.01 * MAX_STEP_M
    assert moving.any()
    for i in np.flatnonzero(moving):
        step = points[i + 1] - points[i]
        difference = math.remainder(yaws[i] - math.atan2(step[1], step[0]), math.tau)
        assert abs(difference) < 1e-9


def test_second_pose_array_and_replan_service_make_new_plans(harness):
    h = harness()
    h.published(1)
    h.send_nodes(NODES_A)
    h.published(2)
    h.send_nodes(NODES_B)
    h.published(3)
    points = flight_points(h.latest(TOPIC_PATH))
    for node in NODES_B:
        assert np.linalg.norm(points - node, axis=1).min() < NEAR_M, node
    assert h.latest(TOPIC_MIN_THROUGHPUT).data == pytest.approx(
        plan(small_scenario(NODES_B)).min_throughput, rel=1e-9)
    first_stamp = nanoseconds_of(h.latest(TOPIC_PATH).header.stamp)

    answer = h.call('replan', Trigger.Request())
    assert answer.success, answer.message
    h.published(4)
    assert nanoseconds_of(h.latest(TOPIC_PATH).header.stamp) > first_stamp
    assert list(h.node.get_parameter('ground_nodes').value) == [
        v for point in NODES_B for v in point]


def test_bad_parameter_is_refused_with_its_reason_and_the_plan_stays(harness):
    h = harness()
    h.published(1)
    before = h.node.current_plan
    requests = h.node.stats.requests_made
    too_short = Parameter('horizon_s', value=5.0).to_parameter_msg()
    answer = h.call('set_parameters', SetParameters.Request(parameters=[too_short]))
    assert not answer.results[0].successful
    assert 'goal unreachable' in answer.results[0].reason
    assert h.node.get_parameter('horizon_s').value == HORIZON_S
    assert h.node.stats.requests_made == requests
    assert h.node.current_plan is before
    assert nanoseconds_of(h.latest(TOPIC_PATH).header.stamp) == before.request.start_ns

    budget = Parameter('power_budget_w', value=10.0).to_parameter_msg()
    answer = h.call('set_parameters', SetParameters.Request(parameters=[budget]))
    assert answer.results[0].successful, answer.results[0].reason
    h.published(2)
    assert h.latest(TOPIC_MIN_THROUGHPUT).data == pytest.approx(plan(small_scenario(
        paper_scenario().ground_nodes_m, power_budget_w=10.0)).min_throughput, rel=1e-9)


@pytest.mark.parametrize('points, frame_id, reason', [
    ([(300.0, math.nan), (900.0, -150.0)], 'map', 'finite'),
    ([(300.0, math.inf), (900.0, -150.0)], 'map', 'finite'),
    ([], 'map', 'no ground nodes'),
    ([(100.0 * i, 50.0) for i in range(1, 5)], 'map', 'too many ground nodes'),
    ([(300.0, 200.0), (300.0, 200.0)], 'map', 'duplicate'),
    (NODES_A, 'odom', "frame is 'odom'"),
])
def test_bad_ground_nodes_are_logged_and_publish_no_plan(harness, points, frame_id, reason):
    h = harness(max_nodes=3)
    h.published(1)
    before = h.node.current_plan
    requests, errors = h.node.stats.requests_made, h.node.stats.error_count
    h.send_nodes(points, frame_id)
    h.errors_after(errors)
    assert reason in h.node.stats.last_error
    h.spin_until(lambda: any(reason in line for line in h.error_logs), 'error on /rosout')
    assert h.node.stats.requests_made == requests
    assert h.node.current_plan is before
    assert h.node.stats.plans_run == 1

    h.send_nodes(NODES_B)
    h.published(2)
    assert h.node.stats.plans_run == 2


class GatedPlanner:
    """The core's plan(), held at a gate while the test lines up requests behind it."""

    def __init__(self) -> None:
        self.gate = threading.Event()
        self.gate.set()
        self.planned: list[tuple] = []

    def __call__(self, scenario, settings, **options):
        self.planned.append(scenario.ground_nodes_m)
        self.gate.wait(DEADLINE_S)
        return plan(scenario, settings, **options)


def test_burst_of_updates_coalesces_and_ends_with_the_last(harness):
    gated = GatedPlanner()
    h = harness(planner=gated)
    h.published(1)
    runs, requests = h.node.stats.plans_run, h.node.stats.requests_made
    gated.gate.clear()
    updates = [[(300.0 + i, 200.0), (900.0, -150.0 + i), (1500.0, 250.0)] for i in range(50)]
    for i, points in enumerate(updates):
        h.send_nodes(points)
        flat = [v for point in points for v in point]
        h.spin_until(lambda: list(h.node.get_parameter('ground_nodes').value) == flat,
                     'update taken')
        if i == len(updates) // 2:
            assert h.call('replan', Trigger.Request()).success
    assert h.node.stats.requests_made - requests == len(updates) + 1
    gated.gate.set()
    h.spin_until(lambda: h.node.current_plan.request.scenario.ground_nodes_m == tuple(
        updates[-1]), 'plan for the last update')
    h.published(h.node.stats.plans_published)
    assert 1 <= h.node.stats.plans_run - runs <= 2
    assert gated.planned[-1] == tuple(updates[-1])
    markers = h.latest(TOPIC_MARKERS).markers[0]
    assert [(p.x, p.y) for p in markers.points] == updates[-1]


def test_uav_pose_replans_the_rest_and_refuses_an_unreachable_goal(harness):
    h = harness()
    h.published(1)
    h.send_pose(500.0, -300.0)       # no mission clock yet: a pose alone plans nothing
    assert h.call('start', Trigger.Request()).success
    assert h.node.progress.started
    h.send_pose(500.0, -300.0)
    h.published(2)
    path = h.latest(TOPIC_PATH)
    points = flight_points(path)
    np.testing.assert_allclose(points[0], (500.0, -300.0))
    np.testing.assert_allclose(points[-1], paper_scenario().goal_m)
    assert 3 <= len(path.poses) <= SLOTS + 2
    assert h.node.current_plan.result.scenario.slot_s == pytest.approx(SLOT_S)
    assert np.all(np.linalg.norm(np.diff(points, axis=0), axis=1) <= MAX_STEP_M * (1 + 1e-6))
    receding = h.node.current_plan.receding
    assert receding is not None
    assert receding.mission_energy_w <= paper_scenario().power_budget_w * (1 + 1e-9)

    errors = h.node.stats.error_count
    h.node.flight._last_pose_replan_s = -math.inf        # past the replan interval
    # 100 km away at once is no flight: refused, until samples in a row confirm the jump.
    for sent in range(1, CONFIRMING_SAMPLES):
        h.send_pose(100000.0, 0.0)
        h.spin_until(lambda: h.node.flight.positions_refused == sent, f'refusal {sent}')
    assert 'farther than the UAV flies' in h.node.stats.last_error
    errors = h.node.stats.error_count
    h.send_pose(100000.0, 0.0)
    h.errors_after(errors)
    assert 'goal unreachable' in h.node.stats.last_error
    assert h.node.stats.plans_published == 2


def test_solver_failure_is_logged_and_the_last_plan_stays(harness):
    calls = []

    def failing_after_first(scenario, settings, **options):
        calls.append(scenario)
        if len(calls) > 1:
            raise SolverError('trajectory step: solver reported NUMERICAL_ERROR')
        return plan(scenario, settings, **options)

    h = harness(planner=failing_after_first)
    h.published(1)
    before = h.node.current_plan
    errors = h.node.stats.error_count
    assert h.call('replan', Trigger.Request()).success
    h.errors_after(errors)
    assert 'NUMERICAL_ERROR' in h.node.stats.last_error
    assert h.node.current_plan is before
    assert h.node.stats.plans_run == 2 and h.node.stats.plans_published == 1


MULTIROTOR = {'max_speed_mps': 10.0, 'horizon_s': 400.0, 'num_slots': 100,
              'vehicle_aware': True}


def test_vehicle_aware_node_publishes_the_plan_as_flown(harness):
    h = harness(**MULTIROTOR)
    h.published(1)
    path = h.latest(TOPIC_PATH)
    expected = plan_for_vehicle(paper_scenario('I', max_speed_mps=10.0, horizon_s=400.0,
                                               num_slots=100)).flown
    poses = np.array([(pose.pose.position.x, pose.pose.position.y) for pose in path.poses])
    assert np.allclose(poses[1:-1], expected.trajectory, atol=1e-6)
    stated = h.received[TOPIC_MIN_THROUGHPUT][-1].data
    assert stated == pytest.approx(expected.min_throughput, rel=1e-9)
    # A planning speed above the vehicle's is refused as a parameter, with the numbers.
    answer = h.call('set_parameters', SetParameters.Request(
        parameters=[Parameter('max_speed_mps', value=12.0).to_parameter_msg()]))
    assert not answer.results[0].successful
    assert 'faster than the vehicle flies: 10 m/s' in answer.results[0].reason


def test_mission_written_on_every_plan_and_on_demand(harness, tmp_path):
    mission = tmp_path / 'flight.waypoints'
    h = harness(mission_dir=str(tmp_path), mission_file=mission.name, **MULTIROTOR)
    h.published(1)
    assert mission.read_text().startswith('QGC WPL 110')
    mission.unlink()
    answer = h.call('export_mission', Trigger.Request())
    assert answer.success, answer.message
    assert mission.read_text().startswith('QGC WPL 110')

    (tmp_path / 'taken.waypoints').mkdir()
    nowhere = Parameter('mission_file', value='taken.waypoints')
    errors, requests = h.node.stats.error_count, h.node.stats.requests_made
    answer = h.call('set_parameters', SetParameters.Request(
        parameters=[nowhere.to_parameter_msg()]))
    assert answer.results[0].successful
    assert h.node.stats.requests_made == requests      # an output parameter never replans
    assert h.call('replan', Trigger.Request()).success
    h.published(2)
    h.errors_after(errors)
    assert 'mission export failed' in h.node.stats.last_error
    assert not h.call('export_mission', Trigger.Request()).success


def test_setting_mission_file_writes_the_plan_in_force_at_once(harness, tmp_path):
    """Not at the next plan: the file is there when the change is accepted, and another end
    writes it again; neither replans."""
    h = harness(mission_dir=str(tmp_path), **MULTIROTOR)
    h.published(1)
    assert list(tmp_path.iterdir()) == []
    requests = h.node.stats.requests_made
    for name, value in (('mission_file', 'now.plan'), ('mission_end', 'rtl')):
        answer = h.call('set_parameters', SetParameters.Request(
            parameters=[Parameter(name, value=value).to_parameter_msg()]))
        assert answer.results[0].successful, answer.results[0].reason
        items = json.loads((tmp_path / 'now.plan').read_text())['mission']['items']
        assert items[-1]['command'] == (20 if value == 'rtl' else 21)   # RTL, else LAND
    assert h.node.stats.requests_made == requests


def test_mission_file_with_unknown_extension_is_refused(harness, tmp_path):
    h = harness()
    h.published(1)
    answer = h.call('set_parameters', SetParameters.Request(parameters=[
        Parameter('mission_file', value='f.txt').to_parameter_msg()]))
    assert not answer.results[0].successful
    assert '.waypoints' in answer.results[0].reason


def test_sender_helper_gets_the_plan_through_its_nodes(harness):
    h = harness()
    h.published(1)
    sender = GroundNodesSender(h.probe)
    h.spin_until(sender.listening, 'planner listening to the sender')
    sender.send(NODES_B, 'map')
    h.spin_until(lambda: sender.answered(NODES_B), 'plan for the sent nodes')
    assert not sender.answered(NODES_A)
    assert describe(sender.path).startswith(
        f'new plan: {SLOTS + 2} poses from (0, 0) to (2000, 0) over {HORIZON_S + SLOT_S:g} s')


def test_invalid_initial_parameters_raise_the_typed_error(ros_context):
    with pytest.raises(InfeasibleHorizonError, match='goal unreachable'):
        PlannerNode(context=ros_context, parameter_overrides=[
            Parameter('horizon_s', value=5.0)])


def test_installed_planner_publishes_to_another_process(ros_context):
    prefix = FilePath(sys.prefix)
    executable = prefix / 'lib' / 'uav_comm_planner' / 'planner'
    assert (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages'
            / 'uav_comm_planner').is_file()
    assert os.access(executable, os.X_OK)
    slots = 21
    probe = Node('planner_process_probe', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(probe)
    paths: list[Path] = []
    probe.create_subscription(Path, TOPIC_PATH, paths.append, OUTPUT_QOS)
    process = subprocess.Popen(
        [str(executable), '--ros-args', '-p', f'num_slots:={slots}'],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + PROCESS_DEADLINE_S
        while (not any(len(path.poses) == slots + 2 for path in paths)
               and process.poll() is None and time.monotonic() < deadline):
            executor.spin_once(timeout_sec=0.1)
        assert process.poll() is None, process.communicate()[1]
        assert any(len(path.poses) == slots + 2 for path in paths), (
            f'no plan of {slots} slots from the planner process within {PROCESS_DEADLINE_S} s')
        process.send_signal(signal.SIGINT)
        _, stderr = process.communicate(timeout=PROCESS_DEADLINE_S)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        executor.shutdown()
        probe.destroy_node()
    assert process.returncode == 0, stderr
    assert 'Traceback' not in stderr
    assert 'plan: min throughput' in stderr
