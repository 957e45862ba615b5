"""The node under hostile input: oversized messages, parameters that point elsewhere, a
newer request during a long plan, service bursts and repeated Ctrl-C."""

from __future__ import annotations

import os
from pathlib import Path as FilePath
import signal
import subprocess
import sys
import threading
import time

from helpers import DEADLINE_S, Harness, NODES_B, PROCESS_DEADLINE_S
import pytest
from rcl_interfaces.srv import SetParameters, SetParametersAtomically
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_srvs.srv import Trigger

from uav_comm_planner import plan
from uav_comm_planner.ros.node import NODE_NAME

pytestmark = pytest.mark.filterwarnings('ignore::DeprecationWarning')


def release_reader(fifo: FilePath) -> None:
    """Open ``fifo`` for writing and close it: a reader blocked opening it goes on (EOF)."""
    try:
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
    except OSError:
        pass        # no reader: nothing to release


def set_parameter(h: Harness, name: str, value):
    answer = h.call('set_parameters', SetParameters.Request(
        parameters=[Parameter(name, value=value).to_parameter_msg()]))
    return answer.results[0]


def test_an_oversized_node_set_is_refused_before_conversion_and_the_node_keeps_spinning(
        harness):
    h = harness()
    h.published(1)
    before = h.node.current_plan
    errors = h.node.stats.error_count
    points = [(float(i), float(i % 7)) for i in range(12_000)]
    began = time.perf_counter()
    h.send_nodes(points)
    h.errors_after(errors)
    print(f'12 000 poses refused {time.perf_counter() - began:.3f} s after sending')
    assert ('too many ground nodes: 12000 given, the limit max_nodes is 100'
            in h.node.stats.last_error)
    assert h.node.current_plan is before
    # The executor still serves: a normal update is planned.
    h.send_nodes(NODES_B)
    h.spin_until(lambda: h.node.current_plan.request.scenario.ground_nodes_m == tuple(NODES_B),
                 'plan for a normal node set after the oversized one')


@pytest.mark.parametrize('name', ['../escape.waypoints', '/tmp/abs.waypoints', '.hidden.plan',
                                  'sub/f.waypoints', 'f.WAYPOINTS.txt', '..'])
def test_mission_file_must_be_a_bare_visible_name(harness, tmp_path, name):
    h = harness(mission_dir=str(tmp_path))
    h.published(1)
    result = set_parameter(h, 'mission_file', name)
    assert not result.successful
    assert 'mission_file must' in result.reason
    assert list(tmp_path.iterdir()) == []


def test_mission_dir_and_the_limits_are_read_only(harness, tmp_path):
    h = harness(mission_dir=str(tmp_path))
    h.published(1)
    for name, value in (('mission_dir', '/'), ('max_node_slots', 10 ** 8), ('max_nodes', 5000)):
        result = set_parameter(h, name, value)
        assert not result.successful, name
        assert 'read-only' in result.reason or 'read only' in result.reason
    assert h.node.get_parameter('mission_dir').value == str(tmp_path)


def test_mission_file_goes_into_mission_dir_and_refuses_a_link_in_its_place(harness, tmp_path):
    outside = tmp_path / 'outside.waypoints'
    outside.write_text('foreign')
    folder = tmp_path / 'missions'
    folder.mkdir()
    (folder / 'linked.waypoints').symlink_to(outside)
    h = harness(mission_dir=str(folder), mission_file='flight.waypoints', max_speed_mps=10.0,
                horizon_s=400.0, num_slots=100, vehicle_aware=True)
    h.published(1)
    assert (folder / 'flight.waypoints').read_text().startswith('QGC WPL 110')
    errors = h.node.stats.error_count
    assert set_parameter(h, 'mission_file', 'linked.waypoints').successful
    # The mission file is an output: it is written with the next plan.
    assert h.call('export_mission', Trigger.Request()).success is False
    h.errors_after(errors)
    assert 'symbolic link' in h.node.stats.last_error
    assert outside.read_text() == 'foreign'


def test_a_newer_request_preempts_the_running_plan(harness):
    running = threading.Event()

    def slow_first(scenario, settings, *, should_stop):
        def hold_until_superseded() -> bool:
            running.set()
            deadline = time.monotonic() + DEADLINE_S
            while not should_stop() and time.monotonic() < deadline:
                time.sleep(0.01)
            return should_stop()
        first = not running.is_set()
        return plan(scenario, settings, should_stop=hold_until_superseded if first
                    else should_stop)

    h = harness(planner=slow_first)
    h.spin_until(running.is_set, 'first plan running')
    h.send_nodes(NODES_B)
    h.spin_until(lambda: h.node.stats.plans_published >= 1, 'plan for the newer request')
    assert h.node.stats.plans_cancelled == 1
    assert h.node.current_plan.request.scenario.ground_nodes_m == tuple(NODES_B)
    assert h.node.stats.error_count == 0


def test_a_burst_of_service_requests_is_answered_in_full(harness):
    h = harness()
    h.published(1)
    client = h.probe.create_client(Trigger, f'/{NODE_NAME}/replan')
    h.spin_until(client.service_is_ready, 'replan service')
    futures = [client.call_async(Trigger.Request()) for _ in range(60)]
    h.spin_until(lambda: all(f.done() for f in futures), 'answers to all 60 requests')
    assert all(f.result().success for f in futures)
    h.spin_until(lambda: h.node.stats.plans_run >= 2, 'a plan after the burst')


def start_planner(*ros_args: str) -> subprocess.Popen:
    executable = FilePath(sys.prefix) / 'lib' / 'uav_comm_planner' / 'planner'
    environment = dict(os.environ, PYTHONUNBUFFERED='1')
    return subprocess.Popen([str(executable), '--ros-args', *ros_args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=environment)


def interrupt_twice(process: subprocess.Popen, gap_s: float) -> tuple[int, str]:
    try:
        process.send_signal(signal.SIGINT)
        time.sleep(gap_s)
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
        _, stderr = process.communicate(timeout=PROCESS_DEADLINE_S)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    return process.returncode, stderr


@pytest.mark.parametrize('delay_s', [0.0, 0.3, 1.0])
def test_double_ctrl_c_while_the_planner_starts_exits_quietly(delay_s):
    process = start_planner()
    time.sleep(delay_s)
    status, stderr = interrupt_twice(process, 0.05)
    assert 'Traceback' not in stderr and 'rethrown' not in stderr
    # Before the interpreter has started, SIGINT's default action ends the process silently.
    assert status == 0 or (status == -signal.SIGINT and not stderr), (status, stderr)


@pytest.mark.slow
def test_double_ctrl_c_during_a_long_plan_exits_quietly(ros_context):
    # 3 nodes x 6000 slots: a plan of tens of seconds, within the default compute budget.
    process = start_planner('-p', 'num_slots:=6000', '-p', 'horizon_s:=12000.0')
    probe = Node('ctrl_c_probe', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(probe)
    client = probe.create_client(Trigger, f'/{NODE_NAME}/replan')
    try:
        deadline = time.monotonic() + PROCESS_DEADLINE_S
        while not client.service_is_ready() and time.monotonic() < deadline:
            assert process.poll() is None, process.communicate()[1]
            executor.spin_once(timeout_sec=0.1)
        assert client.service_is_ready(), 'planner did not come up'
        time.sleep(1.0)  # into the plan
        began = time.monotonic()
        status, stderr = interrupt_twice(process, 0.2)
        print(f'planner ended {time.monotonic() - began:.2f} s after the first Ctrl-C')
    finally:
        executor.shutdown()
        probe.destroy_node()
    assert status == 0, stderr
    assert 'Traceback' not in stderr and 'rethrown' not in stderr


def test_a_parameter_file_that_is_a_device_a_pipe_or_a_folder_is_refused_at_once(
        harness, tmp_path):
    fifo = tmp_path / 'fifo.param'
    os.mkfifo(fifo)
    h = harness()
    h.published(1)
    before = h.node.current_plan
    # Should the node open the FIFO blocking, a writer comes later and lets it go.
    release = threading.Timer(10.0, release_reader, args=(fifo,))
    release.daemon = True
    release.start()
    try:
        # The FIFO first: a reader that blocks on it would also read /dev/zero to the end.
        for path, reason in ((str(fifo), 'it is a pipe'), (str(tmp_path), 'it is a folder'),
                             ('/dev/zero', 'it is a device')):
            began = time.monotonic()
            result = set_parameter(h, 'vehicle_params_file', path)
            assert time.monotonic() - began < 5.0, path
            assert not result.successful and reason in result.reason, (path, result.reason)
    finally:
        release.cancel()
    assert h.node.get_parameter('vehicle_params_file').value == ''
    assert h.node.current_plan is before
    # The executor still answers.
    assert h.call('replan', Trigger.Request()).success


def set_parameters(h: Harness, **values):
    """Set ``values`` in one request (atomically); the one result."""
    answer = h.call('set_parameters_atomically', SetParametersAtomically.Request(
        parameters=[Parameter(name, value=value).to_parameter_msg()
                    for name, value in values.items()]))
    return answer.result


@pytest.mark.parametrize('values, reason', [
    ({'vehicle_jerk_time_s': 1e-300}, 'jerk_time_s must be in [0.01, 10) s'),
    ({'vehicle_max_accel_mpss': 1e300, 'vehicle_max_jerk_mpsss': 1e-300},
     'max_accel_mpss must be in [0.01, 1000]'),
    ({'vehicle_max_jerk_mpsss': 1e-300}, 'max_jerk_mpsss must be in [0.01, 10000]'),
    ({'vehicle_max_speed_mps': 1000.0, 'vehicle_max_accel_mpss': 0.01,
      'vehicle_max_jerk_mpsss': 0.01}, 'to reach its cruise speed from rest'),
])
def test_vehicle_limits_no_plan_could_be_made_with_are_refused_when_set(
        harness, values, reason):
    h = harness()
    h.published(1)
    before = h.node.current_plan
    result = set_parameters(h, **values)
    assert not result.successful and reason in result.reason, result.reason
    assert h.node.config.vehicle == before.request.mission.vehicle
    assert h.call('replan', Trigger.Request()).success
    h.published(2)


def test_a_vehicle_that_cannot_reach_the_goal_in_time_is_refused_when_set(harness):
    h = harness(max_speed_mps=10.0, horizon_s=400.0, num_slots=100, vehicle_aware=True)
    h.published(1)
    result = set_parameters(h, vehicle_max_accel_mpss=0.01)
    assert not result.successful
    assert 'cannot reach qF in time' in result.reason and 'raise horizon_s' in result.reason
    assert h.node.config.vehicle.max_accel_mpss == 2.5


def test_mission_dir_is_opened_once_so_replacing_it_cannot_redirect_writes(harness, tmp_path):
    folder = tmp_path / 'missions'
    folder.mkdir()
    elsewhere = tmp_path / 'elsewhere'
    elsewhere.mkdir()
    h = harness(mission_dir=str(folder), mission_file='flight.waypoints', max_speed_mps=10.0,
                horizon_s=400.0, num_slots=100, vehicle_aware=True)
    h.published(1)
    folder.rename(tmp_path / 'moved')
    folder.symlink_to(elsewhere, target_is_directory=True)
    (tmp_path / 'moved' / 'flight.waypoints').unlink()
    answer = h.call('export_mission', Trigger.Request())
    assert answer.success, answer.message
    assert (tmp_path / 'moved' / 'flight.waypoints').read_text().startswith('QGC WPL 110')
    assert list(elsewhere.iterdir()) == []


def test_a_mission_dir_that_cannot_be_opened_stops_the_node_at_start(ros_context, tmp_path):
    from uav_comm_planner.errors import PlannerError
    from uav_comm_planner.ros.node import PlannerNode

    with pytest.raises(PlannerError, match='mission_dir .* cannot be opened as a folder'):
        PlannerNode(context=ros_context, parameter_overrides=[
            Parameter('mission_dir', value=str(tmp_path / 'missing'))])


@pytest.mark.parametrize('url, reason', [('flight.tlog', "unknown kind 'flight.tlog'"),
                                         ('tcp:127.0.0.1:0', 'port must be a number'),
                                         ('/dev/zero', 'a memory device'),
                                         ('/dev/ttyNOTHERE,57600', 'No such file')])
def test_a_link_url_the_planner_does_not_open_is_refused_when_set(harness, url, reason):
    h = harness()
    h.published(1)
    result = set_parameter(h, 'mavlink_url', url)
    assert not result.successful and reason in result.reason, result.reason
    assert not h.node.vehicle.linked


def test_a_vehicle_link_error_is_one_line_on_the_log_and_on_planner_status(harness):
    from diagnostic_msgs.msg import DiagnosticArray

    from uav_comm_planner.ros.publishing import STATUS_QOS, TOPIC_STATUS
    h = harness()
    h.published(1)
    statuses = []
    h.probe.create_subscription(DiagnosticArray, TOPIC_STATUS, statuses.append, STATUS_QOS)
    h.spin_until(lambda: h.node.count_subscribers(TOPIC_STATUS) > 0, 'status subscriber')
    h.node._on_vehicle_report('vehicle link: the vehicle keeps asking for items: it loops',
                              True)
    h.spin_until(lambda: any('it loops' in s.status[0].message for s in statuses),
                 'link error on planner_status')
    assert h.node.stats.last_error.count('\n') == 0
