"""/diagnostics as ROS tools read it, the topics the node advertises, and coarse slots, on
real rclpy in this process."""

from __future__ import annotations

import socket

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
import numpy as np
import pytest
from rcl_interfaces.msg import Log
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy

from uav_comm_planner.mission.resolution import coarse_slots
from uav_comm_planner.ros.diagnostics import (DIAGNOSTICS_QOS, MISSION_CLOCK, PLANNER,
                                              TOPIC_DIAGNOSTICS, VEHICLE_LINK)
from uav_comm_planner.ros.node import NODE_NAME
from uav_comm_planner.ros.vehicle import TOPIC_VEHICLE_POSE

#: Slots of 1 s at 100 m/s: legs of at most 100 m = H, as fine as the channel needs.
FINE = {'num_slots': 40, 'horizon_s': 40.0}


class DiagnosticsProbe:
    """The latest status of each name heard on /diagnostics, and the node's warnings."""

    def __init__(self, h) -> None:
        self.statuses: dict[str, DiagnosticStatus] = {}
        self.warnings: list[str] = []
        h.probe.create_subscription(DiagnosticArray, TOPIC_DIAGNOSTICS, self._on_array,
                                    DIAGNOSTICS_QOS)
        h.probe.create_subscription(Log, '/rosout', self._on_log, QoSProfile(
            depth=100, reliability=ReliabilityPolicy.RELIABLE))

    def _on_array(self, message: DiagnosticArray) -> None:
        for status in message.status:
            self.statuses[status.name] = status

    def _on_log(self, message: Log) -> None:
        if message.name == NODE_NAME and message.level == Log.WARN:
            self.warnings.append(message.msg)

    def status(self, concern: str) -> DiagnosticStatus | None:
        return self.statuses.get(f'{NODE_NAME}: {concern}')

    def values(self, concern: str) -> dict[str, str]:
        return {pair.key: pair.value for pair in self.status(concern).values}


def set_parameter(h, name: str, value):
    answer = h.call('set_parameters', SetParameters.Request(
        parameters=[Parameter(name, value=value).to_parameter_msg()]))
    return answer.results[0]


def advertised(h) -> set[str]:
    return {name for name, _ in h.probe.get_publisher_names_and_types_by_node(NODE_NAME, '/')}


def test_diagnostics_carry_the_plan_the_link_and_the_clock(harness):
    h = harness(**FINE)
    probe = DiagnosticsProbe(h)
    h.published(1)
    outcome = h.node.current_plan
    h.spin_until(lambda: probe.status(PLANNER) is not None
                 and probe.values(PLANNER).get('plan_stamp_ns') == str(outcome.request.start_ns)
                 and probe.status(VEHICLE_LINK) is not None
                 and probe.status(MISSION_CLOCK) is not None, 'the plan on /diagnostics')
    planner = probe.status(PLANNER)
    assert planner.level == DiagnosticStatus.OK and planner.hardware_id == '/' + NODE_NAME
    assert planner.message.startswith('planned: min throughput ')
    values = probe.values(PLANNER)
    assert float(values['min_throughput_bps']) == outcome.min_throughput
    assert float(values['straight_bps']) == outcome.result.baselines['straight']
    assert values['slots'] == '40' and 'longest_leg_m' not in values
    # The power used of the budget P_T: a sum of watts over nodes and slots, named as such.
    assert float(values['power_sum_w']) == float(outcome.result.power.sum())
    assert float(values['power_sum_w']) <= outcome.result.scenario.power_budget_w * (1 + 1e-9)
    assert 'energy_w' not in values
    link = probe.status(VEHICLE_LINK)
    assert link.level == DiagnosticStatus.OK and link.message.startswith('off: ')
    clock = probe.status(MISSION_CLOCK)
    assert clock.level == DiagnosticStatus.OK and clock.message.startswith('waiting: ')
    # Without a link there is no vehicle pose to publish, so no such topic.
    h.spin_until(lambda: '/planned_path' in advertised(h), 'the node in the graph')
    assert '/' + TOPIC_VEHICLE_POSE not in advertised(h)


def test_diagnostics_state_the_plan_s_propulsion_energy(harness):
    """With an airframe the planner status carries the horizon's propulsion energy (each leg
    at its speed over its slot, by eq. (12) written out here) and the mission's, takeoff and
    landing added."""
    h = harness(airframe='zeng2019', max_speed_mps=10.0, horizon_s=400.0, num_slots=100)
    probe = DiagnosticsProbe(h)
    h.published(1)
    outcome = h.node.current_plan
    h.spin_until(lambda: probe.status(PLANNER) is not None
                 and probe.values(PLANNER).get('plan_stamp_ns') == str(outcome.request.start_ns),
                 'the plan on /diagnostics')
    values = probe.values(PLANNER)
    scenario = outcome.result.scenario
    assert values['airframe'] == 'zeng2019'
    path = np.vstack([scenario.start_m, outcome.result.trajectory, scenario.goal_m])
    v = np.linalg.norm(np.diff(path, axis=0), axis=1) / scenario.slot_s
    # Zeng 2019 eq. (12) with Table I (P0, Pi, U_tip, v0, d0, rho, s, A).
    blade = 79.86 * (1.0 + 3.0 * v ** 2 / 120.0 ** 2)
    induced = 88.63 * np.sqrt(np.sqrt(1.0 + v ** 4 / (4.0 * 4.03 ** 4))
                              - v ** 2 / (2.0 * 4.03 ** 2))
    parasite = 0.5 * 0.6 * 1.225 * 0.05 * 0.503 * v ** 3
    horizon_wh = float(((blade + induced + parasite) * scenario.slot_s).sum()) / 3600.0
    assert float(values['propulsion_energy_wh']) == pytest.approx(horizon_wh, rel=1e-6)
    assert float(values['mission_energy_wh']) > float(values['propulsion_energy_wh'])


def test_a_refused_change_is_on_diagnostics_whole_with_its_fix(harness):
    h = harness(**FINE)
    probe = DiagnosticsProbe(h)
    h.published(1)
    result = set_parameter(h, 'goal_m', [9000.0, 0.0])
    assert not result.successful
    assert result.reason.startswith('goal unreachable: start and goal are 9000.0 m apart')
    assert result.reason.endswith('raise horizon_s to 87.8 s or more, or max_speed_mps, or move '
                                  'the goal')
    h.spin_until(lambda: probe.status(PLANNER) is not None
                 and probe.status(PLANNER).level == DiagnosticStatus.WARN, 'the refusal')
    planner = probe.status(PLANNER)
    assert planner.message == f'parameter change refused (goal_m): {result.reason}'
    assert '\n' not in planner.message and len(planner.message) > 200
    values = probe.values(PLANNER)
    assert values['refused_reason'] == planner.message
    assert values['refused_request'] == 'parameters goal_m'
    # The plan in force stays, and so do its numbers.
    assert float(values['min_throughput_bps']) == h.node.current_plan.min_throughput


def test_slots_too_coarse_for_the_channel_are_warned_with_the_numbers(harness):
    h = harness(**FINE)
    probe = DiagnosticsProbe(h)
    h.published(1)
    assert set_parameter(h, 'num_slots', 3).successful
    h.published(2)
    coarse = coarse_slots(h.node.current_plan.result)
    assert coarse is not None and coarse.longest_leg_m > 500.0
    h.spin_until(lambda: probe.status(PLANNER) is not None
                 and probe.status(PLANNER).level == DiagnosticStatus.WARN
                 and probe.warnings, 'the coarse-slot warning')
    planner = probe.status(PLANNER)
    assert planner.message == coarse.message() == probe.warnings[-1]
    assert planner.message.startswith('slots too coarse for the channel: the 3 waypoints are '
                                      f'up to {coarse.longest_leg_m:.0f} m apart')
    assert planner.message.endswith('set num_slots to at least 40')
    values = probe.values(PLANNER)
    assert float(values['longest_leg_m']) == coarse.longest_leg_m
    assert values['altitude_m'] == '100.0' and values['suggested_num_slots'] == '40'
    assert float(values['along_legs_min_throughput_bps']) < coarse.stated_bps


@pytest.mark.slow
def test_the_link_has_its_status_and_vehicle_pose_only_while_it_runs(harness):
    with socket.create_server(('127.0.0.1', 0)) as unused:
        port = unused.getsockname()[1]
    url = f'tcp:127.0.0.1:{port}'
    h = harness(mavlink_url=url, **FINE)
    probe = DiagnosticsProbe(h)
    h.published(1)
    h.spin_until(lambda: probe.status(VEHICLE_LINK) is not None
                 and probe.status(VEHICLE_LINK).level == DiagnosticStatus.ERROR,
                 'the link error on /diagnostics')
    link = probe.status(VEHICLE_LINK)
    assert link.hardware_id == url and f'cannot open {url!r}' in link.message
    assert probe.values(VEHICLE_LINK)['mavlink_url'] == url
    h.spin_until(lambda: '/' + TOPIC_VEHICLE_POSE in advertised(h), 'vehicle_pose advertised')
    assert set_parameter(h, 'mavlink_url', '').successful
    h.spin_until(lambda: '/' + TOPIC_VEHICLE_POSE not in advertised(h), 'vehicle_pose gone')
    h.spin_until(lambda: probe.status(VEHICLE_LINK).message.startswith('off: '), 'link off')


def test_a_link_error_ends_with_the_link_up_and_a_failed_upload_with_a_verified_one(harness):
    from uav_comm_planner.vehicle.mavlink.telemetry import LinkEvent

    vehicle = harness(**FINE).node.vehicle
    events = vehicle._on_link_event
    events(LinkEvent('error', 'vehicle link lost: reset by peer'))
    assert vehicle.last_error == 'vehicle link lost: reset by peer'
    events(LinkEvent('connected', 'vehicle link up on tcp:127.0.0.1:5760'))
    assert vehicle.last_error == ''
    events(LinkEvent('error', 'mission upload failed: no answer', 7))
    events(LinkEvent('connected', 'vehicle link up on tcp:127.0.0.1:5760'))
    assert vehicle.last_error == 'mission upload failed: no answer'
    events(LinkEvent('uploaded', 'mission of 9 items uploaded and read back', 8))
    assert vehicle.last_error == '' and vehicle.uploads_verified == 1
