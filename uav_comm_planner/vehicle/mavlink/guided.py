"""The streamed trajectory on the link: position, velocity and acceleration targets in
ArduCopter's GUIDED or PX4's OFFBOARD.

A :class:`TargetStream` lives on the vehicle link's thread (the
:class:`~uav_comm_planner.vehicle.mavlink.telemetry.VehicleBridge` calls :meth:`TargetStream.tick`
with the autopilot time of every position it receives, and :meth:`TargetStream.on_heartbeat`
with every heartbeat); the node's thread only hands it work (:meth:`TargetStream.start`,
:meth:`TargetStream.stop`). It sends, for autopilot time t, the reference's state at t - t0
(t0: the autopilot time the plan's clock started) as SET_POSITION_TARGET_GLOBAL_INT
(latitude, longitude through the planning frame's home, the plan's altitude, velocity and
acceleration north-east-down, yaw left to the autopilot), one per position report, so at the
telemetry rate in autopilot time whatever the simulator's speed-up, and switches the vehicle
to the mode that follows them. The modes, and what differs between the autopilots, are the
firmware table's (:class:`~uav_comm_planner.vehicle.firmware.StreamModes`), chosen by the
heartbeat's autopilot.

ArduCopter (GUIDED) follows such targets with its position controller (the position target,
the velocity and acceleration as feed-forward: ``ModeGuided::set_destination_posvelaccel``);
when no target comes for GUID_TIMEOUT (3 s by default) it zeroes the velocity and
acceleration and holds the last position. PX4 (OFFBOARD, custom main mode 6) takes the same
message as a trajectory setpoint for its multicopter position controller (velocity and
acceleration feed-forward too), but only switches to OFFBOARD while targets are coming: the
first :attr:`~uav_comm_planner.vehicle.firmware.StreamModes.lead_s` of targets (holding q0)
go out before the mode is asked; when none comes for COM_OF_LOSS_T (1 s by default) PX4 leaves
OFFBOARD by its own failsafe (COM_OBL_RC_ACT). Its targets' altitude is above mean sea level
(the vehicle's home altitude added: ``amsl_targets``).

The mode asked is confirmed from the heartbeat; a vehicle that does not show it after
:data:`MODE_TRIES` requests ends the stream (an 'error'). When the stream stops (the plan
ends, the node asks, the mode is refused, or a gap in the targets longer than
:data:`STREAM_GAP_S` of autopilot time, as after a lost link) the vehicle is put back in its
mission mode (AUTO, PX4's AUTO.MISSION) at the mission item ahead of the reference
(``fallback`` 'auto', MISSION_SET_CURRENT first, in the vehicle's own numbering) or held
(BRAKE, PX4's AUTO.LOITER: 'hold'), once, with one :class:`StreamEvent`. The fallback is
ordered with the mission uploads of the same link thread: a stop asked before an upload falls
back before that upload starts (:meth:`TargetStream.before_upload`), on the mission the
vehicle still holds, so that its mode change and MISSION_SET_CURRENT never act on the newer
mission; a stop that resumes the newer mission at an item (a replan in flight) waits for that
mission's upload (:meth:`TargetStream.uploaded`) and streams on meanwhile. A pilot (or PX4's
failsafe) who takes the vehicle out of the streamed mode ends the stream, and the node leaves
the vehicle alone.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import threading
import time
from typing import Callable

import numpy as np
from pymavlink import mavutil

from uav_comm_planner.core.catch_up import (catch_up, CATCH_UP_SPEED_SHARE, CatchUp,
                                            ground_speed)
from uav_comm_planner.vehicle.firmware import firmware_of_autopilot, FIRMWARES, StreamModes
from uav_comm_planner.vehicle.geodesy import enu_to_geodetic, Home
from uav_comm_planner.vehicle.mavlink.link import vehicle_seq
from uav_comm_planner.vehicle.stream import STREAM_SPEED_MARGIN, StreamReference

MAV = mavutil.mavlink
#: ArduCopter's flight modes of a stream (HEARTBEAT custom_mode).
COPTER_MODES = dict(FIRMWARES['ardupilot'].stream_modes.modes)
#: PX4's flight modes of a stream (HEARTBEAT custom_mode: main mode << 16 | sub mode << 24).
PX4_MODES = dict(FIRMWARES['px4'].stream_modes.modes)
#: What the vehicle does when the stream stops.
STREAM_FALLBACKS = ('auto', 'hold')
#: Targets further apart than this in autopilot time are a broken stream (ArduCopter's
#: GUID_TIMEOUT default: it holds position then).
STREAM_GAP_S = 3.0
#: The stream ends this long after qF (autopilot seconds): the vehicle settles at qF first.
SETTLE_S = 2.0
#: A mode change is asked again after this long without the heartbeat showing it (autopilot s).
MODE_RETRY_S = 0.5
#: A mode is asked at most this many times: the streamed mode (then the stream ends, refused)
#: and a fallback's mode (then it is left to the vehicle).
MODE_TRIES = 10
#: How long a fallback waits for the heartbeat to show its mode when the link is closing
#: (wall clock).
CLOSING_WAIT_S = 2.0
#: SET_POSITION_TARGET type_mask: position, velocity and acceleration used (the force bit clear:
#: the last three are an acceleration), yaw and yaw rate ignored.
POS_VEL_ACCEL_MASK = (MAV.POSITION_TARGET_TYPEMASK_YAW_IGNORE
                      | MAV.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE)
#: Heartbeats in this long after a stream starts may show a mode asked before (autopilot s).
MODE_SETTLE_S = 1.5
#: After a gap in the targets the vehicle is looked for this far along the reference past the
#: last target (seconds of it): GUID_TIMEOUT (STREAM_GAP_S) of flight on, and braking.
HOLD_SEARCH_S = 2.0 * STREAM_GAP_S


@dataclass(frozen=True)
class StreamEvent:
    """What the stream did: ``kind`` 'started', 'stopped' (with the fallback applied) or
    'error'; ``message`` one line for the log."""

    kind: str
    message: str
    #: A 'caught up' event: the job streamed from now on, and the autopilot time of the last
    #: target before the gap (where the vehicle held).
    job: 'StreamJob | None' = None
    lost_s: float | None = None


@dataclass(frozen=True)
class StreamJob:
    """A reference to stream from autopilot time ``t0_s`` at ``altitude_m`` above home;
    ``resume_item(elapsed_s)`` gives the mission item AUTO goes on from (ArduPilot numbering,
    home is 0) at ``elapsed_s`` of the reference's time; ``catch_up`` maps the clock's
    elapsed time to the reference's after the vehicle lost time (None: the same)."""

    reference: StreamReference
    t0_s: float
    altitude_m: float
    fallback: str
    resume_item: Callable[[float], int]
    catch_up: CatchUp | None = None

    def reference_s(self, elapsed_s: float) -> float:
        """The reference's time at ``elapsed_s`` seconds of the clock after t0."""
        if self.catch_up is None:
            return elapsed_s
        return float(self.catch_up.reference_time(elapsed_s))

    def state(self, elapsed_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The target (2,) position, velocity and acceleration ``elapsed_s`` after t0: the
        reference's, flown faster while catching up (velocity times the rate d tau / d e,
        acceleration times its square, within the reference's acceleration bound)."""
        position, velocity, accel = (value[0] for value in
                                     self.reference.state(self.reference_s(elapsed_s)))
        if self.catch_up is None:
            return position, velocity, accel
        rate = float(self.catch_up.rate(elapsed_s)[0])
        accel = accel * rate ** 2
        size, bound = float(np.linalg.norm(accel)), self.reference.bounds.accel_mpss
        return position, velocity * rate, accel * min(1.0, bound / size) if size else accel

    def caught_up(self, held_s: float, now_s: float,
                  position_m: np.ndarray | None = None) -> tuple['StreamJob | None', str]:
        """After a gap in the targets from autopilot time ``held_s`` (the last one sent) to
        ``now_s``: this job catching up on its own path (:mod:`uav_comm_planner.core.
        catch_up`) at :data:`~uav_comm_planner.core.catch_up.CATCH_UP_SPEED_SHARE` of the
        reference's speed (and airspeed) and acceleration in turns, from where the vehicle
        held, and a line saying so;
        None and the reason when the lost time cannot be made up before qF. The vehicle held
        at ``position_m`` (east, north metres; None: at the last target): ArduCopter flies its
        last target on at its velocity for GUID_TIMEOUT before it holds, so the path is
        taken up at its point nearest the vehicle within :data:`HOLD_SEARCH_S` after the last
        target, not behind it."""
        bounds, reference = self.reference.bounds, self.reference
        speed = ground_speed(
            CATCH_UP_SPEED_SHARE * bounds.speed_mps / (1 + STREAM_SPEED_MARGIN), bounds.wind_mps,
            None if bounds.airspeed_mps is None else CATCH_UP_SPEED_SHARE * bounds.airspeed_mps)
        last = self.reference_s(held_s - self.t0_s)
        if position_m is not None:
            window = np.linspace(last, min(last + HOLD_SEARCH_S, reference.duration_s), 200)
            gaps = np.linalg.norm(reference.state(window)[0] - np.asarray(position_m), axis=1)
            last = float(window[int(np.argmin(gaps))])
        found = catch_up(lambda tau: reference.state(tau)[0], reference.duration_s, last,
                         now_s - self.t0_s, speed,
                         accel_mpss=CATCH_UP_SPEED_SHARE * bounds.accel_mpss)
        gap = _gap(held_s, now_s)
        if found is None:
            return None, f'{gap}; the lost time cannot be made up before qF'
        return replace(self, catch_up=found), (
            f'stream caught up: {gap}; the vehicle flies on from where it held, '
            f'{found.lag_s:.1f} s behind, and makes the time up by '
            f'{found.caught_s:.1f} s after q0')


@dataclass(frozen=True)
class _Stop:
    """A stop asked for: why, the item to resume at (None: the job's fallback), and the tag of
    the upload it waits for (None: none)."""

    reason: str
    resume_seq: int | None
    mission: object


class _ModeWatch:
    """The vehicle's flight mode as its heartbeat shows it, and a fallback's mode asked again
    (link thread) until the heartbeat shows it."""

    def __init__(self) -> None:
        self._mode: int | None = None
        self._mode_asked_s = -float('inf')
        self._pending_mode: str | None = None
        self._pending_tries = 0

    def on_heartbeat(self, message) -> None:
        """The vehicle's HEARTBEAT: its flight mode."""
        if message.base_mode & MAV.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            self._mode = int(message.custom_mode)

    def _confirm_fallback(self, link, time_s: float) -> None:
        """Ask the fallback's mode again until the heartbeat shows it (a few times)."""
        if self._pending_mode is None:
            return
        if self._mode == stream_modes(link).modes[self._pending_mode] \
                or self._pending_tries >= MODE_TRIES:
            self._pending_mode = None
            return
        if time_s - self._mode_asked_s >= MODE_RETRY_S:
            set_mode(link, self._pending_mode)
            self._mode_asked_s = time_s
            self._pending_tries += 1


class TargetStream(_ModeWatch):
    """Streams a :class:`StreamJob` on the link's thread (module docstring); ``on_event``
    receives every :class:`StreamEvent` (quick and thread-safe)."""

    def __init__(self, home: Home, on_event: Callable[[StreamEvent], None]) -> None:
        super().__init__()
        self.home = home
        #: The vehicle's own home (HOME_POSITION), for targets above mean sea level.
        self.vehicle_home: Home | None = None
        self._on_event = on_event
        self._lock = threading.Lock()
        self._job: StreamJob | None = None
        self._stopping: _Stop | None = None
        self._fresh = self._guided_seen = False
        self._last_sent_s: float | None = None
        #: The vehicle's latest position, (2,) east-north metres in the frame of ``home``
        #: (the link sets it before each tick; None: not known).
        self.position_m: np.ndarray | None = None
        self._follow_tries = 0
        self._started_s: float | None = None
        #: Targets sent since the stream started (for tests and diagnostics).
        self.targets_sent = 0
        #: Every event given to ``on_event``, in order.
        self.events: list[StreamEvent] = []

    @property
    def active(self) -> bool:
        with self._lock:
            return self._job is not None

    def start(self, job: StreamJob) -> None:
        """Stream ``job`` from now on (replacing the reference streamed, if any)."""
        with self._lock:
            self._fresh = self._fresh or self._job is None
            self._job = job
            self._stopping = None

    def stop(self, reason: str, *, resume_seq: int | None = None,
             mission: object = None) -> None:
        """End the stream at the next tick (or before the next upload) with the job's
        fallback, saying ``reason``; with ``resume_seq``, in AUTO from that item of the mission
        uploaded with tag ``mission`` whatever the fallback (a replan in flight, uploaded to be
        flown from its q0 item): once that upload is verified, the stream going on until then,
        and with the job's own fallback if it fails."""
        with self._lock:
            if self._job is not None:
                self._stopping = _Stop(reason, resume_seq,
                                       mission if resume_seq is not None else None)

    def before_upload(self, link, time_s: float, tag: object) -> None:
        """Link thread, before the upload tagged ``tag`` starts (autopilot time ``time_s``): a
        stop asked for and not waiting for that upload falls back now, on the mission the
        vehicle holds."""
        with self._lock:
            job, stop = self._job, self._stopping
        if job is not None and stop is not None and stop.mission is None:
            self._fall_back(link, job, time_s - job.t0_s, stop.reason, resume_seq=stop.resume_seq)

    def uploaded(self, link, time_s: float, tag: object, verified: bool) -> None:
        """Link thread, after the upload tagged ``tag`` (``verified`` or not): a stop waiting
        for it resumes that mission at its item now, or, the upload failed, falls back as the
        job says."""
        with self._lock:
            job, stop = self._job, self._stopping
        if job is not None and stop is not None and stop.mission is not None \
                and stop.mission == tag:
            self._fall_back(link, job, time_s - job.t0_s, stop.reason,
                            resume_seq=stop.resume_seq if verified else None)

    def tick(self, link, time_s: float) -> None:
        """Link thread, at every position report (autopilot time ``time_s``): one target, a
        mode change, or the fallback."""
        with self._lock:
            job, fresh = self._job, self._fresh
            # A stop that waits for its mission's upload lets the stream go on until then.
            stop = self._stopping if self._stopping and self._stopping.mission is None else None
            reason, resume = (stop.reason, stop.resume_seq) if stop else (None, None)
            self._fresh = False
        if fresh:
            # A new stream: what the link thread knew of the last one goes.
            self._guided_seen = False
            self._last_sent_s = self._started_s = None
            self._mode_asked_s = -float('inf')
            self._pending_mode = None
            self._follow_tries = 0
        if job is None:
            self._confirm_fallback(link, time_s)
            return
        modes = stream_modes(link)
        follow = modes.modes[modes.follow]
        elapsed = time_s - job.t0_s
        if reason is None and job.reference_s(elapsed) > job.reference.duration_s + SETTLE_S:
            reason = 'the plan reached qF' + _from_end(job, self.position_m)
        if reason is None and self._last_sent_s is not None \
                and time_s - self._last_sent_s > STREAM_GAP_S:
            job, reason = self._catch_up(job, time_s, follow)
        if reason is None and self._guided_seen and self._mode != follow:
            self._end(f'stream stopped: the vehicle left {modes.follow} (mode '
                      f'{_mode_label(modes, self._mode)}); it is left as it is')
            return
        if reason is None and self._mode != follow and self._follow_tries >= MODE_TRIES \
                and time_s - self._mode_asked_s >= MODE_RETRY_S:
            self._fall_back(link, job, elapsed,
                            f'the vehicle did not enter {modes.follow} after {MODE_TRIES} '
                            f'requests', kind='error')
            return
        if reason is not None:
            self._fall_back(link, job, elapsed, reason, resume_seq=resume)
            return
        if self._started_s is None:
            self._started_s = time_s
        since_s = time_s - self._started_s
        if self._mode == follow and since_s >= MODE_SETTLE_S:
            if not self._guided_seen:
                self._guided_seen = True
                self._emit(StreamEvent('started', f'streaming the plan in {modes.follow} from '
                                                  f'{elapsed:.1f} s after q0'))
        elif self._mode != follow and since_s >= modes.lead_s \
                and time_s - self._mode_asked_s >= MODE_RETRY_S:
            # PX4 takes OFFBOARD only while targets come: the first ones went out already.
            set_mode(link, modes.follow)
            self._mode_asked_s = time_s
            self._follow_tries += 1
        send_target(link, job, elapsed, self.home, self.vehicle_home)
        self.targets_sent += 1
        self._last_sent_s = time_s

    def close(self, link) -> None:
        """Link thread, before the link closes: a stream still running falls back now, and the
        heartbeat is awaited (at most CLOSING_WAIT_S) so that the mode is set before the link
        goes."""
        with self._lock:
            job, stop = self._job, self._stopping
        reason = stop.reason if stop else None
        # The mission a waiting stop would resume is not on the vehicle.
        resume = stop.resume_seq if stop and stop.mission is None else None
        if job is None:
            return
        # AUTO goes on from the item ahead of the last target sent (the start if none was).
        sent = self._last_sent_s
        elapsed = 0.0 if sent is None else max(0.0, sent - job.t0_s)
        mode = self._fall_back(link, job, elapsed, reason or 'the vehicle link is closing',
                               resume_seq=resume)
        deadline = time.monotonic() + CLOSING_WAIT_S
        while self._mode != mode and (left := deadline - time.monotonic()) > 0:
            message = link.recv_match(type='HEARTBEAT', blocking=True, timeout=left)
            if message is not None and message.get_srcSystem() == link.target_system:
                self.on_heartbeat(message)

    def _fall_back(self, link, job: StreamJob, elapsed_s: float | None, reason: str, *,
                   resume_seq: int | None = None, kind: str = 'stopped') -> int:
        """Put the vehicle in its mission mode at the item ahead (at ``resume_seq`` when
        given; both in ArduPilot's numbering), or hold it; returns the mode asked (its
        custom_mode)."""
        modes = stream_modes(link)
        if resume_seq is not None or job.fallback == 'auto':
            seq = resume_seq if resume_seq is not None else job.resume_item(
                job.reference_s(elapsed_s) if elapsed_s is not None
                else job.reference.duration_s)
            seq = vehicle_seq(link, seq)
            link.mav.mission_set_current_send(link.target_system, link.target_component, seq)
            name, what = modes.resume, f'back in {modes.resume} from mission item {seq}'
        else:
            name, what = modes.hold, f'held in {modes.hold}'
        set_mode(link, name)
        self._pending_mode, self._pending_tries = name, 0
        self._mode_asked_s = -float('inf') if elapsed_s is None else job.t0_s + elapsed_s
        self._end(f'stream stopped ({reason}): the vehicle is {what}', kind=kind)
        return modes.modes[name]

    def _catch_up(self, job: StreamJob, time_s: float,
                  follow: int) -> tuple[StreamJob, str | None]:
        """After a gap in the targets: ``job`` caught up (said once) while the vehicle is still
        in the ``follow`` mode (PX4's failsafe takes it out), or why the stream stops."""
        if self._mode != follow:
            return job, _gap(self._last_sent_s, time_s)
        caught, message = job.caught_up(self._last_sent_s, time_s, self.position_m)
        if caught is None:
            return job, message
        with self._lock:
            self._job = caught if self._job is job else self._job
        self._emit(StreamEvent('caught up', message, job=caught, lost_s=self._last_sent_s))
        return caught, None

    def _end(self, message: str, *, kind: str = 'stopped') -> None:
        with self._lock:
            self._job = None
            self._stopping = None
        self._guided_seen = False
        self._emit(StreamEvent(kind, message))

    def _emit(self, event: StreamEvent) -> None:
        self.events.append(event)
        self._on_event(event)


def _from_end(job: StreamJob, position_m: np.ndarray | None) -> str:
    """Where the vehicle at ``position_m`` is against the reference's end (qF), in words (''
    before its first position): a vehicle held back (a gale, a fault) is far from it."""
    if position_m is None:
        return ''
    end = job.reference.state(job.reference.duration_s)[0][0]
    return f', the vehicle {float(np.linalg.norm(position_m - end)):.1f} m from it'


def send_target(link, job: StreamJob, elapsed_s: float, home: Home,
                vehicle_home: Home | None) -> None:
    """SET_POSITION_TARGET_GLOBAL_INT of ``job``'s reference ``elapsed_s`` after q0: latitude
    and longitude through the planning frame's ``home``, the plan's altitude above the
    vehicle's home (above mean sea level where the vehicle takes only that exactly and its
    ``vehicle_home`` is known), velocity and acceleration north-east-down."""
    position, velocity, accel = job.state(elapsed_s)
    latitude, longitude, _ = enu_to_geodetic(np.array([position[0]]), np.array([position[1]]),
                                             0.0, home)
    frame, altitude = MAV.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, job.altitude_m
    if stream_modes(link).amsl_targets and vehicle_home is not None:
        frame, altitude = MAV.MAV_FRAME_GLOBAL_INT, vehicle_home.altitude_m + altitude
    # East-north to north-east-down.
    link.mav.set_position_target_global_int_send(
        0, link.target_system, link.target_component, frame, POS_VEL_ACCEL_MASK,
        int(round(float(latitude[0]) * 1e7)), int(round(float(longitude[0]) * 1e7)),
        float(altitude), float(velocity[1]), float(velocity[0]), 0.0,
        float(accel[1]), float(accel[0]), 0.0, 0.0, 0.0)


def stream_modes(link) -> StreamModes:
    """The stream's modes for ``link``'s vehicle (by its heartbeat's autopilot)."""
    return firmware_of_autopilot(getattr(link, 'vehicle_autopilot', None)).stream_modes


def set_mode(link, mode: str) -> None:
    """Ask ``link``'s vehicle for flight mode ``mode`` (a name of its :func:`stream_modes`:
    :data:`COPTER_MODES` or :data:`PX4_MODES`). SET_MODE with the custom mode: PX4 turns it
    into MAV_CMD_DO_SET_MODE(base mode, main mode, sub mode) itself."""
    link.mav.set_mode_send(link.target_system, MAV.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                           stream_modes(link).modes[mode])


def _gap(held_s: float, now_s: float) -> str:
    """What a gap in the targets from autopilot time ``held_s`` to ``now_s`` was."""
    return f'no target reached the vehicle for {now_s - held_s:.1f} s (the link was down)'


def _mode_label(modes: StreamModes, custom_mode: int | None) -> str:
    """A mode for a log line: its name when it is one of ``modes``, else its number."""
    names = {value: name for name, value in modes.modes.items()}
    return names.get(custom_mode, str(custom_mode))


__all__ = ['COPTER_MODES', 'HOLD_SEARCH_S', 'PX4_MODES', 'STREAM_FALLBACKS', 'STREAM_GAP_S',
           'StreamEvent', 'StreamJob', 'TargetStream', 'send_target', 'set_mode', 'stream_modes']
