"""The ROS 2 node ``uav_comm_planner``: parameters and topics in, plans out.

An adapter over :func:`uav_comm_planner.plan`: ROS parameters become the settings
dataclasses (:mod:`uav_comm_planner.ros.params`), messages become arrays and results become
messages (:mod:`uav_comm_planner.ros.messages`). Planning runs on one worker thread; a request
made while a plan runs replaces any request still waiting, so the newest input wins and the
executor's callbacks stay responsive. Results come back to the executor through a guard
condition, where they are published and logged.

Replanning:

- a ``ground_nodes`` message, an accepted parameter change or ``~/replan`` plans the whole
  mission from ``start_m`` and restarts the mission clock. A ``ground_nodes`` message goes
  through the ``ground_nodes`` parameter, so it is checked like any parameter change and the
  parameter always holds the node set in use;
- a request that comes while a plan runs also asks the running plan to give up at its next
  step (the core's ``plan(should_stop=...)``), so the newest request is planned at once;
- a ``uav_pose`` message plans the rest of the mission from the UAV's position: the waypoints
  whose planned time has passed (time since the mission clock started, in whole slots) are
  dropped and the remaining ones, with the same slot length, lead to ``goal_m``. It is an
  error when no slot remains or the goal is out of reach from the pose.
"""

from __future__ import annotations

from collections import deque
import signal
import sys
import threading

from geometry_msgs.msg import PoseArray, PoseStamped
import rclpy
from rclpy.exceptions import InvalidParameterValueException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_srvs.srv import Trigger

from uav_comm_planner.core.optimizer import plan
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.errors import PlannerError
from uav_comm_planner.ros.binding import ParameterBinding
from uav_comm_planner.ros.messages import ground_nodes_of
from uav_comm_planner.ros.params import flat_pairs, PlannerConfig
from uav_comm_planner.ros.publishing import PlanPublisher, summary_line, TOPIC_PATH
from uav_comm_planner.ros.worker import (accepts_should_stop, attempt, LatestOnlyWorker,
                                         Planner, PlanOutcome, PlanRequest, remaining_scenario,
                                         write_mission)

NODE_NAME = 'uav_comm_planner'

TOPIC_GROUND_NODES = 'ground_nodes'
TOPIC_UAV_POSE = 'uav_pose'
SERVICE_REPLAN = '~/replan'
SERVICE_EXPORT_MISSION = '~/export_mission'

#: Volatile so that both volatile and transient-local publishers can send node sets.
GROUND_NODES_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                              durability=DurabilityPolicy.VOLATILE)
#: Service requests are queued, not dropped, up to this many in flight (the default is 10).
SERVICE_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
#: Best effort accepts pose streams of either reliability; only the latest pose matters.
UAV_POSE_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT,
                          durability=DurabilityPolicy.VOLATILE)


class PlannerNode(Node):
    """Plans the UAV's flight for the ground nodes it hears of and publishes the plan.

    ``planner`` is the planning function (the core's :func:`~uav_comm_planner.plan`);
    other keywords go to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``...).
    Raises :class:`~uav_comm_planner.errors.PlannerError` when the initial parameters do not
    make a valid scenario.

    For tests and introspection: ``requests_made`` counts plan requests, ``plans_run``
    finished plan attempts, ``plans_published`` the successful ones, ``plans_cancelled``
    those given up for a newer request; ``error_count`` and
    ``last_error`` follow every error logged.
    """

    def __init__(self, *, planner: Planner = plan, **node_options) -> None:
        super().__init__(NODE_NAME, **node_options)
        self._planner = planner
        self._binding = ParameterBinding(
            self, lambda names: self.request_plan('parameters ' + ', '.join(names)))

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

        self._publisher = PlanPublisher(self)
        self.create_subscription(PoseArray, TOPIC_GROUND_NODES, self._on_ground_nodes,
                                 GROUND_NODES_QOS)
        self.create_subscription(PoseStamped, TOPIC_UAV_POSE, self._on_uav_pose, UAV_POSE_QOS)
        self.create_service(Trigger, SERVICE_REPLAN, self._on_replan, qos_profile=SERVICE_QOS)
        self.create_service(Trigger, SERVICE_EXPORT_MISSION, self._on_export_mission,
                            qos_profile=SERVICE_QOS)

        self._preemptible = accepts_should_stop(planner)
        self.plans_cancelled = 0
        self._worker: LatestOnlyWorker[PlanRequest] = LatestOnlyWorker(
            self._plan_and_export, name='uav_comm_planner.worker')
        self.request_plan('start')

    @property
    def _config(self) -> PlannerConfig:
        return self._binding.config

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
        limit = self._config.settings.max_nodes
        if len(message.poses) > limit:
            # Refused before any conversion: the cost of a message must not grow unchecked.
            self._report_error(f'{TOPIC_GROUND_NODES} refused: too many ground nodes: '
                               f'{len(message.poses)} given, the limit max_nodes is {limit}')
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
            response.message = ('parameter mission_file is empty: set a .waypoints or .plan '
                                'file name')
        elif self.current_plan is None:
            response.message = 'no plan yet'
        else:
            try:
                written = write_mission(self.current_plan, output)
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
        request = PlanRequest(scenario, config.settings, config.node, start_ns, reason,
                              config.vehicle)
        self.requests_made += 1
        if self._worker.submit(request):
            self.get_logger().debug(f'{reason}: replaces a request still waiting')

    def _plan_and_export(self, request: PlanRequest) -> None:
        """Worker thread: plan, write the mission if asked, hand the outcome back."""
        outcome = attempt(self._planner, request,
                          should_stop=self._worker.superseded if self._preemptible else None)
        with self._outcomes_lock:
            if self._closing:
                return
            self._outcomes.append(outcome)
            self._delivery.trigger()

    def _deliver(self) -> None:
        """Executor thread: publish and log every outcome the worker handed back."""
        with self._outcomes_lock:
            outcomes = list(self._outcomes)
            self._outcomes.clear()
        for outcome in outcomes:
            self.plans_run += 1
            if outcome.cancelled:
                self.plans_cancelled += 1
                self.get_logger().info(f'plan for {outcome.request.reason} given up for a '
                                       f'newer request')
                continue
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
            self._publisher.publish(outcome)
            self.plans_published += 1
            if outcome.mission_error:
                self._report_error(f'mission export failed, the plan is kept: '
                                   f'{outcome.mission_error}')

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
    """Run the node until Ctrl-C or shutdown; returns the exit status (0, or 2 for invalid
    parameters). Once it is stopping, further Ctrl-C are ignored so that the shutdown (the
    running plan gives up at its next step) is never cut short by a traceback."""
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
