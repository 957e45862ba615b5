"""The vehicle side of the node: the MAVLink link's events on the executor, the vehicle's
pose on ``vehicle_pose`` (advertised only while a link runs), every plan uploaded, the
autopilot's wind estimates, the battery (:mod:`.battery`), the vehicle's own limit parameters
(:mod:`.vehicle_params`), and the streamed trajectory (:mod:`.stream`) started and stopped.

A :class:`VehicleAdapter` takes the node (as tf2_ros's TransformListener does): with
``mavlink_url`` set it runs a :class:`~uav_comm_planner.vehicle.mavlink.telemetry.VehicleBridge`,
whose thread hands positions, mission progress and link events to the executor through an
:class:`~uav_comm_planner.ros.handoff.ExecutorHandoff`; positions go on to ``on_position``.

Unless the home parameters were set, the vehicle's home (HOME_POSITION) is the planning
frame's origin: a plan's mission items are built for it before the upload, and a plan made
before the vehicle told it waits for it. A link made again (another ``mavlink_url``,
``flight_mode``, ``home_distance_limit_m`` or home) uploads the plan in force again unless the
vehicle on the same link and home was verified to hold it (a plan in force before the first
link is uploaded on it), so that its clock can start; the
events the former link had not handed on yet are dropped. A lost link, a telemetry gap and a
mission refused
for another place are each one line on the log (a loss and a refusal also on
``planner_status``).
"""

from __future__ import annotations

from typing import Callable, Collection

from geometry_msgs.msg import PoseStamped
import numpy as np
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.errors import PlannerError
from uav_comm_planner.ros.battery import BatteryWatch
from uav_comm_planner.ros.binding import ParameterBinding
from uav_comm_planner.ros.handoff import ExecutorHandoff
from uav_comm_planner.ros.params import NodeSettings
from uav_comm_planner.ros.planning import PlanOutcome
from uav_comm_planner.ros.vehicle_params import VehicleParameterWatch
from uav_comm_planner.ros.vehicle_state import VehicleState
from uav_comm_planner.ros.wind import WindTracker
from uav_comm_planner.vehicle.geodesy import geodetic_to_enu, Home
from uav_comm_planner.vehicle.limits import VehicleLimits, VehicleParameters
from uav_comm_planner.vehicle.mavlink.battery import BatteryReport
from uav_comm_planner.vehicle.mavlink.guided import StreamEvent, StreamJob, TargetStream
from uav_comm_planner.vehicle.mavlink.items import MissionItem, NAV_WAYPOINT, Q0_SEQ
from uav_comm_planner.vehicle.mavlink.telemetry import (Event, HomeReport, LinkEvent,
                                                        MissionProgressReport, ModeReport,
                                                        Position, TELEMETRY_RATE_HZ,
                                                        VehicleBridge, Wind)
from uav_comm_planner.vehicle.stream import (resume_item, STREAM_ACCEL_ALLOWANCE,
                                             stream_reference, StreamReference)

TOPIC_VEHICLE_POSE = 'vehicle_pose'
#: The home parameters: set, they anchor the planning frame; else the vehicle's home does.
HOME_PARAMETERS = frozenset({'home_latitude_deg', 'home_longitude_deg', 'home_altitude_m'})
#: Link events kept for the executor at most (the oldest go first).
EVENTS_KEPT = 10_000
#: Reliable, so that subscribers of either reliability hear the vehicle's pose.
VEHICLE_POSE_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                              durability=DurabilityPolicy.VOLATILE)

#: on_position(time_s, east_m, north_m, up_m): the vehicle's position on the executor; whether
#: it passed the node's check (an outlier is not published on vehicle_pose).
PositionCallback = Callable[[float, float, float, float], bool]
#: report(message, is_error): a line for the node's log.
Reporter = Callable[[str, bool], None]
#: Telemetry (and so target) rate with flight_mode stream, per second of autopilot time.
STREAM_TELEMETRY_RATE_HZ = 20.0


def _reference_for(outcome: PlanOutcome, limits: VehicleLimits) -> tuple[StreamReference, str]:
    """The streamed reference of ``outcome``'s plan for its firmware
    (:data:`~uav_comm_planner.vehicle.stream.STREAM_ACCEL_ALLOWANCE`), and what to say of it
    ('' when nothing). Raises PlannerError when the plan cannot be streamed."""
    firmware = outcome.request.output.mission_firmware
    reference = stream_reference(outcome.result, limits,
                                 accel_allowance=STREAM_ACCEL_ALLOWANCE[firmware])
    if not reference.accel_raised:
        return reference, ''
    return reference, (f'stream: the plan\'s points need more acceleration than the '
                       f'vehicle\'s {limits.max_accel_mpss:g} m/s/s (vehicle_max_accel_mpss); '
                       f'streamed with targets of up to {reference.bounds.accel_mpss:.3g} '
                       f'm/s/s, which {firmware} follows in its stream mode')


class VehicleAdapter(VehicleState):
    """The vehicle link of ``node``, (re)made by :meth:`connect` from the node settings.

    ``time_s`` is the vehicle's time of its latest position (None before any);
    ``mission_item`` the item it flies to; ``uploads_verified`` counts uploads read back;
    ``upload_pending`` is True while the latest plan's upload is not yet verified or failed;
    ``last_error`` is the link's latest error ('' when none; a link error ends when the link is
    up again, a failed upload when an upload is verified).
    ``binding``'s ``frame_id`` is the frame of the poses published on ``vehicle_pose``, a topic
    that exists only while a link runs; mode, speed, home, link state: :class:`VehicleState`.
    """

    def __init__(self, node: Node, on_position: PositionCallback, report: Reporter, *,
                 binding: ParameterBinding) -> None:
        self._node = node
        #: The autopilot's wind estimate, smoothed and published (:mod:`.wind`).
        self.wind = WindTracker(node)
        self.battery = BatteryWatch(node)     # reported and acted on (:mod:`.battery`)
        #: The vehicle's own limit parameters, planned with (:mod:`.vehicle_params`).
        self.parameters = VehicleParameterWatch(node, binding)
        #: The streamed trajectory on the link's thread (None without a link).
        self.stream: TargetStream | None = None
        #: Stream events seen: 'started', 'stopped' messages, in order (for tests).
        self.stream_events: list[str] = []
        self._stream_reported = 0
        self._prepared: tuple[PlanResult, StreamReference, tuple] | None = None
        self._on_position = on_position
        self._report = report
        self._frame_id = lambda: binding.config.node.frame_id
        self._bridge: VehicleBridge | None = None
        self._events: ExecutorHandoff[tuple[int, Event]] = ExecutorHandoff(
            node, self._drain, maxlen=EVENTS_KEPT)
        #: Counts the links made: an event of an older one is not drained.
        self._generation = 0
        self._pose: Publisher | None = None
        self._position_ns: int | None = None
        self.time_s: float | None = None
        self.mission_item: int | None = None
        self._init_uploads()
        self._reset_state(None)

    @property
    def linked(self) -> bool:
        return self._bridge is not None

    def connect(self, output: NodeSettings, explicit: Collection[str] = ()) -> None:
        """(Re)start the link for ``output.mavlink_url`` (none when empty); the frame's origin
        is the vehicle's home unless a home parameter is among those set ``explicit``."""
        follow_home = not HOME_PARAMETERS & set(explicit)
        self.stop()
        self.time_s = self._position_ns = None
        self.last_error = ''
        self._upload_failed = False
        self._pending_tag = None
        self._reset_state(None if follow_home else output.home)
        self._link_key = (output.mavlink_url, self.home)
        if output.mavlink_url:
            self._pose = self._node.create_publisher(PoseStamped, TOPIC_VEHICLE_POSE,
                                                     VEHICLE_POSE_QOS)
            put, generation = self._events.put, self._generation

            def on_event(event: Event) -> None:
                put((generation, event))
            self.stream = TargetStream(output.home, on_event)
            rate = (STREAM_TELEMETRY_RATE_HZ if output.flight_mode == 'stream'
                    else TELEMETRY_RATE_HZ)
            self._bridge = VehicleBridge(output.mavlink_url, self.home, on_event,
                                         rate_hz=rate, stream=self.stream,
                                         home_limit_m=output.home_distance_limit_m)
            origin = "the vehicle's home" if follow_home else 'the home parameters'
            self._report(f'vehicle link: connecting to {output.mavlink_url} (planning frame '
                         f'origin: {origin})', False)
            outcome = getattr(self._node, 'current_plan', None)
            if outcome is not None and output.flight_mode == 'stream':
                self.prepare_stream(outcome, self._node.config.vehicle)   # if its clock waits
            self._upload_again(outcome)

    @property
    def stream_reference(self) -> StreamReference | None:
        """The reference made for the latest plan in stream mode (None: none)."""
        return None if self._prepared is None else self._prepared[1]

    def fly(self, outcome: PlanOutcome, limits: VehicleLimits) -> None:
        """A new plan in force: upload it; with ``flight_mode`` stream, make its reference too.
        A stream running stops: the new plan starts from its own q0, which the vehicle flies to
        in AUTO (a replan in flight from its q0 item) as a mission's."""
        rest = outcome.request.mission.in_flight
        if rest is not None and rest.caught_up is not None:
            return      # the stream flies it, on the mission the vehicle holds for a fallback
        if outcome.request.output.flight_mode == 'stream':
            self.prepare_stream(outcome, limits)
        streaming = self.stream is not None and self.stream.active
        if streaming:
            # Asked before the upload: the link thread orders the two (:mod:`.guided`).
            self.stop_stream('a new plan is in force',
                             resume_seq=Q0_SEQ if outcome.receding is not None else None,
                             mission=outcome.request.start_ns)
        self.upload(outcome)
        if streaming and not self.upload_pending:
            # Refused before it reached the link: the stream falls back as its job says.
            self.stop_stream('a new plan is in force')

    def prepare_stream(self, outcome: PlanOutcome, limits: VehicleLimits) -> None:
        """Make the streamed reference of ``outcome``'s plan now (it is streamed once the
        plan's clock starts); a plan that cannot be streamed is said once, and its uploaded
        mission is what the vehicle flies."""
        result = outcome.result
        try:
            reference, note = _reference_for(outcome, limits)
        except PlannerError as exc:
            self._report(f'stream: this plan cannot be streamed, its mission is flown in AUTO: '
                         f'{exc}', True)
            return
        if note:
            self._report(note, False)
        items = outcome.plan.items or ()
        home = outcome.request.output.home
        waypoints = [(seq, _enu(item, home)) for seq, item in enumerate(items)
                     if seq >= Q0_SEQ and item.command == NAV_WAYPOINT]
        self._prepared = (result, reference, tuple(waypoints))

    def start_stream(self, result: PlanResult, t0_s: float, output: NodeSettings) -> bool:
        """Stream the prepared reference of ``result`` from autopilot time ``t0_s``; False
        when there is none (no link, or the plan could not be streamed)."""
        if self.stream is None or self._prepared is None or self._prepared[0] is not result:
            return False
        _, reference, waypoints = self._prepared
        if waypoints:
            def resume(elapsed_s: float) -> int:
                return resume_item(waypoints, reference, elapsed_s)
        else:
            def resume(elapsed_s: float) -> int:
                return Q0_SEQ
        self.stream.start(StreamJob(reference, t0_s, result.scenario.altitude_m,
                                    output.stream_fallback, resume))
        return True

    def stop_stream(self, reason: str, *, resume_seq: int | None = None,
                    mission: object = None) -> None:
        """End the stream (with its fallback, or in AUTO from ``resume_seq`` of the mission
        uploaded as ``mission``, once it is) at the link's next position report or before its
        next upload."""
        if self.stream is not None:
            self.stream.stop(reason, resume_seq=resume_seq, mission=mission)

    def stop(self) -> None:
        """End the link (a stream running falls back first, said on the log) and withdraw
        ``vehicle_pose``."""
        self._generation += 1
        if self._bridge is not None:
            self._bridge.stop()
            self._bridge = None
        if self.stream is not None:
            # Events the executor will not drain any more: said here.
            for event in self.stream.events[self._stream_reported:]:
                self._report(event.message, event.kind == 'error')
        self.stream = None
        self._stream_reported = 0
        if self._pose is not None:
            self._node.destroy_publisher(self._pose)
            self._pose = None

    def _drain(self, events: list[tuple[int, Event]]) -> None:
        """Executor thread: positions, mission progress and link events from the vehicle (of
        the link made last)."""
        for generation, event in events:
            if generation != self._generation:
                continue
            if isinstance(event, Position):
                self.time_s = event.time_s
                self.speed_mps = event.speed_mps
                self._position_ns = self._node.get_clock().now().nanoseconds
                if self._on_position(event.time_s, event.east_m, event.north_m, event.up_m):
                    self._publish_pose(event)
            elif isinstance(event, MissionProgressReport):
                self.mission_item = event.seq
            elif isinstance(event, ModeReport):
                self._on_mode(event)
            elif isinstance(event, BatteryReport):
                self.battery.add(event)
            elif isinstance(event, HomeReport):
                self._on_home(event)
            elif isinstance(event, LinkEvent):
                self._on_link_event(event)
            elif isinstance(event, Wind):
                self.wind.add(event.time_s, event.east_mps, event.north_mps)
            elif isinstance(event, VehicleParameters):
                self.parameters.add(event)
            elif isinstance(event, StreamEvent):
                self._stream_reported += 1
                self.stream_events.append(event.message)
                self._report(event.message, event.kind == 'error')
                if event.kind == 'caught up':
                    self._node.flight.on_catch_up(event)

    def _publish_pose(self, event: Position) -> None:
        if self._pose is not None:      # else a position the link sent before it was stopped
            self._pose.publish(_pose_message(event, self._frame_id(),
                                             self._node.get_clock().now().to_msg()))


def _pose_message(event: Position, frame_id: str, stamp) -> PoseStamped:
    """The vehicle's position ``event`` as a pose in ``frame_id`` at ``stamp``."""
    message = PoseStamped()
    message.header.frame_id = frame_id
    message.header.stamp = stamp
    message.pose.position.x = event.east_m
    message.pose.position.y = event.north_m
    message.pose.position.z = event.up_m
    message.pose.orientation.w = 1.0
    return message


def _enu(item: MissionItem, home: Home) -> np.ndarray:
    east, north, _ = geodetic_to_enu(np.array([item.x]), np.array([item.y]), home.altitude_m,
                                     home)
    return np.array([float(east[0]), float(north[0])])


__all__ = ['HOME_PARAMETERS', 'TOPIC_VEHICLE_POSE', 'VEHICLE_POSE_QOS', 'VehicleAdapter']
