"""The ROS 2 node ``uav_comm_planner``: parameters and topics in, plans out.

An adapter over :func:`uav_comm_planner.plan`: ROS parameters become the settings
dataclasses (:mod:`uav_comm_planner.ros.params`), messages become arrays and results become
messages (:mod:`uav_comm_planner.ros.messages`). Planning runs on one worker thread; a request
made while a plan runs replaces any request still waiting, so the newest input wins and the
executor's callbacks stay responsive. Results come back to the executor through a guard
condition, where they are published and logged.

The mission clock (:mod:`uav_comm_planner.ros.progress`) starts when the UAV reaches the
plan's q0 (a ``uav_pose`` or, with ``mavlink_url``, the vehicle's telemetry within
START_RADIUS_M of it) or on ``~/start``; never at node start nor on a parameter change. A
replan of the mission in flight is in force when the vehicle reaches its q0 (with a link,
after its upload) or, without a link, as soon as it is published.

Replanning:

- before the mission clock runs (and after the mission's last slot), a ``ground_nodes``
  message or an accepted parameter change plans the whole mission from ``start_m``;
  ``~/replan`` always does, and ends the mission in flight. A ``ground_nodes`` message goes
  through the ``ground_nodes`` parameter, so it is checked like any parameter change and the
  parameter always holds the node set in use;
- a request that comes while a plan runs also asks the running plan to give up at its next
  step (the core's ``plan(should_stop=...)``), so the newest request is planned at once;
- while the clock runs, the same inputs replan the rest of the mission from the UAV's
  position by the receding horizon (:mod:`uav_comm_planner.core.receding`): the slots begun so
  far keep their power and the data they delivered (at the flown positions where a pose or
  telemetry has them, else as planned), the rest gets what is left of the budget;
- a ``uav_pose`` (or the vehicle's telemetry) replans the same way, only when the UAV is off
  the plan by more than ``replan_distance_m`` or ``replan_delay_s``, at most once every
  ``replan_interval_s``, and not when less than ``replan_interval_s`` of the mission is left;
- output-only parameters (:data:`~uav_comm_planner.ros.params.OUTPUT_ONLY`: mission file,
  firmware, end, frame, home, link and replan settings) never replan.

Every request ends in one ``planner_status`` message: planned (with the plan stamp that
every output of the plan carries) or refused, with the reason.
"""

from __future__ import annotations

from collections import deque
import math
import signal
import sys
import threading

from geometry_msgs.msg import PoseArray, PoseStamped
import numpy as np
import rclpy
from rclpy.exceptions import InvalidParameterValueException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_srvs.srv import Trigger

from uav_comm_planner.core.optimizer import plan
from uav_comm_planner.core.receding import rest_of_mission
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.errors import PlannerError
from uav_comm_planner.ros.binding import ParameterBinding
from uav_comm_planner.ros.messages import ground_nodes_of, nodes_text
from uav_comm_planner.ros.params import flat_pairs, OUTPUT_ONLY, PlannerConfig
from uav_comm_planner.ros.progress import MissionProgress, off_plan, planned_position, PoseTrack
from uav_comm_planner.ros.publishing import PlanPublisher, summary_line, TOPIC_PATH
from uav_comm_planner.ros.worker import (accepts_should_stop, attempt, LatestOnlyWorker,
                                         Planner, PlanOutcome, PlanRequest, RecedingRequest,
                                         write_mission)
from uav_comm_planner.vehicle.mavlink.items import build_mission_items, Q0_SEQ
from uav_comm_planner.vehicle.mavlink.telemetry import (Event, LinkEvent,
                                                        MissionProgressReport, Position,
                                                        VehicleBridge)

NODE_NAME = 'uav_comm_planner'

TOPIC_GROUND_NODES = 'ground_nodes'
TOPIC_UAV_POSE = 'uav_pose'
TOPIC_VEHICLE_POSE = 'vehicle_pose'
SERVICE_REPLAN = '~/replan'
SERVICE_START = '~/start'
SERVICE_EXPORT_MISSION = '~/export_mission'
#: The UAV is at q0, and the mission clock starts, within this distance of it (metres);
#: ArduCopter counts a waypoint reached within WPNAV_RADIUS, 2 m by default.
START_RADIUS_M = 2.5
#: Name of the telemetry as a position source.
SOURCE_VEHICLE = 'vehicle'

#: Volatile so that both volatile and transient-local publishers can send node sets.
GROUND_NODES_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                              durability=DurabilityPolicy.VOLATILE)
#: Service requests are queued, not dropped, up to this many in flight (the default is 10).
SERVICE_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
#: Best effort accepts pose streams of either reliability; only the latest pose matters.
UAV_POSE_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT,
                          durability=DurabilityPolicy.VOLATILE)
#: Reliable, so that subscribers of either reliability hear the vehicle's pose.
VEHICLE_POSE_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                              durability=DurabilityPolicy.VOLATILE)


class PlannerNode(Node):
    """Plans the UAV's flight for the ground nodes it hears of and publishes the plan.

    ``planner`` is the planning function (the core's :func:`~uav_comm_planner.plan`);
    other keywords go to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``...).
    Raises :class:`~uav_comm_planner.errors.PlannerError` when the initial parameters do not
    make a valid scenario.

    For tests and introspection: ``requests_made`` counts plan requests, ``plans_run``
    finished plan attempts, ``plans_published`` the successful ones, ``plans_cancelled``
    those given up for a newer request; ``error_count`` and ``last_error`` follow every error
    logged; ``progress`` is the mission in flight.
    """

    def __init__(self, *, planner: Planner = plan, **node_options) -> None:
        super().__init__(NODE_NAME, **node_options)
        self._planner = planner
        self._refusing_nodes: str | None = None
        self._binding = ParameterBinding(self, self._on_parameters,
                                         on_refused=self._on_parameters_refused)

        self.requests_made = 0
        self.plans_run = 0
        self.plans_published = 0
        self.error_count = 0
        self.last_error = ''
        self.current_plan: PlanOutcome | None = None
        self.progress = MissionProgress()
        self.track = PoseTrack()
        self._last_pose_replan_s = -math.inf

        self._outcomes: deque[PlanOutcome] = deque()
        self._outcomes_lock = threading.Lock()
        self._closing = False
        self._delivery = self.create_guard_condition(self._deliver)

        self._vehicle: VehicleBridge | None = None
        self._vehicle_events: deque[Event] = deque(maxlen=10_000)
        self._vehicle_lock = threading.Lock()
        self._vehicle_guard = self.create_guard_condition(self._drain_vehicle)
        self._vehicle_time_s: float | None = None
        self._upload_pending: int | None = None
        self.uploads_verified = 0
        self.mission_item: int | None = None
        self._vehicle_pose = self.create_publisher(PoseStamped, TOPIC_VEHICLE_POSE,
                                                   VEHICLE_POSE_QOS)

        self._publisher = PlanPublisher(self)
        self.create_subscription(PoseArray, TOPIC_GROUND_NODES, self._on_ground_nodes,
                                 GROUND_NODES_QOS)
        self.create_subscription(PoseStamped, TOPIC_UAV_POSE, self._on_uav_pose, UAV_POSE_QOS)
        self.create_service(Trigger, SERVICE_REPLAN, self._on_replan, qos_profile=SERVICE_QOS)
        self.create_service(Trigger, SERVICE_START, self._on_start, qos_profile=SERVICE_QOS)
        self.create_service(Trigger, SERVICE_EXPORT_MISSION, self._on_export_mission,
                            qos_profile=SERVICE_QOS)

        self._preemptible = accepts_should_stop(planner)
        self.plans_cancelled = 0
        self._worker: LatestOnlyWorker[PlanRequest] = LatestOnlyWorker(
            self._plan_and_export, name='uav_comm_planner.worker')
        self._connect_vehicle()
        self.request_plan('start')

    @property
    def _config(self) -> PlannerConfig:
        return self._binding.config

    # Inputs.
    def _frame_accepted(self, frame_id: str, topic: str, nodes: str | None = None) -> bool:
        expected = self._config.node.frame_id
        if frame_id and frame_id != expected:
            self._refuse(topic, f'{topic} refused: its frame is {frame_id!r} but the planner '
                                f'works in {expected!r} (parameter frame_id)', nodes=nodes)
            return False
        return True

    def _on_ground_nodes(self, message: PoseArray) -> None:
        """Take the message's positions as the new node set, through the parameter."""
        limit = self._config.settings.max_nodes
        if len(message.poses) > limit:
            # Refused before any conversion: the cost of a message must not grow unchecked.
            self._refuse(TOPIC_GROUND_NODES, f'{TOPIC_GROUND_NODES} refused: too many ground '
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
            self._refuse(TOPIC_GROUND_NODES, f'{TOPIC_GROUND_NODES} refused: {reason}',
                         nodes=self._refusing_nodes)
        else:
            self._refuse('parameters ' + ', '.join(names),
                         f'parameter change refused ({", ".join(names)}): {reason}')

    def _on_parameters(self, names: list[str]) -> None:
        """An accepted change: replan unless only output parameters changed."""
        planning = [name for name in names if name not in OUTPUT_ONLY
                    # A plan for the vehicle is timed for its firmware (hold resolution).
                    or (name == 'mission_firmware' and self._config.node.vehicle_aware)]
        if {'mavlink_url', 'home_latitude_deg', 'home_longitude_deg',
                'home_altitude_m'} & set(names):
            self._connect_vehicle()
        if not planning:
            self.get_logger().info(
                f'parameters {", ".join(names)} set; they apply to the next plan (no replan)')
            return
        reason = (TOPIC_GROUND_NODES if self._refusing_nodes is not None
                  else 'parameters ' + ', '.join(planning))
        self.request_update(reason)

    def _on_uav_pose(self, message: PoseStamped) -> None:
        """A position of the UAV: starts the clock at q0, replans when off the plan."""
        if not self._frame_accepted(message.header.frame_id, TOPIC_UAV_POSE):
            return
        self.on_position(self._clock_s(), message.pose.position.x, message.pose.position.y,
                         source=TOPIC_UAV_POSE)

    def on_position(self, time_s: float, x_m: float, y_m: float, *, source: str,
                    height_m: float | None = None) -> None:
        """The UAV at (x, y) metres (``height_m`` above the ground, when known) at ``time_s``
        on the mission clock's time base."""
        if not (math.isfinite(x_m) and math.isfinite(y_m) and math.isfinite(time_s)):
            self._refuse(source, f'{source} refused: position ({x_m}, {y_m}) is not finite')
            return
        self.track.add(time_s, x_m, y_m)
        segment = self.progress.current
        if segment is None:
            return
        if segment.start_s is None:
            scenario = segment.result.scenario
            climb = 0.0 if height_m is None else height_m - scenario.altitude_m
            uploaded = self._vehicle is None or self._upload_pending is None
            if uploaded and math.hypot(math.dist(scenario.start_m, (x_m, y_m)),
                                       climb) <= START_RADIUS_M:
                self._start_clock(time_s, f'the UAV reached q0 ({source})')
            return
        if self.progress.over(time_s):
            return
        output = self._config.node
        elapsed = time_s - segment.start_s
        left_s = (self.progress.mission.num_slots - segment.first_slot
                  - segment.slots_begun(time_s)) * segment.result.scenario.slot_s
        if left_s < output.replan_interval_s:
            return              # too late in the mission for a replan to be flown
        reason = off_plan(segment.result, elapsed, (x_m, y_m),
                          distance_m=output.replan_distance_m, delay_s=output.replan_delay_s)
        if not reason or time_s - self._last_pose_replan_s < output.replan_interval_s:
            return
        self._last_pose_replan_s = time_s
        self.get_logger().info(f'{source}: the UAV is {reason}; replanning the rest')
        self._request_rest(source, time_s, (x_m, y_m))

    def _on_replan(self, _request: Trigger.Request,
                   response: Trigger.Response) -> Trigger.Response:
        self.request_plan(SERVICE_REPLAN)
        response.success = True
        response.message = (f'planning the mission from start_m; the plan follows on '
                            f'{TOPIC_PATH}; the mission clock starts at q0 or on '
                            f'{SERVICE_START}')
        return response

    def _on_start(self, _request: Trigger.Request,
                  response: Trigger.Response) -> Trigger.Response:
        response.success = False
        segment = self.progress.current
        if self._config.node.mavlink_url:
            response.message = ('the vehicle link starts the mission clock when the vehicle '
                                'reaches q0 (parameter mavlink_url is set)')
        elif segment is None:
            response.message = 'no plan yet'
        elif segment.start_s is not None:
            response.message = 'the mission clock is already running'
        else:
            self._start_clock(self._clock_s(), SERVICE_START)
            response.success = True
            response.message = 'mission clock started: the plan in force is flown from now'
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

    # The vehicle.

    def _connect_vehicle(self) -> None:
        """(Re)start the vehicle link for ``mavlink_url``; stop it when the URL is empty."""
        if self._vehicle is not None:
            self._vehicle.stop()
            self._vehicle = None
        output = self._config.node
        self._vehicle_time_s = None
        if output.mavlink_url:
            self._vehicle = VehicleBridge(output.mavlink_url, output.home, self._queue_event)
            self.get_logger().info(f'vehicle link: connecting to {output.mavlink_url}')

    def _queue_event(self, event: Event) -> None:
        """Link thread: hand an event to the executor."""
        with self._vehicle_lock:
            self._vehicle_events.append(event)
        self._vehicle_guard.trigger()

    def _drain_vehicle(self) -> None:
        """Executor thread: positions, mission progress and link events from the vehicle."""
        with self._vehicle_lock:
            events = list(self._vehicle_events)
            self._vehicle_events.clear()
        for event in events:
            if isinstance(event, Position):
                self._vehicle_time_s = event.time_s
                self._publish_vehicle_pose(event)
                self.on_position(event.time_s, event.east_m, event.north_m,
                                 source=SOURCE_VEHICLE, height_m=event.up_m)
            elif isinstance(event, MissionProgressReport):
                self.mission_item = event.seq
            elif isinstance(event, LinkEvent):
                self._on_link_event(event)

    def _on_link_event(self, event: LinkEvent) -> None:
        if event.kind == 'error':
            if event.tag is not None and event.tag == self._upload_pending:
                self._upload_pending = None
            self._report_error(event.message)
            return
        if event.kind == 'uploaded':
            self.uploads_verified += 1
            if event.tag == self._upload_pending:
                self._upload_pending = None
        self.get_logger().info(event.message)

    def _publish_vehicle_pose(self, event: Position) -> None:
        message = PoseStamped()
        message.header.frame_id = self._config.node.frame_id
        message.header.stamp = self.get_clock().now().to_msg()
        message.pose.position.x = event.east_m
        message.pose.position.y = event.north_m
        message.pose.position.z = event.up_m
        message.pose.orientation.w = 1.0
        self._vehicle_pose.publish(message)

    def _upload(self, outcome: PlanOutcome) -> None:
        """Put the plan on the vehicle; a plan made in flight is flown from its q0 item."""
        output = outcome.request.output
        try:
            items = build_mission_items(outcome.vehicle_plan or outcome.result, output.home,
                                        end=output.mission_end,
                                        firmware=output.mission_firmware,
                                        limits=outcome.request.vehicle)
        except PlannerError as exc:
            self._report_error(f'mission upload skipped, the plan cannot be flown: {exc}')
            return
        in_flight = outcome.request.receding is not None
        self._upload_pending = outcome.request.start_ns
        self._vehicle.upload(items, current_seq=Q0_SEQ if in_flight else None,
                             tag=outcome.request.start_ns)

    # The mission.

    def _start_clock(self, time_s: float, why: str) -> None:
        self.progress.start_clock(time_s)
        self.get_logger().info(f'mission clock started: {why}')

    def _mission_running(self, time_s: float) -> bool:
        """Whether a mission is in flight that a replan should continue."""
        mission = self.progress.mission
        scenario = self._config.scenario
        return (self.progress.started and not self.progress.over(time_s)
                and mission is not None and mission.num_slots == scenario.num_slots
                and mission.horizon_s == scenario.horizon_s)

    def request_update(self, reason: str) -> None:
        """New inputs: replan the rest of the mission in flight, else the whole mission."""
        now = self._clock_s()
        if self._mission_running(now):
            latest = self.track.latest
            segment = self.progress.current
            if latest is not None and now - latest[0] <= self._config.scenario.slot_s:
                position = (latest[1], latest[2])
            else:
                elapsed = now - segment.start_s if segment.start_s is not None else 0.0
                position = tuple(planned_position(segment.result, elapsed))
            self._request_rest(reason, now, position)
        else:
            self.request_plan(reason)

    def request_plan(self, reason: str) -> None:
        """Plan the whole mission from ``start_m`` with the current parameters; a mission in
        flight ends (its clock stops)."""
        self.progress = MissionProgress()
        self._submit(self._config.scenario, reason)

    def _request_rest(self, reason: str, time_s: float, position: tuple[float, float]) -> None:
        """Replan the rest of the mission in flight from ``position`` at ``time_s``."""
        mission = self._config.scenario
        segment = self.progress.current
        flown = self.progress.flown_slots(time_s, mission.ground_nodes_m, self.track)
        begun = segment.slots_begun(time_s) if segment.start_s is not None else 0
        try:
            rest_of_mission(mission, position, flown)
        except PlannerError as exc:
            self._refuse(reason, f'{reason} refused: {exc}',
                         nodes=nodes_text(mission.ground_nodes_m))
            return
        previous = np.asarray(segment.result.trajectory[begun:], dtype=float)
        rest = RecedingRequest(position_m=(float(position[0]), float(position[1])),
                               flown=flown, previous_q=previous, segment=segment,
                               slots_kept=begun)
        self._submit(mission, reason, rest)

    def _submit(self, scenario: Scenario, reason: str,
                receding: RecedingRequest | None = None) -> None:
        config = self._config
        request = PlanRequest(scenario, config.settings, config.node, self._now_ns(), reason,
                              config.vehicle, receding)
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
            request = outcome.request
            if outcome.result is None:
                self._refuse(request.reason, f'planning failed ({request.reason}); the last '
                                             f'good plan stays published: {outcome.error}',
                             nodes=nodes_text(request.scenario.ground_nodes_m),
                             stamp_ns=request.start_ns)
                continue
            if not self._take(outcome):
                continue
            self.current_plan = outcome
            line = summary_line(outcome.result)
            if outcome.receding is not None:
                line += (f'; rest of the mission after {outcome.receding.flown.num_slots} '
                         f'slots, whole mission min throughput {outcome.min_throughput:.4g} '
                         f'bit/s')
            if outcome.mission_path is not None:
                line += f'; mission written to {outcome.mission_path}'
            # Logged first, so that whoever receives the plan can already read its line.
            self.get_logger().info(line)
            self._publisher.publish(outcome)
            self.plans_published += 1
            if self._vehicle is not None:
                self._upload(outcome)
            if outcome.mission_error:
                self._report_error(f'mission export failed, the plan is kept: '
                                   f'{outcome.mission_error}')

    def _take(self, outcome: PlanOutcome) -> bool:
        """Make ``outcome`` the plan in force of the mission; False if it came too late."""
        rest = outcome.request.receding
        if rest is None:
            self.progress.begin(outcome.request.scenario, outcome.result)
            return True
        segments = self.progress.segments
        if rest.segment not in segments or any(
                later.start_s is not None
                for later in segments[segments.index(rest.segment) + 1:]):
            self.get_logger().info(f'{outcome.request.reason}: a newer plan is flown already; '
                                   'this replan is dropped')
            return False
        del segments[segments.index(rest.segment) + 1:]
        rest.segment.slots_kept = rest.slots_kept
        self.progress.follow_with(outcome.request.scenario, outcome.result,
                                  rest.segment.first_slot + rest.slots_kept)
        if not outcome.request.output.mavlink_url:
            # The UAV was at the new q0 when the replan was asked; without a link to say when
            # it flies the new plan, the plan is in force from now.
            self._start_clock(self._clock_s(), 'the replan is in force')
        return True

    def _refuse(self, request: str, message: str, *, nodes: str | None = None,
                stamp_ns: int | None = None) -> None:
        """Log an error and say on planner_status that ``request`` was refused and why."""
        self._report_error(message)
        self._publisher.refused(self._now_ns() if stamp_ns is None else stamp_ns, request,
                                message, nodes=nodes)

    def _report_error(self, message: str) -> None:
        self.error_count += 1
        self.last_error = message
        self.get_logger().error(message)

    def _now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    def _clock_s(self) -> float:
        """Now on the mission clock's time base, seconds: the vehicle's time of its latest
        position with a link (0 before any), the node's clock without."""
        if self._vehicle is not None:
            return self._vehicle_time_s if self._vehicle_time_s is not None else 0.0
        return self._now_ns() / 1e9

    def destroy_node(self) -> None:
        """Stop the worker (a plan in progress is abandoned), then destroy the node."""
        with self._outcomes_lock:
            self._closing = True
        self._worker.stop()
        if self._vehicle is not None:
            self._vehicle.stop()
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
