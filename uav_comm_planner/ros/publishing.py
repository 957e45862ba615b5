"""The node's outputs: one publisher per topic, and the one log line per plan."""

from __future__ import annotations

import math

from nav_msgs.msg import Path
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64, Float64MultiArray
from visualization_msgs.msg import MarkerArray

from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.ros.messages import marker_array, path_message, power_message
from uav_comm_planner.ros.worker import PlanOutcome

TOPIC_PATH = 'planned_path'
TOPIC_POWER = 'power_schedule'
TOPIC_MIN_THROUGHPUT = 'min_throughput'
TOPIC_MARKERS = 'plan_markers'

#: Outputs keep the latest plan for subscribers that join later.
OUTPUT_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)


class PlanPublisher:
    """Publishes a plan on ``planned_path``, ``power_schedule``, ``min_throughput`` and markers.

    Takes the ``node`` that owns the publishers instead of being one.
    """

    def __init__(self, node: Node) -> None:
        self._path = node.create_publisher(Path, TOPIC_PATH, OUTPUT_QOS)
        self._power = node.create_publisher(Float64MultiArray, TOPIC_POWER, OUTPUT_QOS)
        self._throughput = node.create_publisher(Float64, TOPIC_MIN_THROUGHPUT, OUTPUT_QOS)
        self._markers = node.create_publisher(MarkerArray, TOPIC_MARKERS, OUTPUT_QOS)

    def publish(self, outcome: PlanOutcome) -> None:
        """Publish the plan of a successful ``outcome`` on every output."""
        result, request = outcome.result, outcome.request
        frame_id = request.output.frame_id
        self._path.publish(path_message(result, frame_id, request.start_ns))
        self._power.publish(power_message(result))
        self._throughput.publish(Float64(data=float(result.min_throughput)))
        self._markers.publish(marker_array(result, frame_id, request.start_ns))


def summary_line(result: PlanResult) -> str:
    """The one log line per plan: objective, both baselines, size and plan time."""
    scenario = result.scenario
    baselines = result.baselines
    if baselines:
        compared = (f'straight line {baselines.get("straight", math.nan):.4g}, '
                    f'static point {baselines.get("static", math.nan):.4g}')
    else:
        compared = 'baselines off'
    nodes = f'{scenario.num_nodes} node' + ('' if scenario.num_nodes == 1 else 's')
    return (f'plan: min throughput {result.min_throughput:.4g} bit/s ({compared}); {nodes}, '
            f'{scenario.num_slots} slots of {scenario.slot_s:g} s, {result.status}, '
            f'planned in {result.solve_time_s:.2f} s')
