"""The ROS 2 node ``uav_comm_planner``: parameters and topics in, plans out.

An adapter over :func:`uav_comm_planner.plan`: ROS parameters become the settings
dataclasses (:mod:`uav_comm_planner.ros.params`), messages become arrays and results become
messages (:mod:`uav_comm_planner.ros.messages`). Planning runs on one worker thread; a request
made while a plan runs replaces any request still waiting, so the newest input wins and the
executor's callbacks stay responsive. Results come back to the executor through a guard
condition, where they are published and logged.

The mission clock (:mod:`uav_comm_planner.ros.flight`) starts when the UAV reaches the
plan's q0 (a ``uav_pose`` or, with ``mavlink_url``, the vehicle's telemetry within
START_RADIUS_M of it) or on ``~/start``; never at node start nor on a parameter change. A
replan of the mission in flight is in force when the vehicle reaches its q0 (with a link,
after its upload) or, without a link, as soon as it is published.

Replanning:

- before the mission clock runs, a ``ground_nodes`` message or an accepted parameter change
  plans the whole mission from ``start_m``; once the mission's last slot has begun, they
  (and the wind) are refused on ``planner_status`` and never restart the mission;
  ``~/replan`` always plans from ``start_m``, and ends the mission in flight. A
  ``ground_nodes`` message goes through the ``ground_nodes`` parameter, so it is checked like
  any parameter change and the parameter always holds the node set in use;
- a request that comes while a plan runs also asks the running plan to give up at its next
  step (the core's ``plan(should_stop=...)``), so the newest request is planned at once;
- while the clock runs, the same inputs replan the rest of the mission from the UAV's
  position by the receding horizon (:mod:`uav_comm_planner.core.receding`): the slots begun so
  far keep their power and the data they delivered (at the flown positions where a pose or
  telemetry has them, across a telemetry outage as planned moved by the offset from the plan
  at its ends, else as planned), the rest gets what is left of the budget;
- a ``uav_pose`` (or the vehicle's telemetry) replans the same way, only when the UAV is off
  the plan by more than ``replan_distance_m`` or ``replan_delay_s``, at most once every
  ``replan_interval_s``, and not when less than ``replan_interval_s`` of the mission is left;
- output-only parameters (:data:`~uav_comm_planner.ros.params.OUTPUT_ONLY`: mission file,
  firmware, end, frame, home, link and replan settings) never replan.

Every request ends in one ``planner_status`` message: planned (with the plan stamp that
every output of the plan carries) or refused, with the reason. The node's state (planner,
vehicle link, mission clock) is on ``/diagnostics``
(:mod:`uav_comm_planner.ros.diagnostics`).
"""

from __future__ import annotations

from dataclasses import dataclass
import signal
import sys

from geometry_msgs.msg import PoseArray, PoseStamped
import rclpy
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from uav_comm_planner.core.optimizer import plan
from uav_comm_planner.errors import PlannerError
from uav_comm_planner.mission.pipeline import Planner
from uav_comm_planner.mission.request import InFlight, MissionRequest
from uav_comm_planner.ros.battery import REASON as BATTERY
from uav_comm_planner.ros.binding import ParameterBinding
from uav_comm_planner.ros.diagnostics import NodeDiagnostics
from uav_comm_planner.ros.fleet import NodeFleet
from uav_comm_planner.ros.flight import MissionFlight, SOURCE_TELEMETRY
from uav_comm_planner.ros.messages import ground_nodes_of, nodes_text
from uav_comm_planner.ros.params import (flat_pairs, node_battery, NodeSettings, OUTPUT_ONLY,
                                         PlannerConfig)
from uav_comm_planner.ros.planning import (open_mission_folder, PlanningWorker, PlanOutcome,
                                           PlanRequest)
from uav_comm_planner.ros.publishing import PlanPublisher, summary_line
from uav_comm_planner.ros.services import PlannerServices
from uav_comm_planner.ros.vehicle import HOME_PARAMETERS, VehicleAdapter

NODE_NAME = 'uav_comm_planner'

TOPIC_GROUND_NODES = 'ground_nodes'
TOPIC_UAV_POSE = 'uav_pose'
#: Name of the telemetry as a position source.
SOURCE_VEHICLE = SOURCE_TELEMETRY
#: Name of the vehicle link's errors on planner_status.
SOURCE_VEHICLE_LINK = 'vehicle link'
#: Parameters that remake the vehicle link when they change (a stream running falls back).
LINK_PARAMETERS = HOME_PARAMETERS | {'mavlink_url', 'home_distance_limit_m', 'flight_mode'}

#: Volatile so that both volatile and transient-local publishers can send node sets.
GROUND_NODES_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                              durability=DurabilityPolicy.VOLATILE)
#: Best effort accepts pose streams of either reliability; only the latest pose matters.
UAV_POSE_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT,
                          durability=DurabilityPolicy.VOLATILE)


@dataclass
class PlannerStats:
    """What the node has done, for tests and introspection: plan requests made, plan attempts
    finished, plans published and given up for a newer request, errors logged (and the last
    one)."""

    requests_made: int = 0
    plans_run: int = 0
    plans_published: int = 0
    plans_cancelled: int = 0
    error_count: int = 0
    last_error: str = ''


#: Parameters that change what the mission file holds or where it is: a change writes the plan
#: in force again at once.
MISSION_OUTPUT = frozenset({'mission_file', 'mission_end', 'mission_firmware',
                            'home_latitude_deg', 'home_longitude_deg', 'home_altitude_m'})


def _replans(name: str, settings: NodeSettings) -> bool:
    """Whether a change of parameter ``name`` calls for a new plan."""
    return (name not in OUTPUT_ONLY
            # A plan for the vehicle is timed for its firmware (hold resolution).
            or (name == 'mission_firmware' and settings.vehicle_aware)
            # A fence is anchored at home: another home moves its zones.
            or (name.startswith('home_') and bool(settings.fence_file)))


class PlannerNode(Node):
    """Plans the UAV's flight for the ground nodes it hears of and publishes the plan (with
    ``uavs`` >= 2 a fleet's: :attr:`fleet`, :mod:`uav_comm_planner.ros.fleet`, plans).

    ``planner`` is the optimiser (the core's :func:`~uav_comm_planner.plan`, or a function of
    its signature); other keywords go to :class:`rclpy.node.Node`. Raises
    :class:`~uav_comm_planner.errors.PlannerError` when the initial parameters are invalid.
    Its parts each take the node: parameters, planning worker, mission in flight
    (:attr:`flight`), vehicle link (:attr:`vehicle`), outputs, services, fleet. ``stats``
    counts what it did; ``current_plan`` is the outcome in force.
    """

    def __init__(self, *, planner: Planner = plan, **node_options) -> None:
        super().__init__(NODE_NAME, **node_options)
        self._refusing_nodes: str | None = None
        self._binding = ParameterBinding(self, self._on_parameters,
                                         on_refused=self._on_parameters_refused)
        self.stats = PlannerStats()
        self.current_plan: PlanOutcome | None = None
        self.flight = MissionFlight(self)
        self.vehicle = VehicleAdapter(self, self._on_vehicle_position, self._on_vehicle_report,
                                      binding=self._binding)
        self._publisher = PlanPublisher(self)
        self.diagnostics = NodeDiagnostics(self)
        self.create_subscription(PoseArray, TOPIC_GROUND_NODES, self._on_ground_nodes,
                                 GROUND_NODES_QOS)
        self.create_subscription(PoseStamped, TOPIC_UAV_POSE, self._on_uav_pose, UAV_POSE_QOS)
        # Opened once: replacing mission_dir's path later cannot redirect a mission write.
        self.mission_folder = open_mission_folder(self.config.node)
        self._trigger_services = PlannerServices(self)
        self.fleet = NodeFleet(self, self.mission_folder)
        self._worker = self.fleet if self.fleet.active else PlanningWorker(
            self, planner, self._deliver, folder=self.mission_folder)
        self.vehicle.connect(self.config.node, self._binding.explicit)
        self.flight.request_plan('start')

    @property
    def config(self) -> PlannerConfig:
        """The settings the parameters make now."""
        return self._binding.config

    @property
    def progress(self):
        """The mission in flight (:class:`~uav_comm_planner.mission.progress.MissionProgress`)."""
        return self.flight.progress

    # Inputs.

    def _frame_accepted(self, frame_id: str, topic: str, nodes: str | None = None) -> bool:
        expected = self.config.node.frame_id
        if frame_id and frame_id != expected:
            self.refuse(topic, f'{topic} refused: its frame is {frame_id!r} but the planner '
                               f'works in {expected!r} (parameter frame_id)', nodes=nodes)
            return False
        return True

    def _on_ground_nodes(self, message: PoseArray) -> None:
        """Take the message's positions as the new node set, through the parameter."""
        limit = self.config.settings.max_nodes
        if len(message.poses) > limit:
            # Refused before any conversion: the cost of a message must not grow unchecked.
            self.refuse(TOPIC_GROUND_NODES, f'{TOPIC_GROUND_NODES} refused: too many ground '
                                            f'nodes: {len(message.poses)} given, the limit '
                                            f'max_nodes is {limit}')
            return
        points = ground_nodes_of(message)
        text = nodes_text(points)
        if not self._frame_accepted(message.header.frame_id, TOPIC_GROUND_NODES, text):
            return
        nodes = Parameter('ground_nodes', Parameter.Type.DOUBLE_ARRAY, flat_pairs(points))
        self._refusing_nodes = text
        try:
            self.set_parameters([nodes])
        finally:
            self._refusing_nodes = None

    def _on_parameters_refused(self, names: list[str], reason: str) -> None:
        """A refused parameter change (a ground_nodes message included): log and status."""
        if self._refusing_nodes is not None and names == ['ground_nodes']:
            self.refuse(TOPIC_GROUND_NODES, f'{TOPIC_GROUND_NODES} refused: {reason}',
                        nodes=self._refusing_nodes)
        else:
            self.refuse('parameters ' + ', '.join(names),
                        f'parameter change refused ({", ".join(names)}): {reason}')

    def _on_parameters(self, names: list[str]) -> None:
        """An accepted change: replan unless only output parameters changed."""
        planning = [name for name in names if _replans(name, self.config.node)]
        if LINK_PARAMETERS & set(names):
            self.vehicle.connect(self.config.node, self._binding.explicit)
        if not planning:
            self.get_logger().info(
                f'parameters {", ".join(names)} set; they apply to the next plan (no replan)')
            if MISSION_OUTPUT & set(names) and self.config.node.mission_file:
                self._trigger_services.export_mission()     # at once, not at the next plan
            return
        reason = (TOPIC_GROUND_NODES if self._refusing_nodes is not None
                  else 'parameters ' + ', '.join(planning))
        self.flight.request_update(reason)

    def _on_uav_pose(self, message: PoseStamped) -> None:
        if self._frame_accepted(message.header.frame_id, TOPIC_UAV_POSE):
            self.flight.on_position(self.clock_s(), message.pose.position.x,
                                    message.pose.position.y, source=TOPIC_UAV_POSE)

    def _on_vehicle_position(self, time_s: float, x: float, y: float, up_m: float) -> bool:
        return self.flight.on_position(time_s, x, y, source=SOURCE_VEHICLE, height_m=up_m)

    def _on_vehicle_report(self, message: str, is_error: bool) -> None:
        if is_error:
            # One line on the log and on planner_status.
            self.refuse(SOURCE_VEHICLE_LINK, message)
        else:
            self.get_logger().info(message)
        self.diagnostics.update()

    # Planning.

    def submit(self, reason: str, in_flight: InFlight | None = None) -> None:
        """Plan the whole mission (or, ``in_flight``, its rest): parameters, measured wind."""
        config = self.vehicle.wind.config(self.config)
        output = config.node
        mission = MissionRequest(
            config.scenario, config.settings, config.vehicle, vehicle_aware=output.vehicle_aware,
            firmware=output.mission_firmware, end=output.mission_end, home=output.home,
            items=bool(output.mission_file or output.mavlink_url), in_flight=in_flight)
        self.stats.requests_made += 1
        if self._worker.submit(PlanRequest(mission, output, self.now_ns(), reason)):
            self.get_logger().debug(f'{reason}: replaces a request still waiting')

    def _deliver(self, outcomes: list[PlanOutcome]) -> None:
        """Executor thread: publish and log every outcome the worker handed back."""
        for outcome in outcomes:
            self.stats.plans_run += 1
            request = outcome.request
            if outcome.cancelled:
                self.stats.plans_cancelled += 1
                self.get_logger().info(f'plan for {request.reason} given up for a newer request')
            elif outcome.plan is None and request.reason == BATTERY:
                self.vehicle.battery.replan_failed(outcome.error)
            elif outcome.plan is None:
                self.refuse(request.reason, f'planning failed ({request.reason}); the last '
                                            f'good plan stays published: {outcome.error}',
                            nodes=nodes_text(request.scenario.ground_nodes_m),
                            stamp_ns=request.start_ns)
            elif self.flight.take(outcome):
                self._publish(outcome)

    def _publish(self, outcome: PlanOutcome) -> None:
        self.current_plan = outcome
        line = summary_line(outcome.result, node_battery(outcome.request.output))
        if outcome.receding is not None:
            line += (f'; rest of the mission after {outcome.receding.flown.num_slots} '
                     f'slots, whole mission min throughput {outcome.min_throughput:.4g} bit/s')
        if outcome.mission_path is not None:
            line += f'; mission written to {outcome.mission_path}'
        # Logged first, so that whoever receives the plan can already read its line.
        self.get_logger().info(line)
        self.diagnostics.planned(outcome)
        self._publisher.publish(outcome)
        self.stats.plans_published += 1
        if self.vehicle.linked:
            self.vehicle.fly(outcome, self.config.vehicle)
        if outcome.mission_error:
            self.report_error(f'mission export failed, the plan is kept: '
                              f'{outcome.mission_error}')

    # Errors and clocks.

    def refuse(self, request: str, message: str, *, nodes: str | None = None,
               stamp_ns: int | None = None) -> None:
        """Log an error and say on planner_status and /diagnostics that ``request`` was
        refused and why."""
        self.report_error(message)
        self._publisher.refused(self.now_ns() if stamp_ns is None else stamp_ns, request,
                                message, nodes=nodes)
        self.diagnostics.refused(request, message, nodes=nodes)

    def report_error(self, message: str) -> None:
        self.stats.error_count += 1
        self.stats.last_error = message
        self.get_logger().error(message)

    def now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    def clock_s(self) -> float:
        """Now on the mission clock's time base, seconds: the vehicle's time of its latest
        position with a link (0 before any), the node's clock without."""
        if self.vehicle.linked:
            return self.vehicle.time_s if self.vehicle.time_s is not None else 0.0
        return self.now_ns() / 1e9

    def destroy_node(self) -> None:
        """Stop the workers (a plan in progress is abandoned) and the links, then destroy."""
        self._worker.stop()
        self.vehicle.stop()
        self.mission_folder.close()
        super().destroy_node()


#: What rclpy raises when its arguments cannot be parsed (rclpy exports no name for it).
RCLError = rclpy_implementation.RCLError


def main(args: list[str] | None = None) -> int:
    """Run the node until Ctrl-C or shutdown; returns the exit status (0, or 2 for invalid
    parameters). Once it is stopping, further Ctrl-C are ignored so that the shutdown (the
    running plan gives up at its next step) is never cut short by a traceback."""
    try:
        rclpy.init(args=args)
    except RCLError as exc:
        # The ROS arguments themselves: a params file that cannot be read or parsed, a
        # malformed -p or remapping.
        print(f'{NODE_NAME}: invalid ROS arguments: {exc}', file=sys.stderr)
        return 2
    node = None
    status = 0
    try:
        node = PlannerNode()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (PlannerError, InvalidParameterTypeException, InvalidParameterValueException) as exc:
        print(f'{NODE_NAME}: invalid parameters: {exc}', file=sys.stderr)
        status = 2
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
        # rclpy.shutdown puts back the handler it found; keep ignoring until the process ends.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    return status


if __name__ == '__main__':
    sys.exit(main())
