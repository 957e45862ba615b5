"""Send a new ground-node set to a running planner and wait for the plan through it.

For a terminal without the ros2 command line::

    python -m uav_comm_planner.ros.send_ground_nodes 300,200 900,-150 1500,250

publishes the nodes (x, y in metres, in ``--frame-id``) on ``ground_nodes`` and waits until
the planner publishes a plan for exactly these nodes; it prints that plan's path and exits 0.
When the planner refuses the nodes (``planner_status`` says so, naming them) it prints the
planner's reason and exits 2 at once; it exits 1 when no planner listens or none answers in
time.
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Sequence

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseArray
from nav_msgs.msg import Path
import rclpy
from rclpy.node import Node
from rclpy.utilities import remove_ros_args
from visualization_msgs.msg import MarkerArray

from uav_comm_planner.core.scenario import Point
from uav_comm_planner.ros.messages import (nanoseconds_of, nodes_text, pose_array,
                                           STATUS_NAME)
from uav_comm_planner.ros.node import GROUND_NODES_QOS, TOPIC_GROUND_NODES
from uav_comm_planner.ros.publishing import (OUTPUT_QOS, STATUS_QOS, TOPIC_MARKERS,
                                             TOPIC_PATH, TOPIC_STATUS)


def parse_point(text: str) -> Point:
    """``'x,y'`` as a point in metres."""
    try:
        x, y = (float(part) for part in text.split(','))
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected x,y in metres, got {text!r}') from None
    return (x, y)


class GroundNodesSender:
    """Publishes node sets through ``node`` and recognises the planner's answer to them.

    Spinning is left to the caller, so that the helper works in any executor.
    """

    def __init__(self, node: Node) -> None:
        self._publisher = node.create_publisher(PoseArray, TOPIC_GROUND_NODES, GROUND_NODES_QOS)
        self.path: Path | None = None
        self.markers: MarkerArray | None = None
        self.refusals: dict[str, str] = {}
        node.create_subscription(Path, TOPIC_PATH, self._on_path, OUTPUT_QOS)
        node.create_subscription(MarkerArray, TOPIC_MARKERS, self._on_markers, OUTPUT_QOS)
        node.create_subscription(DiagnosticArray, TOPIC_STATUS, self._on_status, STATUS_QOS)

    def _on_status(self, message: DiagnosticArray) -> None:
        for status in message.status:
            if status.name != STATUS_NAME or status.level != DiagnosticStatus.ERROR:
                continue
            values = {pair.key: pair.value for pair in status.values}
            if values.get('request') == TOPIC_GROUND_NODES and 'nodes' in values:
                self.refusals[values['nodes']] = status.message

    def refusal(self, points: Sequence[Point]) -> str | None:
        """The planner's reason for refusing exactly ``points``, if it said so."""
        return self.refusals.get(nodes_text(points))

    def _on_path(self, message: Path) -> None:
        self.path = message

    def _on_markers(self, message: MarkerArray) -> None:
        self.markers = message

    def listening(self) -> bool:
        """Whether a planner subscribes to the ground nodes."""
        return self._publisher.get_subscription_count() > 0

    def send(self, points: Sequence[Point], frame_id: str) -> None:
        """Publish ``points`` as the new node set."""
        self._publisher.publish(pose_array(points, frame_id))

    def answered(self, points: Sequence[Point]) -> bool:
        """Whether the latest plan received is for exactly ``points``, path included."""
        if self.markers is None or self.path is None:
            return False
        nodes = next((m for m in self.markers.markers if m.ns == 'ground_nodes'), None)
        return (nodes is not None and [(p.x, p.y) for p in nodes.points] == list(points)
                and self.path.header.stamp == nodes.header.stamp)


def describe(path: Path) -> str:
    """One line about a planned path: poses, launch and landing points, duration."""
    first, last = path.poses[0], path.poses[-1]
    seconds = (nanoseconds_of(last.header.stamp) - nanoseconds_of(first.header.stamp)) / 1e9
    return (f'new plan: {len(path.poses)} poses from ({first.pose.position.x:g}, '
            f'{first.pose.position.y:g}) to ({last.pose.position.x:g}, '
            f'{last.pose.position.y:g}) over {seconds:g} s in {path.header.frame_id!r}')


def _spin_until(node: Node, condition, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            return False
        rclpy.spin_once(node, timeout_sec=0.1)
    return True


def _arguments(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='send_ground_nodes', description='Send ground nodes to a running planner.')
    parser.add_argument('points', nargs='+', type=parse_point, metavar='X,Y',
                        help='ground node position in metres')
    parser.add_argument('--frame-id', default='map', help='frame of the positions')
    parser.add_argument('--timeout', type=float, default=30.0,
                        help='seconds to wait for the planner, each step (default 30)')
    return parser.parse_args(argv)


def main(args: list[str] | None = None) -> int:
    """Publish the nodes given on the command line, wait for the plan; exit status."""
    argv = remove_ros_args(sys.argv if args is None else args)[1:]
    options = _arguments(argv)
    rclpy.init(args=args)
    node = Node('send_ground_nodes')
    try:
        sender = GroundNodesSender(node)
        if not _spin_until(node, sender.listening, options.timeout):
            print(f'no planner subscribes to {TOPIC_GROUND_NODES} (same ROS_DOMAIN_ID?)',
                  file=sys.stderr)
            return 1
        sender.refusals.clear()
        sender.send(options.points, options.frame_id)
        if not _spin_until(node, lambda: (sender.answered(options.points)
                                          or sender.refusal(options.points) is not None),
                           options.timeout):
            print('no plan for these nodes and no answer from the planner within '
                  f'{options.timeout:g} s', file=sys.stderr)
            return 1
        reason = sender.refusal(options.points)
        if reason is not None and not sender.answered(options.points):
            print(f'the planner {reason}', file=sys.stderr)
            return 2
        print(describe(sender.path))
        return 0
    except KeyboardInterrupt:
        return 1
    finally:
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()


if __name__ == '__main__':
    sys.exit(main())
