"""The mission in flight, as the node runs it: its clock, the UAV's positions, the replans.

A :class:`MissionFlight` takes the node (as tf2_ros's TransformListener does) and keeps the
mission's :class:`~uav_comm_planner.mission.progress.MissionProgress` and the UAV's
:class:`~uav_comm_planner.mission.progress.PoseTrack`. The mission clock starts when the UAV
reaches the plan's q0 (within :data:`START_RADIUS_M`) or on ``~/start``; with a link, only
once the plan is uploaded, from the vehicle's telemetry, when the vehicle holds q0: within
:data:`START_RADIUS_M` of it and :data:`START_HEIGHT_M` of the planned altitude, slower than
:data:`HOLD_SPEED_MPS`, in a mode that flies the mission (AUTO or GUIDED; never during the
climb, never in BRAKE or LOITER). While it runs, new inputs replan the rest of the mission
from the UAV's position (the receding horizon), and a position off the plan does too, within
the ``replan_*`` parameters' limits, once the UAV has been off the plan for
:data:`OFF_PLAN_CONFIRM_S` (a short glitch of the position estimate never replans), and not
while the wind loop refuses the measured wind (``wind_refused``, kept by
:class:`~uav_comm_planner.ros.wind.WindTracker`: the UAV, slower than any plan in the gale,
flies the plan in force as it can).
"""

from __future__ import annotations

import math
import time
from typing import Protocol

from uav_comm_planner.errors import PlannerError
from uav_comm_planner.mission.catch_up import caught_up_rest
from uav_comm_planner.mission.plausible import PositionGate
from uav_comm_planner.mission.progress import (MissionProgress, off_plan, planned_position,
                                               PoseTrack, TRACK_GAP_S)
from uav_comm_planner.mission.request import InFlight, with_slots
from uav_comm_planner.ros.messages import nodes_text
from uav_comm_planner.ros.params import PlannerConfig
from uav_comm_planner.ros.planning import PlanOutcome
from uav_comm_planner.ros.vehicle import VehicleAdapter
from uav_comm_planner.vehicle.mavlink.guided import StreamEvent

#: The UAV is at q0, and the mission clock starts, within this distance of it (metres);
#: ArduCopter counts a waypoint reached within WPNAV_RADIUS, 2 m by default.
START_RADIUS_M = 2.5
#: With a link, the vehicle holds q0 within this height of the planned altitude (metres)...
START_HEIGHT_M = 1.0
#: ... and slower than this (m/s, vertical speed included).
HOLD_SPEED_MPS = 0.5
#: The source name of the vehicle's telemetry.
SOURCE_TELEMETRY = 'vehicle'
#: A source's refused positions are reported at most once in this many seconds (wall clock).
REFUSAL_REPORT_S = 1.0
#: Samples off the plan replan only once the last sample on it is this old (mission clock
#: seconds): a stream must stay off the plan this long, a lone pose replans at once.
OFF_PLAN_CONFIRM_S = 1.0
#: A caught-up rest being planned keeps the off-plan replans away for at most this many
#: slots of autopilot time.
CATCH_UP_WAIT_SLOTS = 5


class FlightHost(Protocol):
    """What :class:`MissionFlight` asks of its node (the planner node provides it)."""

    config: PlannerConfig
    vehicle: VehicleAdapter

    def get_logger(self): ...

    def submit(self, reason: str, in_flight: InFlight | None = None) -> None: ...

    def refuse(self, request: str, message: str, *, nodes: str | None = None) -> None: ...

    def clock_s(self) -> float: ...


class _RefusalReports:
    """Refused position samples, counted, and reported in one line per source at most once
    every :data:`REFUSAL_REPORT_S` (wall clock) with the count since the last line."""

    def __init__(self, node: FlightHost) -> None:
        self._node = node
        #: Position samples refused by the plausibility check so far.
        self.positions_refused = 0
        self._unreported: dict[str, int] = {}
        self._reported_at: dict[str, float] = {}

    def _refuse_position(self, source: str, reason: str) -> None:
        self.positions_refused += 1
        self._unreported[source] = self._unreported.get(source, 0) + 1
        now = time.monotonic()
        if now - self._reported_at.get(source, -math.inf) < REFUSAL_REPORT_S:
            return
        count = self._unreported.pop(source)
        self._reported_at[source] = now
        more = f' ({count} samples refused since the last report)' if count > 1 else ''
        self._node.refuse(source, f'{source} refused: {reason}{more}')

    def _refuse_late(self, mission, reason: str, ended: str | None = None) -> None:
        """Refuse ``reason``: the mission ended (``ended``, its reason) or every slot of
        ``mission`` in flight has begun."""
        why = ended or (f'every slot of the mission in flight has begun ({mission.num_slots} '
                        f'of {mission.num_slots}), so there is nothing left to replan and the '
                        f'vehicle flies on to qF')
        self._node.refuse(reason, f'{reason} refused: {why}; the input applies to the next '
                                  f'mission (~/replan plans one from start_m now)',
                          nodes=nodes_text(mission.ground_nodes_m))


class MissionFlight(_RefusalReports):
    """The mission of ``node`` in flight (module docstring)."""

    def __init__(self, node: FlightHost) -> None:
        super().__init__(node)
        self.progress = MissionProgress()
        self.track = PoseTrack()
        self.gate = PositionGate()
        self._last_pose_replan_s = -math.inf
        self._on_plan_s = -math.inf
        #: The autopilot time a caught-up rest was asked at, and of which plan in force.
        self._catch_up: tuple[float, int, int] | None = None
        #: A wind no plan can take is refused (:mod:`.wind`): no replan from positions then.
        self.wind_refused = False

    def on_position(self, time_s: float, x_m: float, y_m: float, *, source: str,
                    height_m: float | None = None) -> bool:
        """The UAV at (x, y) metres (``height_m`` above the ground, when known) at ``time_s``
        on the mission clock's time base: starts the clock at q0, replans when off the plan.

        Every sample passes the plausibility check (:mod:`uav_comm_planner.mission.plausible`)
        first; a refused one never reaches the track nor the clock and is reported in one
        line (at most once every :data:`REFUSAL_REPORT_S` per source, with the count). No
        error of a sample ends the node: it is refused with its reason. Returns whether the
        sample passed the check."""
        reason = self.gate.check((time_s, x_m, y_m), self._top_speed_mps(), height_m)
        if reason is not None:
            self._refuse_position(source, reason)
            return False
        try:
            self._take_position(time_s, x_m, y_m, source=source, height_m=height_m)
        except (PlannerError, ArithmeticError, ValueError) as exc:
            self._refuse_position(source, f'cannot use it: {exc}')
        return True

    def _top_speed_mps(self) -> float:
        """The fastest the UAV may move over the ground: the planning speed or the vehicle's
        cruise, whichever is faster, plus the wind."""
        config = self._node.config
        cruise = config.vehicle.cruise_speed_mps
        speed = max(config.scenario.max_speed_mps, cruise if math.isfinite(cruise) else 0.0)
        return speed + config.scenario.wind_speed_mps

    def _take_position(self, time_s: float, x_m: float, y_m: float, *, source: str,
                       height_m: float | None) -> None:
        node = self._node
        latest = self.track.latest
        self.track.add(time_s, x_m, y_m)
        if latest is not None and time_s - latest[0] > TRACK_GAP_S:
            self._on_plan_s = time_s        # after a gap in the telemetry the wait restarts
        segment = self.progress.current
        if segment is None:
            return
        if segment.start_s is None:
            if _at_start(node.vehicle, segment.result.scenario, (x_m, y_m), height_m, source):
                self.start_clock(time_s, f'the UAV holds q0 ({source})')
            return
        if self.progress.over(time_s) or 0.0 < segment.start_s - time_s <= \
                segment.result.scenario.slot_s:
            return              # over, or a caught-up rest not in force before its slot
        output = node.config.node
        elapsed = time_s - segment.start_s
        left_s = (self.progress.mission.num_slots - segment.first_slot
                  - segment.slots_begun(time_s)) * segment.result.scenario.slot_s
        if left_s < output.replan_interval_s or self._catching_up(time_s) or self.wind_refused:
            return      # too late to be flown, a caught-up rest comes, or a gale is refused
        reason = off_plan(segment.result, elapsed, (x_m, y_m),
                          distance_m=output.replan_distance_m, delay_s=output.replan_delay_s)
        if not reason:
            self._on_plan_s = time_s
            return
        # A clock that went back (a rebooted autopilot) restarts both waits.
        self._on_plan_s = min(self._on_plan_s, time_s)
        self._last_pose_replan_s = min(self._last_pose_replan_s, time_s)
        if (time_s - self._last_pose_replan_s < output.replan_interval_s
                or time_s - self._on_plan_s < OFF_PLAN_CONFIRM_S):
            return
        self._last_pose_replan_s = time_s
        node.get_logger().info(f'{source}: the UAV is {reason}; replanning the rest')
        self._request_rest(source, time_s, (x_m, y_m))

    def on_catch_up(self, event: StreamEvent) -> None:
        """The stream caught up the plan in force after a gap: its rest restated as flown
        (:mod:`uav_comm_planner.mission.catch_up`), in force at once once planned."""
        job = event.job
        try:
            rest = caught_up_rest(self.progress, self.track, self._node.config.scenario,
                                  job.reference, job.catch_up, t0_s=job.t0_s,
                                  lost_s=event.lost_s)
        except (PlannerError, ArithmeticError, ValueError) as exc:
            self._node.refuse('stream caught up', f'the caught-up plan is not stated: {exc}')
            return              # the stream flies on; the plan in force is checked as ever
        if rest is not None:
            self._catch_up = (job.t0_s + float(job.catch_up.clock_s[0]), rest.mission_id,
                              rest.segment)
            self._node.submit('the stream caught up the plan in force', rest)

    def _catching_up(self, time_s: float) -> bool:
        """Whether a caught-up rest of the plan in force is being planned (for at most
        :data:`CATCH_UP_WAIT_SLOTS` slots): the vehicle, behind the plan meanwhile, is not off
        it."""
        asked = self._catch_up
        return (asked is not None and (asked[1], asked[2]) == (self.progress.mission_id,
                                                               len(self.progress.segments) - 1)
                and 0.0 <= time_s - asked[0]
                <= CATCH_UP_WAIT_SLOTS * self.progress.current.result.scenario.slot_s)

    def start_clock(self, time_s: float, why: str) -> None:
        """Start the plan's clock at ``time_s``; with ``flight_mode`` stream and a link, the
        vehicle then flies the plan as streamed targets from that autopilot time on."""
        first = not self.progress.started
        self.progress.start_clock(time_s)
        # The mission's clock starts once; a replan taken over later only comes into force.
        self._node.get_logger().info(f'mission clock started: {why}' if first
                                     else f'{why} from now (the mission clock runs on)')
        node = self._node
        if node.config.node.flight_mode == 'stream' and node.vehicle.linked:
            node.vehicle.start_stream(self.progress.current.result, time_s, node.config.node)

    def running(self, time_s: float) -> bool:
        """Whether a mission is in flight that a replan should continue."""
        mission = self.progress.mission
        scenario = self._node.config.scenario
        # The same mission: its slots as the parameters say, or more (a replan lengthened it).
        return (self.progress.started and not self.progress.over(time_s)
                and mission is not None and mission.num_slots >= scenario.num_slots
                and math.isclose(mission.slot_s, scenario.slot_s, rel_tol=1e-12))

    def request_update(self, reason: str) -> None:
        """New inputs: replan the rest of the mission in flight, else the whole mission.

        Once the mission's last slot has begun there is no rest to replan, and a new mission
        from ``start_m`` would send the vehicle back from its way to qF: the request is
        refused, with the reason (``~/replan`` plans a new mission)."""
        now = self._node.clock_s()
        if self.progress.started and self.progress.over(now):
            self._refuse_late(self.progress.mission, reason, self.progress.ended)
            return
        if not self.running(now):
            self.request_plan(reason)
            return
        latest = self.track.latest
        segment = self.progress.current
        if latest is not None and now - latest[0] <= self._node.config.scenario.slot_s:
            position = (latest[1], latest[2])
        else:
            elapsed = now - segment.start_s if segment.start_s is not None else 0.0
            position = tuple(planned_position(segment.result, elapsed))
        self._request_rest(reason, now, position)

    def request_plan(self, reason: str) -> None:
        """Plan the whole mission from ``start_m`` with the current parameters; a mission in
        flight ends (its clock stops)."""
        self.progress = MissionProgress()
        self._node.submit(reason)

    def _request_rest(self, reason: str, time_s: float, position: tuple[float, float]) -> None:
        """Replan the rest of the mission in flight from ``position`` at ``time_s``."""
        energy_left_wh = self._node.vehicle.battery.budget()
        try:
            in_flight = self.progress.in_flight(self._node.config.scenario, time_s, position,
                                                self.track, energy_left_wh=energy_left_wh)
        except PlannerError as exc:
            mission = with_slots(self._node.config.scenario, self.progress.mission.num_slots)
            self._node.refuse(reason, f'{reason} refused: {exc}',
                              nodes=nodes_text(mission.ground_nodes_m))
            return
        self._node.submit(reason, in_flight)

    def take(self, outcome: PlanOutcome) -> bool:
        """Make ``outcome`` the plan in force of the mission; False if it came too late."""
        node = self._node
        request = outcome.request
        rest = request.mission.in_flight
        planned = outcome.plan.optimised
        if rest is None:
            self.progress.begin(request.scenario, outcome.result, planned=planned)
            return True
        mission = outcome.receding.mission
        before = self.progress.mission
        if not self.progress.take_over(rest.mission_id, rest.segment, rest.slots_kept,
                                       mission, outcome.result, planned=planned,
                                       restated=rest.restated):
            node.get_logger().info(f'{request.reason}: a newer plan is flown already; this '
                                   f'replan is dropped')
            return False
        if rest.start_s is not None:        # caught up: the stream flies it from then
            self.progress.current.start_s = rest.start_s
            return True
        if before is not None and mission.num_slots > before.num_slots:
            node.get_logger().warning(
                f'{request.reason}: the rest cannot keep qF in time; the mission is lengthened '
                f'from {before.num_slots} to {mission.num_slots} slots ({mission.horizon_s:g} '
                f's) and promises a whole-mission min throughput of '
                f'{outcome.receding.mission_min_throughput:.4g} bit/s over them')
        if not request.output.mavlink_url:
            # The UAV was at the new q0 when the replan was asked; without a link to say when
            # it flies the new plan, the plan is in force from now.
            self.start_clock(node.clock_s(), 'the replan is in force')
        return True


def _at_start(vehicle: VehicleAdapter, scenario, position: tuple[float, float],
              height_m: float | None, source: str) -> bool:
    """Whether the sample starts the plan's clock (module docstring)."""
    horizontal = math.dist(scenario.start_m, position)
    if not vehicle.linked:
        climb = 0.0 if height_m is None else height_m - scenario.altitude_m
        return math.hypot(horizontal, climb) <= START_RADIUS_M
    return (not vehicle.upload_pending and height_m is not None
            and source == SOURCE_TELEMETRY and vehicle.flying_mission
            and horizontal <= START_RADIUS_M
            and abs(height_m - scenario.altitude_m) <= START_HEIGHT_M
            and vehicle.speed_mps <= HOLD_SPEED_MPS)


__all__ = ['CATCH_UP_WAIT_SLOTS', 'FlightHost', 'HOLD_SPEED_MPS', 'MissionFlight',
           'OFF_PLAN_CONFIRM_S',
           'REFUSAL_REPORT_S', 'SOURCE_TELEMETRY', 'START_HEIGHT_M', 'START_RADIUS_M']
