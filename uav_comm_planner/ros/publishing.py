"""The node's outputs: one publisher per topic, and the one log line per plan.

Every output of one plan carries the same plan stamp: the header stamp of ``planned_path``,
``power_plan`` (the power schedule as trajectory_msgs/JointTrajectory), ``plan_markers``,
``zone_markers`` (the zones the plan keeps to) and the ``planner_status`` entry that
announces the plan (with its min throughput). The unstamped ``power_schedule``
(Float64MultiArray) and ``min_throughput`` (Float64) stay for existing subscribers; pair them
by arrival only.
"""

from __future__ import annotations

import math

from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Path
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64, Float64MultiArray
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

from uav_comm_planner.core.energy import Battery, JOULES_PER_WH
from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.mission.energy import energy_figures, energy_lines
from uav_comm_planner.ros.messages import (marker_array, nodes_text, path_message, power_message,
                                           power_plan_message, status_message, zone_markers)
from uav_comm_planner.ros.params import node_battery
from uav_comm_planner.ros.planning import PlanOutcome

TOPIC_PATH = 'planned_path'
TOPIC_POWER = 'power_schedule'
TOPIC_POWER_PLAN = 'power_plan'
TOPIC_MIN_THROUGHPUT = 'min_throughput'
TOPIC_MARKERS = 'plan_markers'
TOPIC_STATUS = 'planner_status'
#: The zones the latest plan keeps to (operating area, keep-out zones), as line strips.
TOPIC_ZONE_MARKERS = 'zone_markers'

#: Outputs keep the latest plan for subscribers that join later.
OUTPUT_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: One status per request; a sender subscribes before it asks, so nothing is kept for later.
STATUS_QOS = QoSProfile(depth=20, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)


class PlanPublisher:
    """Publishes a plan on ``planned_path``, ``power_schedule``, ``min_throughput`` and markers.

    Takes the ``node`` that owns the publishers instead of being one; ``namespace`` (a fleet's
    ``uav1``...) puts every topic under ``<node namespace>/<namespace>/``.
    """

    def __init__(self, node: Node, namespace: str = '') -> None:
        def publisher(kind: type, topic: str, qos: QoSProfile):
            return node.create_publisher(kind, f'{namespace}/{topic}' if namespace else topic,
                                         qos)
        self._path = publisher(Path, TOPIC_PATH, OUTPUT_QOS)
        self._power = publisher(Float64MultiArray, TOPIC_POWER, OUTPUT_QOS)
        self._power_plan = publisher(JointTrajectory, TOPIC_POWER_PLAN, OUTPUT_QOS)
        self._throughput = publisher(Float64, TOPIC_MIN_THROUGHPUT, OUTPUT_QOS)
        self._markers = publisher(MarkerArray, TOPIC_MARKERS, OUTPUT_QOS)
        self._zones = publisher(MarkerArray, TOPIC_ZONE_MARKERS, OUTPUT_QOS)
        self._status = publisher(DiagnosticArray, TOPIC_STATUS, STATUS_QOS)
        suffix = f'/{namespace}' if namespace else ''
        self._hardware_id = node.get_fully_qualified_name() + suffix

    def publish(self, outcome: PlanOutcome) -> None:
        """Publish the plan of a successful ``outcome`` on every output, then its status."""
        result, request = outcome.result, outcome.request
        frame_id = request.output.frame_id
        stamp = request.start_ns
        self._path.publish(path_message(result, frame_id, stamp))
        self._power.publish(power_message(result))
        self._power_plan.publish(power_plan_message(result, frame_id, stamp))
        self._throughput.publish(Float64(data=outcome.min_throughput))
        self._markers.publish(marker_array(result, frame_id, stamp))
        self._zones.publish(zone_markers(result.scenario.zones, frame_id, stamp,
                                         altitude_m=result.scenario.altitude_m))
        self._status.publish(status_message(
            stamp, request=request.reason, planned=True,
            message=summary_line(result, node_battery(request.output)),
            values=plan_values(outcome), hardware_id=self._hardware_id))

    def refused(self, stamp_ns: int, request: str, reason: str, *,
                nodes: str | None = None) -> None:
        """Publish that ``request`` was refused (or failed) and why; ``nodes``: the node set it
        asked for, as :func:`~uav_comm_planner.ros.messages.nodes_text` writes it."""
        values = {} if nodes is None else {'nodes': nodes}
        self._status.publish(status_message(stamp_ns, request=request, planned=False,
                                            message=reason, values=values,
                                            hardware_id=self._hardware_id))


def plan_values(outcome: PlanOutcome) -> dict[str, object]:
    """What the status says about a plan: node set, throughput, slots, and the power used of
    the budget: ``power_sum_w``, the sum of every node's transmit power over the slots (W),
    which P_T (``power_budget_w``) bounds; for a replan in flight ``mission_power_sum_w``, the
    same over the whole mission, the slots flown included."""
    result = outcome.result
    values: dict[str, object] = {
        'nodes': nodes_text(result.scenario.ground_nodes_m),
        'min_throughput_bps': repr(outcome.min_throughput),
        'slots': result.scenario.num_slots,
        'power_sum_w': repr(float(result.power.sum())),
    }
    if result.scenario.airframe is not None:
        figures = energy_figures(result)
        values.update({'propulsion_energy_wh': repr(figures.horizon_j / JOULES_PER_WH),
                       'mission_energy_wh': repr(figures.mission_j / JOULES_PER_WH),
                       'airframe': result.scenario.airframe.name})
    if outcome.receding is not None:
        receding = outcome.receding
        values.update({'elapsed_slots': receding.flown.num_slots,
                       'mission_power_sum_w': repr(receding.mission_energy_w),
                       'mission_rates_bps': ','.join(repr(float(r))
                                                     for r in receding.mission_rates)})
    return values


def summary_line(result: PlanResult, battery: Battery | None = None) -> str:
    """The one log line per plan: objective, both baselines, size and plan time, and with an
    airframe its propulsion energy and whether ``battery`` (None: ArduCopter's default) flies
    it. A plan below the static point is said not to be worse than it: the static point hovers
    over the nodes for the whole horizon, so it ignores the flight from launch and to
    landing."""
    scenario = result.scenario
    baselines = result.baselines
    if baselines:
        static = baselines.get('static', math.nan)
        caveat = (', which ignores launch and landing' if result.min_throughput < static
                  else '')
        compared = (f'straight line {baselines.get("straight", math.nan):.4g}, '
                    f'static point {static:.4g}{caveat}')
    else:
        compared = 'baselines off'
    nodes = f'{scenario.num_nodes} node' + ('' if scenario.num_nodes == 1 else 's')
    line = (f'plan: min throughput {result.min_throughput:.4g} bit/s ({compared}); {nodes}, '
            f'{scenario.num_slots} slots of {scenario.slot_s:g} s, {result.status}, '
            f'planned in {result.solve_time_s:.2f} s')
    if scenario.airframe is not None:
        line += '; ' + '; '.join(energy_lines(result, battery))
    return line
