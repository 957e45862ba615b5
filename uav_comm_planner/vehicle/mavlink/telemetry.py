"""The vehicle on its own thread: telemetry in, missions out, over one MAVLink connection.

A :class:`VehicleBridge` owns the connection (pymavlink's are not thread-safe) and runs on a
daemon thread, never on the caller's: it connects (waiting for a heartbeat, again after a lost
link), asks for GLOBAL_POSITION_INT and MISSION_CURRENT at ``rate_hz`` (autopilot time) and
for HOME_POSITION, turns each position into the planning frame through ``home`` and hands the
caller :class:`Position`, :class:`MissionProgressReport`, :class:`ModeReport`,
:class:`HomeReport`, :class:`LinkEvent` and the battery's
:class:`~uav_comm_planner.vehicle.mavlink.battery.BatteryReport` (BATTERY_STATUS, asked at
its own rate, and SYS_STATUS) objects through ``on_event``, which must be quick
and thread-safe (a queue push). Uploads are queued with :meth:`VehicleBridge.upload`; the
newest waiting mission replaces an older one that has not started. An upload is verified by
reading the mission back (:func:`~uav_comm_planner.vehicle.mavlink.link.upload_and_verify`)
and, when asked, followed by MISSION_SET_CURRENT so that a vehicle in flight goes on from that
item instead of restarting. ``VehicleBridge.ending`` sends the vehicle home, down or into its
hold mode from the thread. A mission whose home or first waypoint is farther than
``home_limit_m`` from the vehicle's home (or position) is refused before it is uploaded
(:mod:`.home`); one queued before the vehicle has told either waits for it.

Without ``home`` the bridge follows the vehicle: the first HOME_POSITION it hears is the
planning frame's origin, and no position is handed on before it.

On each connection the vehicle's limit parameters are read (:mod:`.parameters`, from the
connection's message hook: the telemetry is never held up for them) and handed on as a
:class:`~uav_comm_planner.vehicle.limits.VehicleParameters`.

Faults of the link: a connection the vehicle closes (EOF) or resets, and a link on which
nothing arrives for :data:`SILENCE_S` (wall clock, counted only while the thread reads, so a
stalled process is not taken for a silent vehicle), end the connection; the thread connects
again with backoff, in autopilot time as the last connection's clock ran (a simulator at a
speed-up is asked as often per second of its flight as a real vehicle). During an upload
the same silence ends it too (a :class:`~.link.LinkWatch` on the connection), and so does
stopping the bridge. Each change of state is one event: 'lost'
once when the link goes down (whatever the reconnection attempts meet then), 'connected' when
it is up again. A mission whose upload the loss cut (a
:class:`~uav_comm_planner.errors.VehicleLinkLostError` or any OSError, in any step: fence,
mission, read-back, MISSION_SET_CURRENT) is uploaded again once the link is back; a refusal
is said and not sent again. A gap of more than
:data:`TELEMETRY_GAP_S` of autopilot time between two positions is one 'gap' event.
A wind estimate carries the time of the latest position; one that comes on a connection before
its first position (whose time is not known yet: WIND carries none) is held, the latest only,
and handed on with that position's time.
An upload may carry fence items (:mod:`.fence`): they go first, each time they differ from the
fence the vehicle was last given on this connection, and are read back too.

Times are the autopilot's (``time_boot_ms`` / 1000, seconds), never the wall clock.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math
import threading
import time
from typing import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike
from pymavlink import mavutil

from uav_comm_planner.errors import VehicleLinkError, VehicleLinkLostError
from uav_comm_planner.vehicle.geodesy import geodetic_to_enu, Home
from uav_comm_planner.vehicle.limits import VehicleParameters
from uav_comm_planner.vehicle.mavlink.battery import (battery_of, BatteryReport, EndRequest,
                                                      request_battery)
from uav_comm_planner.vehicle.mavlink.guided import StreamEvent, TargetStream
from uav_comm_planner.vehicle.mavlink.home import (HOME_DISTANCE_LIMIT_M, home_of,
                                                   mission_far_from_vehicle, position_of,
                                                   request_home)
from uav_comm_planner.vehicle.mavlink.items import DEGREES_E7, MissionItem
from uav_comm_planner.vehicle.mavlink.link import (check_link, connect, LinkSettings,
                                                   LinkWatch, SILENCE_S, upload_and_verify,
                                                   vehicle_seq, WATCH_POLL_S)

MAV = mavutil.mavlink
#: Telemetry rate asked of the autopilot (per second of autopilot time).
TELEMETRY_RATE_HZ = 10.0
#: Pause before connecting again after a lost or refused link, seconds of autopilot time (as
#: the last connection's clock ran against the wall clock; wall seconds before any).
RECONNECT_PAUSE_S = 1.0
#: The pause doubles after each failure in a row, up to this many seconds: a vehicle in flight
#: whose link comes back is found again within this (autopilot time, as above).
MAX_RECONNECT_PAUSE_S = 8.0
#: The shortest pause, wall clock seconds, whatever the autopilot's clock rate.
MIN_RECONNECT_PAUSE_S = 0.05
#: A connection's clock rate is measured over at least this many wall seconds of positions.
CLOCK_RATE_SPAN_S = 1.0
#: Positions further apart than this (autopilot seconds) are a gap in the telemetry, said once.
TELEMETRY_GAP_S = 2.0
#: HOME_POSITION is asked for again this often (wall clock) until the vehicle has told it.
HOME_REQUEST_S = 1.0
#: A mission waiting this long (wall clock) for the vehicle's home or position is said once.
HOME_WAIT_REPORT_S = 10.0
#: How long MISSION_SET_CURRENT waits for MISSION_CURRENT to confirm, per try (wall clock).
SET_CURRENT_TIMEOUT_S = 1.0
SET_CURRENT_TRIES = 5
#: Wind estimates asked of the autopilot (per second of autopilot time).
WIND_RATE_HZ = 2.0
#: Messages handed on at the time of the latest position: the wind, the battery.
TIMED_MESSAGES = frozenset({'WIND', 'WIND_COV', 'BATTERY_STATUS', 'SYS_STATUS'})


@dataclass(frozen=True)
class Position:
    """The vehicle at east, north metres from home, ``up_m`` above home, at ``time_s``,
    moving at ``speed_mps`` (the norm of its velocity, vertical included; NaN unknown)."""

    time_s: float
    east_m: float
    north_m: float
    up_m: float
    speed_mps: float = math.nan


@dataclass(frozen=True)
class MissionProgressReport:
    """MISSION_CURRENT: the item the vehicle flies to (``seq``) at ``time_s`` (last seen)."""

    time_s: float
    seq: int


@dataclass(frozen=True)
class ModeReport:
    """The vehicle's flight mode as its heartbeat names it ('AUTO', 'GUIDED', 'BRAKE' on
    ArduCopter; 'MISSION', 'OFFBOARD' on PX4) at ``time_s`` (its latest position's time)."""

    time_s: float
    mode: str


@dataclass(frozen=True)
class HomeReport:
    """The vehicle's home; ``adopted`` when it became the planning frame's origin."""

    home: Home
    adopted: bool


@dataclass(frozen=True)
class LinkEvent:
    """Something the link did: ``kind`` is 'connected', 'uploaded', 'error' (an upload or a
    connect refused), 'lost' (the link went down), 'gap' (a telemetry gap of ``seconds`` of
    autopilot time); ``tag`` names the upload it concerns (what :meth:`VehicleBridge.upload`
    was given)."""

    kind: str
    message: str
    tag: object = None
    seconds: float = math.nan


@dataclass(frozen=True)
class Wind:
    """The autopilot's wind estimate at ``time_s``: the air's velocity east and north, m/s
    (where the air moves to; ArduPilot's WIND gives where it comes from, PX4's WIND_COV the
    velocity north-east-down)."""

    time_s: float
    east_mps: float
    north_mps: float


Event = (Position | MissionProgressReport | ModeReport | HomeReport | LinkEvent | Wind
         | StreamEvent | BatteryReport | VehicleParameters)

#: Heartbeat modes in which the vehicle flies its mission or the node's targets.
MISSION_MODES = frozenset({'AUTO', 'GUIDED', 'MISSION', 'OFFBOARD'})


@dataclass(frozen=True)
class _Upload:
    items: tuple[MissionItem, ...]
    current_seq: int | None
    tag: object
    fence: tuple[MissionItem, ...] | None = None


def request_telemetry(link, rate_hz: float = TELEMETRY_RATE_HZ) -> None:
    """Ask the autopilot for GLOBAL_POSITION_INT and MISSION_CURRENT at ``rate_hz`` (per second
    of autopilot time), and for BATTERY_STATUS at its own rate."""
    for message_id in (MAV.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
                       MAV.MAVLINK_MSG_ID_MISSION_CURRENT):
        link.mav.command_long_send(link.target_system, link.target_component,
                                   MAV.MAV_CMD_SET_MESSAGE_INTERVAL, 0, message_id,
                                   1e6 / rate_hz, 0, 0, 0, 0, 0)
    request_battery(link)


#: The wind estimates asked for: ArduPilot's WIND (168), PX4's WIND_COV (231).
WIND_MESSAGE_IDS = (168, MAV.MAVLINK_MSG_ID_WIND_COV)


def request_wind(link, rate_hz: float) -> None:
    """Ask for the autopilot's wind estimate at ``rate_hz`` (one of the two messages is
    refused by each autopilot; that refusal is harmless)."""
    for message_id in WIND_MESSAGE_IDS:
        link.mav.command_long_send(link.target_system, link.target_component,
                                   MAV.MAV_CMD_SET_MESSAGE_INTERVAL, 0, message_id,
                                   1e6 / rate_hz, 0, 0, 0, 0, 0)


def wind_of(message, time_s: float) -> Wind | None:
    """A WIND or WIND_COV message as the air's east-north velocity; None when it holds no
    estimate: NaN, or exactly 0 m/s, which is what an autopilot that does not estimate the wind
    sends (ArduCopter without its drag model: speed 0, direction -180)."""
    if message.get_type() == 'WIND':
        towards = math.radians(message.direction + 180.0)
        east = message.speed * math.sin(towards)
        north = message.speed * math.cos(towards)
    else:
        east, north = message.wind_y, message.wind_x
    if not (math.isfinite(east) and math.isfinite(north)) or east == north == 0.0:
        return None
    return Wind(time_s, float(east), float(north))


def global_position_enu(latitude_e7: ArrayLike, longitude_e7: ArrayLike,
                        relative_alt_mm: ArrayLike,
                        home: Home) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """GLOBAL_POSITION_INT positions (``lat``, ``lon`` in 1e-7 degree, ``relative_alt`` in mm;
    one message's or arrays of many) as east, north metres from ``home`` and metres above
    home."""
    east, north, _ = geodetic_to_enu(np.asarray(latitude_e7) / DEGREES_E7,
                                     np.asarray(longitude_e7) / DEGREES_E7, home.altitude_m,
                                     home)
    return east, north, np.asarray(relative_alt_mm) / 1000.0


class VehicleBridge:
    """Telemetry and mission uploads for one vehicle at ``url``, on a thread of its own
    (module docstring); ``home`` None follows the vehicle's home."""

    def __init__(self, url: str, home: Home | None, on_event: Callable[[Event], None], *,
                 settings: LinkSettings = LinkSettings(), rate_hz: float = TELEMETRY_RATE_HZ,
                 connect_timeout_s: float = 30.0, stream: TargetStream | None = None,
                 home_limit_m: float = HOME_DISTANCE_LIMIT_M) -> None:
        self.url = url
        self.home = home
        self._on_event = on_event
        self._settings, self._rate_hz, self._connect_timeout_s = (settings, rate_hz,
                                                                  connect_timeout_s)
        #: The streamed trajectory, run on this thread at every position (None: no stream).
        self.stream = stream
        self._home_limit_m, self._lock = home_limit_m, threading.Lock()
        self._waiting: _Upload | None = None
        self._stop, self.ending = threading.Event(), EndRequest()
        #: What the vehicle told of itself: its home, its latest latitude and longitude.
        self.vehicle_home: Home | None = None
        self._vehicle_position: tuple[float, float] | None = None
        self._last_position_s = math.nan
        self._gap_cause, self._clock = '', _ConnectionClock(on_event)
        self._thread = threading.Thread(target=self._run, name='uav_comm_planner.vehicle',
                                        daemon=True)
        self._thread.start()

    def upload(self, items: Sequence[MissionItem], *, current_seq: int | None = None,
               tag: object = None, fence: Sequence[MissionItem] | None = None) -> None:
        """Queue ``items`` (after the fence items ``fence``) for upload, replacing a waiting one;
        then, with ``current_seq``, make that item the vehicle's current one."""
        with self._lock:
            self._waiting = _Upload(tuple(items), current_seq, tag, fence and tuple(fence))

    def stop(self, timeout_s: float = 5.0) -> None:
        """End the thread and close the connection."""
        self._stop.set()
        self._thread.join(timeout_s)

    def _run(self) -> None:
        # down: what was said of the link being down ('' while up or never up).
        down, down_since, failures = '', None, 0
        while not self._stop.is_set():
            try:
                link = connect(self.url, timeout_s=self._connect_timeout_s,
                               should_stop=self._stop.is_set, parameters=self._on_event)
            except VehicleLinkError as exc:
                if not down:            # said once, not at every retry
                    down = str(exc)
                    self._on_event(LinkEvent('error', f'{exc}; retrying'))
                # Backoff: a vehicle that stays away is asked less and less often.
                self._stop.wait(reconnect_pause_s(failures, self._clock.rate))
                failures += 1
                continue
            try:
                again = '' if down_since is None else \
                    f' again after {time.monotonic() - down_since:.1f} s down'
                self._on_event(LinkEvent('connected', f'vehicle link up{again} on {self.url}'))
                down, down_since, failures = '', None, 0
                self._serve(link)
            except (VehicleLinkError, OSError) as exc:
                down, down_since = str(exc), time.monotonic()
                self._gap_cause = ' (the link was down)'
                self._on_event(LinkEvent('lost', f'vehicle link lost: {exc}; reconnecting'))
                self._stop.wait(reconnect_pause_s(failures, self._clock.rate))
                failures += 1
            finally:
                link.close()

    def _serve(self, link) -> None:
        link.watch = LinkWatch(silence_s=SILENCE_S, should_stop=self._stop.is_set)
        request_telemetry(link, self._rate_hz)
        request_wind(link, WIND_RATE_HZ)
        heard = asked = time.monotonic()
        request_home(link)
        clock = self._clock = _ConnectionClock(self._on_event, self._clock.rate)
        mode = None
        waiting_since = None
        while not self._stop.is_set():
            now = time.monotonic()
            if self.vehicle_home is None and now - asked >= HOME_REQUEST_S:
                request_home(link)
                asked = now
            self.ending.send(link)
            job = self._next_job()
            if job is None and self._waiting is not None:
                if waiting_since is None:
                    waiting_since = now
                elif now - waiting_since > HOME_WAIT_REPORT_S:
                    waiting_since = math.inf        # said once
                    self._on_event(LinkEvent(
                        'error', f'the mission waits: the vehicle has told neither its home '
                                 f'nor its position for {HOME_WAIT_REPORT_S:g} s'))
            if job is not None:
                waiting_since = None
                if self.stream is not None:     # a stop of the stream acts on the old mission
                    self.stream.before_upload(link, clock.time_s, job.tag)
                verified = self._upload(link, job)
                if self.stream is not None:
                    self.stream.uploaded(link, clock.time_s, job.tag, verified)
                request_telemetry(link, self._rate_hz)
                heard = time.monotonic()
                self._gap_cause = ' (the link read no telemetry during an upload)'
                continue
            message = link.recv_match(blocking=True, timeout=0.05)
            if message is None:
                if time.monotonic() - heard > SILENCE_S:
                    raise VehicleLinkError(f'nothing heard from the vehicle for '
                                           f'{SILENCE_S:g} s')
                continue
            kind = message.get_type()
            if kind == 'BAD_DATA' or message.get_srcSystem() != link.target_system:
                continue
            heard = time.monotonic()
            if kind in TIMED_MESSAGES:
                clock.timed(message)
            elif kind == 'HEARTBEAT':
                if self.stream is not None:
                    self.stream.on_heartbeat(message)
                if link.probably_vehicle_heartbeat(message) \
                        and (name := mavutil.mode_string_v10(message)) != mode:
                    mode = name
                    self._on_event(ModeReport(clock.time_s, mode))
            elif kind == 'GLOBAL_POSITION_INT':
                time_s = clock.position(message.time_boot_ms / 1000.0)
                if self._position(message, time_s) and self.stream is not None:
                    self.stream.tick(link, time_s)
            elif kind == 'MISSION_CURRENT':
                self._on_event(MissionProgressReport(clock.time_s, int(message.seq)))
            elif kind == 'HOME_POSITION':
                self._heard_home(message)
        if self.stream is not None:
            self.stream.close(link)

    def _position(self, message, time_s: float) -> bool:
        """Hand the position on; whether the vehicle has a position (a fix) at all."""
        where = position_of(message)
        if where is None:
            return False        # no position yet: autopilots send 0, 0 before a fix
        self._vehicle_position = where
        previous_s, self._last_position_s = self._last_position_s, time_s
        if time_s - previous_s > TELEMETRY_GAP_S:
            self._on_event(LinkEvent('gap', f'telemetry gap: no position from the vehicle '
                                            f'for {time_s - previous_s:.1f} s of autopilot '
                                            f'time ({previous_s:.1f} s to {time_s:.1f} s)'
                                            f'{self._gap_cause}',
                                     seconds=time_s - previous_s))
        self._gap_cause = ''
        if self.home is None:
            return True         # following the vehicle's home: not told yet
        east, north, up = global_position_enu(message.lat, message.lon, message.relative_alt,
                                              self.home)
        if self.stream is not None:         # where a stream after a gap takes its path up
            self.stream.position_m = np.array([float(east), float(north)])
        speed = math.sqrt(message.vx ** 2 + message.vy ** 2 + message.vz ** 2) / 100.0
        self._on_event(Position(time_s, float(east), float(north), float(up), speed))
        return True

    def _heard_home(self, message) -> None:
        home = home_of(message)
        if home is None or home == self.vehicle_home:
            return
        self.vehicle_home = home
        adopted = self.home is None
        if adopted:
            self.home = home
        if self.stream is not None:     # its targets are in the same frame
            self.stream.home, self.stream.vehicle_home = self.home, home
        self._on_event(HomeReport(home, adopted))

    def _next_job(self) -> _Upload | None:
        """The waiting upload, once the vehicle has told its home or position (the check)."""
        known = self.vehicle_home is not None or self._vehicle_position is not None
        if not (known or math.isinf(self._home_limit_m)):
            return None
        with self._lock:
            job, self._waiting = self._waiting, None
        return job

    def _upload(self, link, job: _Upload) -> bool:
        """Upload ``job``; whether the vehicle holds it (a loss of the link raises)."""
        reason = mission_far_from_vehicle(job.items, self.vehicle_home, self._vehicle_position,
                                          self._home_limit_m)
        if reason:
            self._on_event(LinkEvent('error', f'mission upload refused: {reason}', job.tag))
            return False
        try:
            note = _put_on_vehicle(link, job, self._settings)
        except (VehicleLinkLostError, OSError):
            if self._stop.is_set():
                return False                # the bridge is being stopped: nothing to say
            with self._lock:                # uploaded again once the link is back
                self._waiting = self._waiting or job
            raise
        except VehicleLinkError as exc:
            self._on_event(LinkEvent('error', f'mission upload failed: {exc}', job.tag))
            return False
        self._on_event(LinkEvent('uploaded', f'mission of {len(job.items)} items uploaded '
                                             f'and read back{note}', job.tag))
        return True


def reconnect_pause_s(failures: int, clock_rate: float | None) -> float:
    """Wall seconds to wait before connecting again after ``failures`` failures in a row: the
    backoff in autopilot time, at ``clock_rate`` autopilot seconds per wall second (a
    simulator's speed-up; None: unknown, 1)."""
    autopilot_s = min(RECONNECT_PAUSE_S * 2 ** min(failures, 16), MAX_RECONNECT_PAUSE_S)
    return max(autopilot_s / (clock_rate or 1.0), MIN_RECONNECT_PAUSE_S)


class _ConnectionClock:
    """The autopilot's time on one connection, that of its latest position (0 before any); a
    wind estimate heard before the first position (WIND carries no time) is held, the latest
    only, and handed on with that position's time. ``rate`` is the autopilot seconds per wall
    second its positions showed (over CLOCK_RATE_SPAN_S at least; else the one given)."""

    def __init__(self, on_event: Callable[[Event], None], rate: float | None = None) -> None:
        self.time_s = 0.0
        self.rate = rate
        self._on_event = on_event
        self._timed = False
        self._held: Wind | None = None
        self._first: tuple[float, float] | None = None

    def position(self, time_s: float) -> float:
        """A position's time, which it returns; the first hands on the wind held."""
        self.time_s, now = time_s, time.monotonic()
        if self._first is None or time_s < self._first[1]:
            self._first = (now, time_s)     # the first, or a clock restarted
        elif now - self._first[0] >= CLOCK_RATE_SPAN_S:
            self.rate = max(1.0, (time_s - self._first[1]) / (now - self._first[0]))
        if not self._timed:
            self._timed = True
            if self._held is not None:
                self._on_event(replace(self._held, time_s=time_s))
        return time_s

    def timed(self, message) -> None:
        """A message of :data:`TIMED_MESSAGES`: a battery's report handed on at the latest
        position's time; a WIND or WIND_COV message too, or held before the first."""
        if message.get_type() in ('BATTERY_STATUS', 'SYS_STATUS'):
            if (report := battery_of(message, self.time_s)) is not None:
                self._on_event(report)
            return
        wind = wind_of(message, self.time_s)
        if wind is not None and self._timed:
            self._on_event(wind)
        elif wind is not None:
            self._held = wind


def _put_on_vehicle(link, job: _Upload, settings: LinkSettings) -> str:
    """The fence first, the mission read back, then its current item; the note for the
    'uploaded' event. Raises VehicleLinkError (VehicleLinkLostError or OSError: the link went
    down)."""
    fence, note = upload_fence(link, job.fence, settings), ''
    upload_and_verify(link, job.items, settings)
    if job.current_seq is not None:
        current = vehicle_seq(link, job.current_seq)
        set_current(link, current)
        note = f'; current item {current}'
    return fence + note


def upload_fence(link, fence: Sequence[MissionItem] | None, settings: LinkSettings) -> str:
    """Upload the fence items ``fence`` (None or empty: none) on ``link`` and read them back,
    unless they are what this connection last gave the vehicle (a vehicle connected again is
    given them again); returns the note for the upload's event."""
    if not fence or getattr(link, 'fence_held', None) == tuple(fence):
        return ''
    link.fence_held = None
    upload_and_verify(link, fence, settings, mission_type=MAV.MAV_MISSION_TYPE_FENCE)
    link.fence_held = tuple(fence)
    return f' after a fence of {len(fence)} items'


def set_current(link, seq: int) -> None:
    """MISSION_SET_CURRENT until MISSION_CURRENT reports ``seq``; raises VehicleLinkError
    (VehicleLinkLostError when the link goes down meanwhile)."""
    for _ in range(SET_CURRENT_TRIES):
        deadline = time.monotonic() + SET_CURRENT_TIMEOUT_S
        try:
            link.mav.mission_set_current_send(link.target_system, link.target_component, seq)
            while (left := deadline - time.monotonic()) > 0:
                check_link(link)
                message = link.recv_match(type='MISSION_CURRENT', blocking=True,
                                          timeout=min(left, WATCH_POLL_S))
                if message is not None and message.seq == seq:
                    return
        except (OSError, ConnectionError) as exc:
            raise VehicleLinkLostError(f'link lost while making item {seq} current: '
                                       f'{exc}') from exc
    raise VehicleLinkError(f'the vehicle did not make item {seq} current after '
                           f'{SET_CURRENT_TRIES} tries of {SET_CURRENT_TIMEOUT_S:g} s')


__all__ = ['HomeReport', 'LinkEvent', 'MISSION_MODES', 'MissionProgressReport', 'ModeReport',
           'Position', 'VehicleBridge', 'Wind', 'global_position_enu', 'request_telemetry',
           'request_wind', 'set_current', 'upload_fence', 'wind_of']
