"""The closed loop's faults on the node's side, on real rclpy in this process: explicit
parameters over firmware defaults, late requests, unflyable winds."""

from __future__ import annotations

import pytest
import rclpy
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions

from uav_comm_planner.errors import PlannerError
from uav_comm_planner.ros.node import PlannerNode
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
        assert node.config.vehicle.max_speed_mps == FIRMWARES['px4'].default_limits['max_speed_mps']
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
