"""The ROS 2 node ``uav_comm_planner``: parameters and topics in, plans out.

An adapter over :func:`uav_comm_planner.plan`: ROS parameters become the settings
dataclasses (:mod:`uav_comm_planner.ros_params`), messages become arrays and results become
messages (:mod:`uav_comm_planner.ros_messages`). Planning runs on one worker thread; a request
made while a plan runs replaces any request still waiting, so the newest input wins and the
executor's callbacks stay responsive. Results come back to the executor through a guard
condition, where they are published and logged.

Replanning:

- a ``ground_nodes`` message, an accepted parameter change or ``~/replan`` plans the whole
  mission from ``start_m`` and restarts the mission clock. A ``ground_nodes`` message goes
  through the ``ground_nodes`` parameter, so it is checked like any parameter change and the
  parameter always holds the node set in use;
- a ``uav_pose`` message plans the rest of the mission from the UAV's position: the waypoints
  whose planned time has passed (time since the mission clock started, in whole slots) are
  dropped and the remaining ones, with the same slot length, lead to ``goal_m``. It is an
  error when no slot remains or the goal is out of reach from the pose.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
import math
from pathlib import Path as FilePath
import sys
import threading
from typing import Callable, Generic, Sequence, TypeVar

from geometry_msgs.msg import PoseArray, PoseStamped
from nav_msgs.msg import Path
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.exceptions import InvalidParameterValueException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from uav_comm_planner.errors import InfeasibleHorizonError, PlannerError
from uav_comm_planner.mission import export_mission
from uav_comm_planner.optimizer import plan, PlanResult
from uav_comm_planner.ros_messages import (ground_nodes_of, marker_array, path_message,
                                           power_message)
from uav_comm_planner.ros_params import (config_from_parameters, flat_pairs, NodeSettings,
                                         parameter_specs, PlannerConfig)
from uav_comm_planner.scenario import Scenario, SolverSettings

NODE_NAME = 'uav_comm_planner'

TOPIC_GROUND_NODES = 'ground_nodes'
TOPIC_UAV_POSE = 'uav_pose'
TOPIC_PATH = 'planned_path'
TOPIC_POWER = 'power_schedule'
TOPIC_MIN_THROUGHPUT = 'min_throughput'
TOPIC_MARKERS = 'plan_markers'
SERVICE_REPLAN = '~/replan'
SERVICE_EXPORT_MISSION = '~/export_mission'

#: Outputs keep the latest plan for subscribers that join later.
OUTPUT_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Volatile so that both volatile and transient-local publishers can send node sets.
GROUND_NODES_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                              durability=DurabilityPolicy.VOLATILE)
#: Best effort accepts pose streams of either reliability; only the latest pose matters.
UAV_POSE_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT,
                          durability=DurabilityPolicy.VOLATILE)

#: How long shutting down waits for a plan in progress before leaving it to its daemon thread.
WORKER_STOP_TIMEOUT_S = 5.0

Planner = Callable[[Scenario, SolverSettings], PlanResult]
Request = TypeVar('Request')


class LatestOnlyWorker(Generic[Request]):
    """Runs ``job`` on one thread, one request at a time; newer requests replace waiting ones.

    Nothing queues up: at most one request waits while a job runs, and it is the newest.
    ``job`` must not raise.
    """

    def __init__(self, job: Callable[[Request], None], *, name: str) -> None:
        self._job = job
        self._condition = threading.Condition()
        self._waiting: Request | None = None
        self._stopping = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def submit(self, request: Request) -> bool:
        """Queue ``request`` in place of any waiting one; True if one was replaced."""
        with self._condition:
            replaced = self._waiting is not None
            self._waiting = request
            self._condition.notify()
        return replaced

    def stop(self, timeout_s: float = WORKER_STOP_TIMEOUT_S) -> None:
        """Drop any waiting request and wait up to ``timeout_s`` for the running job."""
        with self._condition:
            self._stopping = True
            self._waiting = None
            self._condition.notify()
        self._thread.join(timeout_s)

    def _next(self) -> Request | None:
        with self._condition:
            while self._waiting is None and not self._stopping:
                self._condition.wait()
            request, self._waiting = self._waiting, None
            return None if self._stopping else request

    def _run(self) -> None:
        while (request := self._next()) is not None:
            self._job(request)


@dataclass(frozen=True)
class PlanRequest:
    """What to plan, the settings to publish it with, and when the planned flight starts."""

    scenario: Scenario
    settings: SolverSettings
    output: NodeSettings
    start_ns: int
    reason: str


@dataclass(frozen=True)
class PlanOutcome:
    """A finished request: its plan, or the reason it failed, and the mission file written."""

    request: PlanRequest
    result: PlanResult | None = None
    error: str = ''
    mission_path: FilePath | None = None
    mission_error: str = ''


def remaining_scenario(scenario: Scenario, position: tuple[float, float],
                       elapsed_s: float) -> Scenario:
    """The rest of ``scenario`` flown from ``position`` after ``elapsed_s`` seconds.

    Keeps the slot length; drops the slots whose waypoint time has passed. Raises
    :class:`~uav_comm_planner.errors.InfeasibleHorizonError` when none remains or the goal
    is out of reach from ``position``.
    """
    passed = max(0, math.floor(elapsed_s / scenario.slot_s))
    remaining = scenario.num_slots - passed
    if remaining < 1:
        raise InfeasibleHorizonError(
            f'the mission horizon is over ({elapsed_s:.1f} s since the mission started, '
            f'{scenario.num_slots} slots of {scenario.slot_s:g} s): call ~/replan to start '
            f'a new mission')
    return scenario.replace(start_m=position, num_slots=remaining,
                            horizon_s=remaining * scenario.slot_s)


def write_mission(result: PlanResult, output: NodeSettings) -> FilePath:
    """Write ``result`` to ``output.mission_file``; raises MissionExportError on failure."""
    return export_mission(result, output.mission_file, output.home, end=output.mission_end,
                          firmware=output.mission_firmware)


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


class PlannerNode(Node):
    """Plans the UAV's flight for the ground nodes it hears of and publishes the plan.

    ``planner`` is the planning function (the core's :func:`~uav_comm_planner.plan`);
    other keywords go to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``...).
    Raises :class:`~uav_comm_planner.errors.PlannerError` when the initial parameters do not
    make a valid scenario.

    For tests and introspection: ``requests_made`` counts plan requests, ``plans_run``
    finished plan attempts, ``plans_published`` the successful ones; ``error_count`` and
    ``last_error`` follow every error logged.
    """

    def __init__(self, *, planner: Planner = plan, **node_options) -> None:
        super().__init__(NODE_NAME, **node_options)
        self._planner = planner
        self._parameter_names = self._declare_parameters()
        self._config: PlannerConfig = config_from_parameters(self._parameter_values())
        self.add_on_set_parameters_callback(self._check_parameters)
        self.add_post_set_parameters_callback(self._parameters_changed)

        self.requests_made = 0
        self.plans_run = 0
        self.plans_published = 0
        self.error_count = 0
        self.last_error = ''
        self.current_plan: PlanOutcome | None = None
        self._mission_start_ns = self._now_ns()

        self._outcomes: deque[PlanOutcome] = deque()
        self._outcomes_lock = threading.Lock()
        self._closing = False
        self._delivery = self.create_guard_condition(self._deliver)

        self._path_pub = self.create_publisher(Path, TOPIC_PATH, OUTPUT_QOS)
        self._power_pub = self.create_publisher(Float64MultiArray, TOPIC_POWER, OUTPUT_QOS)
        self._throughput_pub = self.create_publisher(Float64, TOPIC_MIN_THROUGHPUT, OUTPUT_QOS)
        self._markers_pub = self.create_publisher(MarkerArray, TOPIC_MARKERS, OUTPUT_QOS)
        self.create_subscription(PoseArray, TOPIC_GROUND_NODES, self._on_ground_nodes,
                                 GROUND_NODES_QOS)
        self.create_subscription(PoseStamped, TOPIC_UAV_POSE, self._on_uav_pose, UAV_POSE_QOS)
        self.create_service(Trigger, SERVICE_REPLAN, self._on_replan)
        self.create_service(Trigger, SERVICE_EXPORT_MISSION, self._on_export_mission)

        self._worker: LatestOnlyWorker[PlanRequest] = LatestOnlyWorker(
            self._plan_and_export, name='uav_comm_planner.worker')
        self.request_plan('start')

    # Parameters.

    def _declare_parameters(self) -> tuple[str, ...]:
        specs = parameter_specs()
        self.declare_parameters('', [(spec.name, spec.default, spec.descriptor())
                                     for spec in specs])
        return tuple(spec.name for spec in specs)

    def _parameter_values(self, changes: Sequence[Parameter] = ()) -> dict[str, object]:
        values = {name: self.get_parameter(name).value for name in self._parameter_names}
        values.update({p.name: p.value for p in changes if p.name in self._parameter_names})
        return values

    def _check_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        """Refuse a change that does not make a valid configuration, saying why."""
        try:
            config_from_parameters(self._parameter_values(changes))
        except PlannerError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _parameters_changed(self, changes: list[Parameter]) -> None:
        names = [p.name for p in changes if p.name in self._parameter_names]
        if names:
            self._config = config_from_parameters(self._parameter_values())
            self.request_plan('parameters ' + ', '.join(names))

    # Inputs.

    def _frame_accepted(self, frame_id: str, topic: str) -> bool:
        expected = self._config.node.frame_id
        if frame_id and frame_id != expected:
            self._report_error(f'{topic} refused: its frame is {frame_id!r} but the planner '
                               f'works in {expected!r} (parameter frame_id)')
            return False
        return True

    def _on_ground_nodes(self, message: PoseArray) -> None:
        """Take the message's positions as the new node set, through the parameter."""
        if not self._frame_accepted(message.header.frame_id, TOPIC_GROUND_NODES):
            return
        nodes = Parameter('ground_nodes', Parameter.Type.DOUBLE_ARRAY,
                          flat_pairs(ground_nodes_of(message)))
        result = self.set_parameters([nodes])[0]
        if not result.successful:
            self._report_error(f'{TOPIC_GROUND_NODES} refused: {result.reason}')

    def _on_uav_pose(self, message: PoseStamped) -> None:
        """Replan the rest of the mission from the UAV's current position."""
        if not self._frame_accepted(message.header.frame_id, TOPIC_UAV_POSE):
            return
        now = self._now_ns()
        position = (message.pose.position.x, message.pose.position.y)
        elapsed_s = (now - self._mission_start_ns) / 1e9
        try:
            scenario = remaining_scenario(self._config.scenario, position, elapsed_s)
        except PlannerError as exc:
            self._report_error(f'{TOPIC_UAV_POSE} refused: {exc}')
            return
        self._submit(scenario, now, TOPIC_UAV_POSE)

    def _on_replan(self, _request: Trigger.Request,
                   response: Trigger.Response) -> Trigger.Response:
        self.request_plan(SERVICE_REPLAN)
        response.success = True
        response.message = (f'planning the mission from start_m; the plan follows on '
                            f'{TOPIC_PATH}')
        return response

    def _on_export_mission(self, _request: Trigger.Request,
                           response: Trigger.Response) -> Trigger.Response:
        output = self._config.node
        response.success = False
        if not output.mission_file:
            response.message = 'parameter mission_file is empty: set a .waypoints or .plan path'
        elif self.current_plan is None:
            response.message = 'no plan yet'
        else:
            try:
                written = write_mission(self.current_plan.result, output)
            except PlannerError as exc:
                self._report_error(f'mission export failed: {exc}')
                response.message = str(exc)
            else:
                response.success = True
                response.message = f'mission written to {written}'
        return response

    # Planning.

    def request_plan(self, reason: str) -> None:
        """Plan the whole mission from ``start_m`` with the current parameters."""
        self._mission_start_ns = self._now_ns()
        self._submit(self._config.scenario, self._mission_start_ns, reason)

    def _submit(self, scenario: Scenario, start_ns: int, reason: str) -> None:
        config = self._config
        request = PlanRequest(scenario, config.settings, config.node, start_ns, reason)
        self.requests_made += 1
        if self._worker.submit(request):
            self.get_logger().debug(f'{reason}: replaces a request still waiting')

    def _plan_and_export(self, request: PlanRequest) -> None:
        """Worker thread: plan, write the mission if asked, hand the outcome back."""
        outcome = self._attempt(request)
        with self._outcomes_lock:
            if self._closing:
                return
            self._outcomes.append(outcome)
            self._delivery.trigger()

    def _attempt(self, request: PlanRequest) -> PlanOutcome:
        try:
            result = self._planner(request.scenario, request.settings)
        except PlannerError as exc:
            return PlanOutcome(request, error=str(exc))
        except Exception as exc:  # noqa: B902 - a failed plan must not end the worker thread
            return PlanOutcome(request, error=f'unexpected {type(exc).__name__}: {exc}')
        if not request.output.mission_file:
            return PlanOutcome(request, result)
        try:
            return PlanOutcome(request, result, mission_path=write_mission(result,
                                                                           request.output))
        except PlannerError as exc:
            return PlanOutcome(request, result, mission_error=str(exc))

    def _deliver(self) -> None:
        """Executor thread: publish and log every outcome the worker handed back."""
        with self._outcomes_lock:
            outcomes = list(self._outcomes)
            self._outcomes.clear()
        for outcome in outcomes:
            self.plans_run += 1
            if outcome.result is None:
                self._report_error(f'planning failed ({outcome.request.reason}); the last '
                                   f'good plan stays published: {outcome.error}')
                continue
            self.current_plan = outcome
            line = summary_line(outcome.result)
            if outcome.mission_path is not None:
                line += f'; mission written to {outcome.mission_path}'
            # Logged first, so that whoever receives the plan can already read its line.
            self.get_logger().info(line)
            self._publish(outcome)
            self.plans_published += 1
            if outcome.mission_error:
                self._report_error(f'mission export failed, the plan is kept: '
                                   f'{outcome.mission_error}')

    def _publish(self, outcome: PlanOutcome) -> None:
        result, request = outcome.result, outcome.request
        frame_id = request.output.frame_id
        self._path_pub.publish(path_message(result, frame_id, request.start_ns))
        self._power_pub.publish(power_message(result))
        self._throughput_pub.publish(Float64(data=float(result.min_throughput)))
        self._markers_pub.publish(marker_array(result, frame_id, request.start_ns))

    def _report_error(self, message: str) -> None:
        self.error_count += 1
        self.last_error = message
        self.get_logger().error(message)

    def _now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    def destroy_node(self) -> None:
        """Stop the worker (a plan in progress is abandoned), then destroy the node."""
        with self._outcomes_lock:
            self._closing = True
        self._worker.stop()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run uav_comm_planner planner``; returns the exit status."""
    rclpy.init(args=args)
    node = None
    status = 0
    try:
        node = PlannerNode()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (PlannerError, InvalidParameterValueException) as exc:
        print(f'{NODE_NAME}: invalid parameters: {exc}', file=sys.stderr)
        status = 2
    finally:
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return status


if __name__ == '__main__':
    sys.exit(main())
