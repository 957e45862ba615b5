"""The vehicle on its own thread: telemetry in, missions out, over one MAVLink connection.

A :class:`VehicleBridge` owns the connection (pymavlink's are not thread-safe) and runs on a
daemon thread, never on the caller's: it connects (waiting for a heartbeat, again after a lost
link), asks for GLOBAL_POSITION_INT and MISSION_CURRENT at ``rate_hz`` (autopilot time), turns
each position into the planning frame through ``home`` and hands the caller
:class:`Position`, :class:`MissionProgressReport` and :class:`LinkEvent` objects through
``on_event``, which must be quick and thread-safe (a queue push). Uploads are queued with
:meth:`VehicleBridge.upload`; the newest waiting mission replaces an older one that has not
started. An upload is verified by reading the mission back
(:func:`~uav_comm_planner.vehicle.mavlink.link.upload_and_verify`) and, when asked, followed by
MISSION_SET_CURRENT so that a vehicle in flight goes on from that item instead of restarting.

Times are the autopilot's (``time_boot_ms`` / 1000, seconds), never the wall clock.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
import threading
import time
from typing import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike
from pymavlink import mavutil

from uav_comm_planner.errors import VehicleLinkError
from uav_comm_planner.vehicle.geodesy import geodetic_to_enu, Home
from uav_comm_planner.vehicle.mavlink.guided import StreamEvent, TargetStream
from uav_comm_planner.vehicle.mavlink.items import DEGREES_E7, MissionItem
from uav_comm_planner.vehicle.mavlink.link import (connect, has_home_row, LinkSettings,
                                                   upload_and_verify)

MAV = mavutil.mavlink
#: Telemetry rate asked of the autopilot (per second of autopilot time).
TELEMETRY_RATE_HZ = 10.0
#: Pause before connecting again after a lost or refused link, seconds (wall clock).
RECONNECT_PAUSE_S = 1.0
#: The pause doubles after each failure in a row, up to this many seconds.
MAX_RECONNECT_PAUSE_S = 30.0
#: How long MISSION_SET_CURRENT waits for MISSION_CURRENT to confirm, per try (wall clock).
SET_CURRENT_TIMEOUT_S = 1.0
SET_CURRENT_TRIES = 5
#: Wind estimates asked of the autopilot (per second of autopilot time).
WIND_RATE_HZ = 2.0


@dataclass(frozen=True)
class Position:
    """The vehicle at east, north metres from home, ``up_m`` above home, at ``time_s``."""

    time_s: float
    east_m: float
    north_m: float
    up_m: float


@dataclass(frozen=True)
class MissionProgressReport:
    """MISSION_CURRENT: the item the vehicle flies to (``seq``) at ``time_s`` (last seen)."""

    time_s: float
    seq: int


@dataclass(frozen=True)
class LinkEvent:
    """Something the link did: ``kind`` is 'connected', 'uploaded', 'error'; ``tag`` names the
    upload it concerns (what :meth:`VehicleBridge.upload` was given)."""

    kind: str
    message: str
    tag: object = None


@dataclass(frozen=True)
class Wind:
    """The autopilot's wind estimate at ``time_s``: the air's velocity east and north, m/s
    (where the air moves to; ArduPilot's WIND gives where it comes from, PX4's WIND_COV the
    velocity north-east-down)."""

    time_s: float
    east_mps: float
    north_mps: float


Event = Position | MissionProgressReport | LinkEvent | Wind | StreamEvent


@dataclass(frozen=True)
class _Upload:
    items: tuple[MissionItem, ...]
    current_seq: int | None
    tag: object


def request_telemetry(link, rate_hz: float = TELEMETRY_RATE_HZ) -> None:
    """Ask the autopilot for GLOBAL_POSITION_INT and MISSION_CURRENT at ``rate_hz`` (per second
    of autopilot time)."""
    for message_id in (MAV.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
                       MAV.MAVLINK_MSG_ID_MISSION_CURRENT):
        link.mav.command_long_send(link.target_system, link.target_component,
                                   MAV.MAV_CMD_SET_MESSAGE_INTERVAL, 0, message_id,
                                   1e6 / rate_hz, 0, 0, 0, 0, 0)


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
    """Telemetry and mission uploads for one vehicle at ``url``, on a thread of its own."""

    def __init__(self, url: str, home: Home, on_event: Callable[[Event], None], *,
                 settings: LinkSettings = LinkSettings(), rate_hz: float = TELEMETRY_RATE_HZ,
                 connect_timeout_s: float = 30.0, stream: TargetStream | None = None) -> None:
        self.url = url
        self.home = home
        self._on_event = on_event
        self._settings = settings
        self._rate_hz = rate_hz
        self._connect_timeout_s = connect_timeout_s
        #: The streamed trajectory, run on this thread at every position (None: no stream).
        self.stream = stream
        self._lock = threading.Lock()
        self._waiting: _Upload | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='uav_comm_planner.vehicle',
                                        daemon=True)
        self._thread.start()

    def upload(self, items: Sequence[MissionItem], *, current_seq: int | None = None,
               tag: object = None) -> None:
        """Queue ``items`` for upload (replacing a waiting one); then, with ``current_seq``,
        make that item the vehicle's current one."""
        with self._lock:
            self._waiting = _Upload(tuple(items), current_seq, tag)

    def stop(self, timeout_s: float = 5.0) -> None:
        """End the thread and close the connection."""
        self._stop.set()
        self._thread.join(timeout_s)

    def _run(self) -> None:
        refused = ''
        failures = 0
        while not self._stop.is_set():
            # Backoff: a vehicle that stays away is asked less and less often.
            pause_s = min(RECONNECT_PAUSE_S * 2 ** min(failures, 16), MAX_RECONNECT_PAUSE_S)
            try:
                link = connect(self.url, timeout_s=self._connect_timeout_s,
                               should_stop=self._stop.is_set)
            except VehicleLinkError as exc:
                if str(exc) != refused:            # said once, not at every retry
                    refused = str(exc)
                    self._on_event(LinkEvent('error', f'{exc}; retrying'))
                failures += 1
                self._stop.wait(pause_s)
                continue
            refused = ''
            try:
                self._on_event(LinkEvent('connected', f'vehicle link up on {self.url}'))
                failures = 0
                self._serve(link)
            except VehicleLinkError as exc:
                self._on_event(LinkEvent('error', f'vehicle link: {exc}'))
                failures += 1
                self._stop.wait(pause_s)
            except (OSError, ConnectionError) as exc:
                self._on_event(LinkEvent('error', f'vehicle link lost: {exc}'))
                failures += 1
                self._stop.wait(pause_s)
            finally:
                link.close()

    def _serve(self, link) -> None:
        request_telemetry(link, self._rate_hz)
        request_wind(link, WIND_RATE_HZ)
        latest_time_s = 0.0
        while not self._stop.is_set():
            with self._lock:
                job, self._waiting = self._waiting, None
            if job is not None:
                self._upload(link, job)
                request_telemetry(link, self._rate_hz)
                continue
            message = link.recv_match(type=['GLOBAL_POSITION_INT', 'MISSION_CURRENT',
                                            'HEARTBEAT', 'WIND', 'WIND_COV'],
                                      blocking=True, timeout=0.05)
            if message is None:
                continue
            kind = message.get_type()
            if kind in ('WIND', 'WIND_COV'):
                wind = wind_of(message, latest_time_s)
                if wind is not None:
                    self._on_event(wind)
                continue
            if kind == 'HEARTBEAT':
                if self.stream is not None and message.get_srcSystem() == link.target_system:
                    self.stream.on_heartbeat(message)
                continue
            if kind == 'GLOBAL_POSITION_INT':
                latest_time_s = message.time_boot_ms / 1000.0
                if message.lat == 0 and message.lon == 0:
                    continue            # no position yet: autopilots send 0, 0 before a fix
                east, north, up = global_position_enu(message.lat, message.lon,
                                                      message.relative_alt, self.home)
                self._on_event(Position(latest_time_s, float(east), float(north), float(up)))
                if self.stream is not None:
                    self.stream.tick(link, latest_time_s)
            else:
                self._on_event(MissionProgressReport(latest_time_s, int(message.seq)))
        if self.stream is not None:
            self.stream.close(link)

    def _upload(self, link, job: _Upload) -> None:
        try:
            upload_and_verify(link, job.items, self._settings)
            note = ''
            if job.current_seq is not None:
                # Sequence numbers count the home row, which a PX4 mission has not.
                current = job.current_seq - (0 if has_home_row(link) else 1)
                set_current(link, current)
                note = f'; current item {current}'
        except VehicleLinkError as exc:
            self._on_event(LinkEvent('error', f'mission upload failed: {exc}', job.tag))
            if 'link lost' in str(exc):
                raise
            return
        self._on_event(LinkEvent('uploaded', f'mission of {len(job.items)} items uploaded '
                                             f'and read back{note}', job.tag))


def set_current(link, seq: int) -> None:
    """MISSION_SET_CURRENT until MISSION_CURRENT reports ``seq``; raises VehicleLinkError."""
    for _ in range(SET_CURRENT_TRIES):
        link.mav.mission_set_current_send(link.target_system, link.target_component, seq)
        deadline = time.monotonic() + SET_CURRENT_TIMEOUT_S
        while (left := deadline - time.monotonic()) > 0:
            message = link.recv_match(type='MISSION_CURRENT', blocking=True, timeout=left)
            if message is not None and message.seq == seq:
                return
    raise VehicleLinkError(f'the vehicle did not make item {seq} current after '
                           f'{SET_CURRENT_TRIES} tries of {SET_CURRENT_TIMEOUT_S:g} s')


__all__ = ['LinkEvent', 'MissionProgressReport', 'Position', 'VehicleBridge', 'Wind',
           'global_position_enu', 'request_telemetry', 'request_wind', 'set_current', 'wind_of']
