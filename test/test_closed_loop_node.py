"""The node's side of the closed loop, on real rclpy in this process: plan stamps that pair
every output, the status of every request, the mission clock, and pose replans that happen
only off the plan and at a bounded rate."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from helpers import NODES_B
import numpy as np
import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from uav_comm_planner.mission.progress import planned_position
from uav_comm_planner.ros.messages import nanoseconds_of, nodes_text, status_values
from uav_comm_planner.ros.publishing import (OUTPUT_QOS, STATUS_QOS, TOPIC_MARKERS,
                                             TOPIC_MIN_THROUGHPUT, TOPIC_PATH, TOPIC_POWER_PLAN,
                                             TOPIC_STATUS)

POSE_RATE_HZ = 20.0


def listen(h):
    """Subscribe the harness's probe to power_plan and planner_status."""
    plans: list[JointTrajectory] = []
    statuses: list[DiagnosticArray] = []
    h.probe.create_subscription(JointTrajectory, TOPIC_POWER_PLAN, plans.append, OUTPUT_QOS)
    h.probe.create_subscription(DiagnosticArray, TOPIC_STATUS, statuses.append, STATUS_QOS)
    h.spin_until(lambda: h.node.count_subscribers(TOPIC_STATUS) > 0, 'status subscriber')
    return plans, statuses


def test_every_output_of_a_plan_carries_the_same_stamp(harness):
    h = harness()
    plans, statuses = listen(h)
    h.published(1)
    h.send_nodes(NODES_B)
    h.published(2)
    h.spin_until(lambda: plans and len(plans[-1].joint_names) == 2, 'power plan')
    h.spin_until(lambda: any(status_values(s).get('nodes') == nodes_text(NODES_B)
                             for s in statuses), 'status of the plan')
    stamp = h.node.current_plan.request.start_ns
    power_plan = plans[-1]
    status = next(s for s in statuses if status_values(s).get('nodes') == nodes_text(NODES_B))
    assert nanoseconds_of(h.latest(TOPIC_PATH).header.stamp) == stamp
    assert nanoseconds_of(power_plan.header.stamp) == stamp
    assert nanoseconds_of(h.latest(TOPIC_MARKERS).markers[0].header.stamp) == stamp
    assert nanoseconds_of(status.header.stamp) == stamp
    assert status.status[0].level == DiagnosticStatus.OK
    values = status_values(status)
    assert values['request'] == 'ground_nodes'
    assert float(values['min_throughput_bps']) == h.latest(TOPIC_MIN_THROUGHPUT).data
    # The stamped power schedule is the published one: slot m at m delta, one joint per node.
    result = h.node.current_plan.result
    assert power_plan.joint_names == ['node_1', 'node_2']
    np.testing.assert_array_equal([p.positions for p in power_plan.points], result.power.T)
    ends = [p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec
            for p in power_plan.points]
    np.testing.assert_allclose(ends, result.scenario.times_s, atol=1e-9)


def test_refusals_are_on_the_status_and_the_log(harness):
    h = harness(max_nodes=3)
    _, statuses = listen(h)
    h.published(1)
    duplicate = [(300.0, 200.0), (300.0, 200.0)]
    h.send_nodes(duplicate)
    h.spin_until(lambda: any(status_values(s).get('nodes') == nodes_text(duplicate)
                             for s in statuses), 'refusal on the status')
    refusal = next(s for s in statuses if status_values(s).get('nodes') == nodes_text(duplicate))
    assert refusal.status[0].level == DiagnosticStatus.ERROR
    assert 'refused' in refusal.status[0].message and 'duplicate' in refusal.status[0].message

    too_short = Parameter('horizon_s', value=5.0).to_parameter_msg()
    answer = h.call('set_parameters', SetParameters.Request(parameters=[too_short]))
    assert not answer.results[0].successful
    h.spin_until(lambda: any('parameter change refused (horizon_s)' in line
                             and 'goal unreachable' in line for line in h.error_logs),
                 'refused parameter in the log')
    h.spin_until(lambda: any(status_values(s).get('request') == 'parameters horizon_s'
                             for s in statuses), 'refused parameter on the status')


@pytest.mark.slow
def test_sender_exits_at_once_with_the_planners_reason(harness):
    h = harness()
    h.published(1)
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set():
            h.executor.spin_once(timeout_sec=0.05)
    spinner = threading.Thread(target=spin, daemon=True)
    spinner.start()
    sender = os.path.join(sys.prefix, 'bin', 'send_ground_nodes')
    try:
        began = time.monotonic()
        done = subprocess.run([sender, '300,200', '300,200', '--timeout', '60'],
                              capture_output=True, text=True, timeout=120)
        print(f'send_ground_nodes answered a refusal in {time.monotonic() - began:.1f} s')
        assert done.returncode == 2, done.stderr
        assert 'duplicate ground nodes' in done.stderr

        done = subprocess.run([sender, '300,200', '900,-150', '--frame-id', 'odom',
                               '--timeout', '60'], capture_output=True, text=True, timeout=120)
        assert done.returncode == 2 and "frame is 'odom'" in done.stderr, done.stderr

        done = subprocess.run([sender, '400,-200', '1100,300', '--timeout', '60'],
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr
        assert done.stdout.startswith('new plan:')
    finally:
        stop.set()
        spinner.join(5)


def test_mission_clock_starts_on_start_and_output_parameters_never_replan(harness, tmp_path):
    h = harness(mission_dir=str(tmp_path))
    h.published(1)
    assert not h.node.progress.started
    assert h.call('start', Trigger.Request()).success
    assert h.node.progress.started
    start = h.node.progress.segments[0].start_s
    assert not h.call('start', Trigger.Request()).success       # already running

    requests = h.node.stats.requests_made
    for name, value in (('mission_file', 'f.waypoints'),
                        ('mission_firmware', 'px4'), ('mission_end', 'rtl'),
                        ('replan_interval_s', 3.0)):
        answer = h.call('set_parameters', SetParameters.Request(
            parameters=[Parameter(name, value=value).to_parameter_msg()]))
        assert answer.results[0].successful, answer.results[0].reason
    assert h.node.stats.requests_made == requests
    assert h.node.progress.segments[0].start_s == start

    # A planning parameter in flight replans the rest under the whole mission's budget.
    answer = h.call('set_parameters', SetParameters.Request(
        parameters=[Parameter('power_budget_w', value=4.0).to_parameter_msg()]))
    assert answer.results[0].successful
    h.published(2)
    receding = h.node.current_plan.receding
    assert receding is not None
    assert h.node.progress.segments[0].start_s == start
    assert receding.mission_energy_w <= 4.0 * (1 + 1e-9)


def stream_poses(h, seconds: float, position_of) -> int:
    """Publish poses at POSE_RATE_HZ for ``seconds`` (node clock); returns how many."""
    sent = 0
    began = time.monotonic()
    while time.monotonic() - began < seconds:
        h.send_pose(*position_of())
        sent += 1
        next_at = began + sent / POSE_RATE_HZ
        while time.monotonic() < next_at:
            h.executor.spin_once(timeout_sec=max(0.0, next_at - time.monotonic()))
    return sent


@pytest.mark.slow
def test_a_20_hz_pose_stream_replans_a_bounded_number_of_times(harness):
    interval_s = 1.0
    h = harness(replan_interval_s=interval_s)
    h.published(1)
    assert h.call('start', Trigger.Request()).success

    def on_plan():
        segment = h.node.progress.current
        elapsed = h.node.get_clock().now().nanoseconds / 1e9 - segment.start_s
        return tuple(planned_position(segment.result, elapsed))

    requests = h.node.stats.requests_made
    sent = stream_poses(h, 2.0, on_plan)
    assert sent >= 30
    assert h.node.stats.requests_made == requests, 'a pose on the plan replanned'

    seconds = 3.0
    sent = stream_poses(h, seconds, lambda: (500.0, -300.0))
    replans = h.node.stats.requests_made - requests
    print(f'{sent} poses off the plan in {seconds:g} s: {replans} replans')
    assert 1 <= replans <= seconds / interval_s + 1
    h.published(h.node.stats.plans_published)
    assert h.node.current_plan.receding is not None


def test_a_replan_in_flight_is_planned_for_the_vehicle(harness):
    h = harness(vehicle_aware=True, max_speed_mps=10.0, horizon_s=400.0, num_slots=50)
    h.published(1)
    first = h.node.current_plan.vehicle_plan
    assert first is not None
    assert h.call('start', Trigger.Request()).success
    answer = h.call('set_parameters', SetParameters.Request(
        parameters=[Parameter('power_budget_w', value=4.0).to_parameter_msg()]))
    assert answer.results[0].successful
    h.published(2)
    outcome = h.node.current_plan
    assert outcome.receding is not None and outcome.vehicle_plan is not None
    # The same nodes: the replan continues the optimiser's plan in force, not the flown one.
    rest = outcome.request.mission.in_flight
    assert rest.warm
    np.testing.assert_array_equal(rest.previous_q, first.ideal.trajectory[rest.slots_kept:])
    # The published plan is the one the vehicle flies: its trajectory is the schedule's.
    scenario = outcome.result.scenario
    np.testing.assert_allclose(
        outcome.vehicle_plan.schedule.flight.positions(scenario.times_s),
        outcome.result.trajectory)
    assert outcome.receding.mission_energy_w <= 4.0 * (1 + 1e-9)
    rates = outcome.receding.mission_rates
    assert rates.min() == pytest.approx(outcome.min_throughput, rel=1e-12)
    # The mission's clock started once, at ~/start; the replan only came into force.
    h.spin_until(lambda: any('runs on' in line for line in h.info_logs), 'the replan logged')
    started = [line for line in h.info_logs if line.startswith('mission clock started')]
    assert len(started) == 1, h.info_logs
    assert 'the replan is in force from now (the mission clock runs on)' in h.info_logs


@pytest.mark.slow
def test_an_unreachable_vehicle_is_said_once_and_start_is_left_to_the_link(harness):
    with socket.create_server(('127.0.0.1', 0)) as unused:
        port = unused.getsockname()[1]
    h = harness(mavlink_url=f'tcp:127.0.0.1:{port}')
    h.published(1)

    def link_errors() -> list[str]:
        return [line for line in h.error_logs if 'retrying' in line]
    h.spin_until(lambda: link_errors(), 'link error on /rosout')
    assert f'cannot open {h.node.get_parameter("mavlink_url").value!r}' in link_errors()[0]
    began = time.monotonic()
    while time.monotonic() - began < 3.0:          # several reconnection attempts
        h.executor.spin_once(timeout_sec=0.05)
    assert len(link_errors()) == 1
    answer = h.call('start', Trigger.Request())
    assert not answer.success and 'mavlink_url' in answer.message
    assert not h.node.progress.started
