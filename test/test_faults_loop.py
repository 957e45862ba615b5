"""The closed loop's faults on the node's side, on real rclpy in this process: explicit
parameters over firmware defaults, late requests, unflyable winds."""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from helpers import HORIZON_S, NODES_B, SLOT_S
import pytest
import rclpy
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from std_srvs.srv import Trigger

from uav_comm_planner.errors import PlannerError
from uav_comm_planner.ros.flight import SOURCE_TELEMETRY
from uav_comm_planner.ros.messages import status_values
from uav_comm_planner.ros.node import PlannerNode, TOPIC_GROUND_NODES
from uav_comm_planner.ros.publishing import STATUS_QOS, TOPIC_STATUS
from uav_comm_planner.ros.wind import REASON as WIND_REASON
from uav_comm_planner.vehicle.firmware import FIRMWARES


def _node_from_command_line(arguments: list[str]) -> PlannerNode:
    """A node made as ``planner --ros-args <arguments>`` makes it (its context's arguments)."""
    context = rclpy.Context()
    rclpy.init(args=['planner', '--ros-args', *arguments], context=context,
               signal_handler_options=SignalHandlerOptions.NO)
    try:
        return PlannerNode(context=context)
    except BaseException:
        context.try_shutdown()
        raise


def _close(node: PlannerNode) -> None:
    context = node.context
    node.destroy_node()
    context.try_shutdown()


def test_an_explicit_speed_equal_to_arducopters_default_wins_for_px4():
    # 10 m/s is ArduCopter's WPNAV_SPEED default: given for PX4 it is still given.
    node = _node_from_command_line(['-p', 'mission_firmware:=px4',
                                    '-p', 'vehicle_max_speed_mps:=10.0'])
    try:
        assert node.config.vehicle.max_speed_mps == 10.0
        assert 'vehicle_max_speed_mps' in node._binding.explicit
    finally:
        _close(node)


def test_a_speed_not_given_is_the_firmwares_default():
    node = _node_from_command_line(['-p', 'mission_firmware:=px4', '-p', 'max_speed_mps:=5.0',
                                    '-p', 'horizon_s:=600.0'])
    try:
        default = FIRMWARES['px4'].default_limits['max_speed_mps']
        assert node.config.vehicle.max_speed_mps == default
        assert 'vehicle_max_speed_mps' not in node._binding.explicit
    finally:
        _close(node)


def test_an_override_equal_to_the_default_is_explicit(ros_context):
    node = PlannerNode(context=ros_context, parameter_overrides=[
        Parameter('mission_firmware', value='px4'),
        Parameter('vehicle_max_speed_mps', value=10.0)])
    try:
        assert node.config.vehicle.max_speed_mps == 10.0
    finally:
        node.destroy_node()


def test_px4_without_an_explicit_speed_refuses_a_faster_plan():
    with pytest.raises(PlannerError, match='faster than the vehicle flies'):
        _node_from_command_line(['-p', 'mission_firmware:=px4'])


def _statuses(h) -> list:
    statuses: list[DiagnosticArray] = []
    h.probe.create_subscription(DiagnosticArray, TOPIC_STATUS, statuses.append, STATUS_QOS)
    h.spin_until(lambda: h.node.count_subscribers(TOPIC_STATUS) > 0, 'status subscriber')
    return statuses


def _refusals(statuses: list, request: str) -> list[str]:
    return [s.status[0].message for s in statuses
            if s.status[0].level == DiagnosticStatus.ERROR
            and status_values(s).get('request') == request]


def test_a_request_after_the_last_slot_has_begun_never_restarts_the_mission(harness):
    h = harness()
    statuses = _statuses(h)
    h.published(1)
    # The mission's clock started one slot less than its horizon ago: its last slot has begun.
    h.node.flight.start_clock(h.node.clock_s() - HORIZON_S + SLOT_S / 2, 'test')
    mission_id = h.node.progress.mission_id
    requests = h.node.stats.requests_made
    assert h.node.progress.over(h.node.clock_s())
    h.send_nodes(NODES_B)
    h.spin_until(lambda: _refusals(statuses, TOPIC_GROUND_NODES), 'refusal of the late nodes')
    assert 'every slot of the mission in flight has begun' in \
        _refusals(statuses, TOPIC_GROUND_NODES)[0]
    h.node.vehicle.wind.add(h.node.clock_s(), -3.0, 0.0)
    h.spin_until(lambda: _refusals(statuses, WIND_REASON), 'refusal of the late wind')
    for _ in range(20):
        h.executor.spin_once(timeout_sec=0.05)
    # Nothing planned, the mission and its clock as they were.
    assert h.node.stats.requests_made == requests
    assert h.node.progress.mission_id == mission_id and h.node.progress.started
    # Asked for explicitly, a new mission is planned from start_m.
    assert h.call('replan', Trigger.Request()).success
    h.published(2)
    assert h.node.progress.mission_id != mission_id and not h.node.progress.started


def test_a_wind_the_plan_cannot_fly_is_refused_once_not_replanned_at_every_interval(harness):
    h = harness(vehicle_aware=True, max_speed_mps=10.0, horizon_s=400.0, num_slots=20,
                replan_interval_s=10.0)
    statuses = _statuses(h)
    h.published(1)
    h.node.flight.start_clock(h.node.clock_s(), 'test')
    tracker = h.node.vehicle.wind
    requests = h.node.stats.requests_made
    # A gale at the vehicle's airspeed, reported at 10 Hz over 30 replan intervals.
    airspeed = h.node.config.vehicle.airspeed_mps
    for step in range(3000):
        tracker.add(step * 0.1, -airspeed - 1.0, 0.0)
    h.spin_until(lambda: _refusals(statuses, WIND_REASON), 'refusal of the gale')
    for _ in range(20):
        h.executor.spin_once(timeout_sec=0.05)
    refusals = _refusals(statuses, WIND_REASON)
    assert len(refusals) == 1 and 'cannot hold its position' in refusals[0], refusals
    assert tracker.replans == 0 and h.node.stats.requests_made == requests
    assert h.node.stats.plans_published == 1
    # A wind that changes materially is answered again: one the vehicle flies (here a
    # tailwind, once the smoothing has let the gale go) is planned for.
    for step in range(3000, 4200):
        tracker.add(step * 0.1, 3.0, 0.0)
    h.spin_until(lambda: h.node.current_plan.request.scenario.wind_speed_mps > 1.0,
                 'plan for the tailwind')
    assert h.node.current_plan.request.reason == WIND_REASON and tracker.replans >= 1


def _gale_harness(harness):
    """A vehicle-aware node (airspeed 9 m/s) with its first plan published, and its
    planner_status messages."""
    h = harness(vehicle_aware=True, max_speed_mps=10.0, horizon_s=400.0, num_slots=20,
                replan_interval_s=10.0)
    statuses = _statuses(h)
    h.published(1)
    return h, statuses


def test_a_rising_gale_is_refused_once_not_at_every_threshold_it_crosses(harness):
    h, statuses = _gale_harness(harness)
    tracker = h.node.vehicle.wind
    airspeed = h.node.config.vehicle.airspeed_mps
    requests = h.node.stats.requests_made
    # Before the clock runs (the plan follows the wind to 0.5 m/s): a gale from the airspeed
    # to 5 m/s above it over 100 s at 10 Hz, its smoothed estimate crossing 0.5 m/s steps
    # many times.
    for step in range(1000):
        tracker.add(step * 0.1, -(airspeed + 0.005 * step), 0.0)
    assert tracker.estimate.speed_mps > airspeed + 2.0
    h.spin_until(lambda: _refusals(statuses, WIND_REASON), 'refusal of the gale')
    for _ in range(20):
        h.executor.spin_once(timeout_sec=0.05)
    refusals = _refusals(statuses, WIND_REASON)
    assert len(refusals) == 1, refusals
    assert tracker.refused and h.node.flight.wind_refused
    assert h.node.stats.requests_made == requests and tracker.replans == 0
    # Once a plan can take the wind it is planned for, and the refusal no longer stands.
    for step in range(1000, 2200):
        tracker.add(step * 0.1, 3.0, 0.0)
    h.spin_until(lambda: h.node.current_plan.request.scenario.wind_speed_mps > 1.0,
                 'plan for the tailwind')
    assert not tracker.refused and len(_refusals(statuses, WIND_REASON)) == 1


@pytest.mark.parametrize('gale', [False, True])
def test_a_uav_off_its_plan_in_a_refused_gale_is_not_replanned(harness, gale):
    h, statuses = _gale_harness(harness)
    flight = h.node.flight
    start_s = h.node.clock_s()
    flight.start_clock(start_s, 'test')
    if gale:
        for step in range(300):
            h.node.vehicle.wind.add(step * 0.1, -h.node.config.vehicle.airspeed_mps - 1.0, 0.0)
        h.spin_until(lambda: _refusals(statuses, WIND_REASON), 'refusal of the gale')
    requests = h.node.stats.requests_made
    # The UAV 300 m beside q0 for 30 s (three replan intervals): far off its plan.
    x, y = h.node.config.scenario.start_m
    for k in range(300):
        flight.on_position(start_s + 0.1 * k, x, y + 300.0, source=SOURCE_TELEMETRY)
    made = h.node.stats.requests_made - requests
    assert made == 0 if gale else made >= 1, made


def test_the_node_streams_a_px4_plan_at_10_mps_and_says_the_acceleration_it_asks():
    from types import SimpleNamespace

    from uav_comm_planner import paper_scenario
    from uav_comm_planner.mission.request import vehicle_limits
    from uav_comm_planner.ros.vehicle import _reference_for
    from uav_comm_planner.mission.policy import plan_for_vehicle

    scenario = paper_scenario('I', ground_nodes_m=((-150.0, 150.0), (150.0, 350.0)),
                              start_m=(0.0, 10.0), goal_m=(0.0, 400.0), horizon_s=120.0,
                              num_slots=30, altitude_m=30.0, max_speed_mps=10.0)
    limits = vehicle_limits({'max_speed_mps': 10.0}, firmware='px4')
    flown = plan_for_vehicle(scenario, limits, firmware='px4').flown

    def outcome(firmware: str) -> SimpleNamespace:
        output = SimpleNamespace(mission_firmware=firmware)
        return SimpleNamespace(result=flown, request=SimpleNamespace(output=output))
    reference, note = _reference_for(outcome('px4'), limits)
    assert reference.accel_raised
    assert f'up to {reference.bounds.accel_mpss:.3g} m/s/s' in note and 'px4' in note
    with pytest.raises(PlannerError, match='acceleration 3 m/s/s'):
        _reference_for(outcome('ardupilot'), limits)
