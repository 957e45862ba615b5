"""A small MAVLink peer on 127.0.0.1 that plays a vehicle, well or badly, for the link's tests
and the fuzz target (``test/fuzz/fuzz_vehicle.py``).

It listens on a free TCP port (``url``), takes one connection at a time and, by ``behaviour``:

- ``good``: heartbeats, the mission protocol done right, the mission read back as stored;
- ``mute``: accepts the connection and never sends a byte (no heartbeat);
- ``silent``: heartbeats, never answers a mission message;
- ``loop``: asks for item 0 again after every item it receives;
- ``out_of_range``: asks for an item past the end of the mission;
- ``wrong_ack``: answers the mission count with a refusal drawn from ``seed``;
- ``wrong_count``: stores the mission, reports one item more on read-back;
- ``wrong_item``: stores the mission, reads its last item back moved by a degree (home, the
  only item of a one-item mission, as another command);
- ``slow``: the mission protocol done right, each answer ``delay_s`` late;
- ``garbage``: heartbeats among seeded random bytes and random MAVLink messages, answering
  mission messages with random seqs, counts and results.

Every behaviour that answers tells its ``home`` (HOME_POSITION) when asked. With
``positions`` it also sends GLOBAL_POSITION_INT at 10 Hz (its boot time is the wall clock
since it started, times ``speedup``: a simulator's), at ``where`` (latitude, longitude,
metres above home; home at 10 m unless set), from ``positions_after_s`` after each connection
on; with ``wind`` (speed m/s, direction it comes from, degrees) a WIND message after every
heartbeat. ``mode`` (None: no mode) is the
ArduCopter mode number its heartbeat shows; SET_MODE changes it. MISSION_SET_CURRENT is
answered with MISSION_CURRENT. A PARAM_REQUEST_READ of a name in ``parameters`` is answered
with its PARAM_VALUE, after ``parameter_drops`` requests left unanswered; the names put in
``announce`` are sent unasked. ``log`` lists what it received, in order: the message type
(with the item or mode number for MISSION_COUNT, MISSION_SET_CURRENT and SET_MODE).
:meth:`hang_up` closes the connection it serves (the link sees EOF), and ``hang_up_on`` (a
message type) does once, when that message arrives; while ``quiet`` is set it sends nothing
and answers nothing (a silent link), and ``quiet_on`` (a message type) sets ``quiet`` when
that message arrives (at ``quiet_at``, monotonic).
"""

from __future__ import annotations

import random
import socket
import threading
import time

# MAVLink 2, as ArduPilot speaks it: the link under test switches to it on the first packet.
from pymavlink.dialects.v20 import ardupilotmega as MAV

from uav_comm_planner.vehicle.mavlink.telemetry import LinkEvent

BEHAVIOURS = ('good', 'mute', 'silent', 'loop', 'out_of_range', 'wrong_ack', 'wrong_count',
              'wrong_item', 'slow', 'garbage', 'impatient')
HEARTBEAT_S = 0.1


class Events:
    """What a vehicle bridge hands on (its ``on_event``), with the monotonic time of each."""

    def __init__(self) -> None:
        self.seen: list[tuple[float, object]] = []

    def __call__(self, event) -> None:
        self.seen.append((time.monotonic(), event))

    def links(self, kind: str) -> list:
        """The (time, LinkEvent) pairs of ``kind``."""
        return [(t, e) for t, e in self.seen if isinstance(e, LinkEvent) and e.kind == kind]

    def wait(self, condition, what: str, timeout_s: float = 10.0) -> None:
        deadline = time.monotonic() + timeout_s
        while not condition():
            assert time.monotonic() < deadline, f'no {what} within {timeout_s} s'
            time.sleep(0.02)


class FakeVehicle:
    """A vehicle on ``url`` (module docstring); :meth:`close` stops it and joins its thread."""

    def __init__(self, behaviour: str = 'good', *, seed: int = 0, delay_s: float = 0.3,
                 home: tuple[float, float, float] = (47.0, 8.0, 400.0),
                 positions: bool = False) -> None:
        if behaviour not in BEHAVIOURS:
            raise ValueError(f'unknown behaviour {behaviour!r}')
        self.behaviour = behaviour
        self.home = home
        self.positions = positions
        self.where: tuple[float, float, float] = (home[0], home[1], 10.0)
        self.positions_after_s = 0.0
        self.speedup = 1.0
        self.wind: tuple[float, float] | None = None
        self.mode: int | None = None
        self.parameters: dict[str, float] = {}
        self.parameter_drops = 0
        #: Names whose PARAM_VALUE is sent at the next heartbeat, unasked (a set announced).
        self.announce: list[str] = []
        self.quiet = False
        self.quiet_on: str | None = None
        self.quiet_at: float | None = None
        self.hang_up_on: str | None = None
        self.log: list[tuple] = []
        self.connections = 0
        self._hang_up = threading.Event()
        self._booted = time.monotonic()
        self.delay_s = delay_s
        self.random = random.Random(seed)
        self.stored: list = []
        self._requested: int | None = None
        self.received = 0
        self._stop = threading.Event()
        self._server = socket.create_server(('127.0.0.1', 0))
        self._server.settimeout(0.05)
        self.port = self._server.getsockname()[1]
        self._thread = threading.Thread(target=self._run, name='fake-vehicle', daemon=True)
        self._thread.start()

    def reset(self, behaviour: str, *, seed: int = 0) -> None:
        """Play ``behaviour`` with a fresh ``seed`` and no mission from the next connection
        on (one vehicle serves many fuzz cases)."""
        if behaviour not in BEHAVIOURS:
            raise ValueError(f'unknown behaviour {behaviour!r}')
        self.behaviour = behaviour
        self.random = random.Random(seed)
        self.stored = []

    @property
    def url(self) -> str:
        return f'tcp:127.0.0.1:{self.port}'

    def hang_up(self) -> None:
        """Close the connection being served (the next one is served as before)."""
        self._hang_up.set()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5.0)
        self._server.close()

    def __enter__(self) -> FakeVehicle:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                connection, _ = self._server.accept()
            except (socket.timeout, OSError):
                continue
            self.connections += 1
            self._hang_up.clear()
            with connection:
                connection.settimeout(0.02)
                try:
                    self._serve(connection)
                except OSError:
                    pass

    def _serve(self, connection: socket.socket) -> None:
        mav = MAV.MAVLink(None, srcSystem=1, srcComponent=1)
        mav.robust_parsing = True
        self._mav, self._connection = mav, connection
        self._expected = 0
        next_beat = 0.0
        next_position = time.monotonic() + self.positions_after_s
        while not self._stop.is_set() and not self._hang_up.is_set():
            now = time.monotonic()
            if self.quiet:
                try:
                    if not connection.recv(4096):       # read and dropped
                        return
                except socket.timeout:
                    pass
                continue
            if self.positions and now >= next_position:
                latitude, longitude, up = self.where
                self._send(mav.global_position_int_encode(
                    int((now - self._booted) * self.speedup * 1000), round(latitude * 1e7),
                    round(longitude * 1e7), round((self.home[2] + up) * 1000),
                    round(up * 1000), 0, 0, 0, 0))
                next_position = now + 0.1
            if self.behaviour != 'mute' and now >= next_beat:
                flags, mode = ((0, 0) if self.mode is None
                               else (MAV.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, self.mode))
                self._send(mav.heartbeat_encode(MAV.MAV_TYPE_QUADROTOR,
                                                MAV.MAV_AUTOPILOT_ARDUPILOTMEGA, flags, mode, 0))
                if self.wind is not None:
                    speed, direction = self.wind
                    self._send(mav.wind_encode(direction, speed, 0.0))
                next_beat = now + HEARTBEAT_S
                while self.announce:
                    self._send_parameter(self.announce.pop(0))
                if self.behaviour == 'garbage':
                    self._garbage()
            try:
                data = connection.recv(4096)
            except socket.timeout:
                continue
            if not data:
                return
            for message in mav.parse_buffer(data) or []:
                self.received += 1
                self._note(message)
                kind = message.get_type()
                if kind == self.hang_up_on:
                    self.hang_up_on = None
                    return
                if kind == self.quiet_on:
                    self.quiet_on, self.quiet, self.quiet_at = None, True, time.monotonic()
                    break
                self._answer(message)

    def _note(self, message) -> None:
        kind = message.get_type()
        if kind in ('MISSION_COUNT', 'MISSION_SET_CURRENT', 'SET_MODE'):
            number = {'MISSION_COUNT': 'count', 'MISSION_SET_CURRENT': 'seq',
                      'SET_MODE': 'custom_mode'}[kind]
            self.log.append((kind, getattr(message, number)))
        else:
            self.log.append((kind,))

    def _send_parameter(self, name: str) -> None:
        """PARAM_VALUE of ``name`` (of :attr:`parameters`), as an autopilot answers a read or
        tells every link of a set (``announce``)."""
        names = list(self.parameters)
        self._send(self._mav.param_value_encode(name.encode(), self.parameters[name],
                                                MAV.MAV_PARAM_TYPE_REAL32, len(names),
                                                names.index(name)))

    def _send(self, message) -> None:
        self._connection.sendall(message.pack(self._mav))

    def _garbage(self) -> None:
        draw = self.random
        self._connection.sendall(bytes(draw.randrange(256) for _ in range(draw.randrange(64))))
        mav = self._mav
        choices = [
            lambda: mav.mission_request_int_encode(255, 0, draw.randrange(70000) % 65536, 0),
            lambda: mav.mission_ack_encode(255, 0, draw.randrange(256), 0),
            lambda: mav.mission_count_encode(255, 0, draw.randrange(65536), 0),
            lambda: mav.mission_item_int_encode(
                255, 0, draw.randrange(65536), draw.randrange(256), draw.randrange(65536), 0,
                1, *(draw.uniform(-1e38, 1e38) for _ in range(4)),
                draw.randrange(-2**31, 2**31), draw.randrange(-2**31, 2**31),
                draw.uniform(-1e38, 1e38), 0),
            lambda: mav.global_position_int_encode(
                draw.randrange(2**32), draw.randrange(-2**31, 2**31),
                draw.randrange(-2**31, 2**31), 0, draw.randrange(-2**31, 2**31), 0, 0, 0, 0),
        ]
        self._send(draw.choice(choices)())

    def _request(self, seq: int) -> None:
        """Ask for item ``seq``; an impatient vehicle (ArduPilot at a simulator's speed-up,
        whose 1 s resend is 50 ms of wall clock at 20) asks twice before the answer comes, so
        that the answer to its second request arrives as an item it did not ask for."""
        self._requested = seq
        for _ in range(2 if self.behaviour == 'impatient' else 1):
            self._send(self._mav.mission_request_int_encode(255, 0, seq, 0))

    def _answer(self, message) -> None:
        kind = message.get_type()
        behaviour = self.behaviour
        if behaviour in ('mute', 'silent'):
            return
        if behaviour == 'slow':
            time.sleep(self.delay_s)
        if behaviour == 'garbage':
            if kind.startswith('MISSION'):
                self._garbage()
            return
        mav = self._mav
        if kind == 'COMMAND_LONG' and (
                message.command == MAV.MAV_CMD_GET_HOME_POSITION
                or (message.command == MAV.MAV_CMD_REQUEST_MESSAGE
                    and int(message.param1) == MAV.MAVLINK_MSG_ID_HOME_POSITION)):
            latitude, longitude, altitude = self.home
            self._send(mav.home_position_encode(round(latitude * 1e7), round(longitude * 1e7),
                                                round(altitude * 1000), 0, 0, 0,
                                                [1, 0, 0, 0], 0, 0, 0))
        elif kind == 'SET_MODE':
            self.mode = int(message.custom_mode)
        elif kind == 'PARAM_REQUEST_READ' and message.param_id in self.parameters:
            if self.parameter_drops > 0:
                self.parameter_drops -= 1
                return
            self._send_parameter(message.param_id)
        elif kind == 'MISSION_SET_CURRENT':
            self._send(mav.mission_current_encode(message.seq))
        elif kind == 'MISSION_COUNT':
            if behaviour == 'wrong_ack':
                refusals = [r for r in MAV.enums['MAV_MISSION_RESULT'] if r != 0]
                self._send(mav.mission_ack_encode(255, 0, self.random.choice(refusals), 0))
                return
            self.stored = [None] * message.count
            first = message.count + 3 if behaviour == 'out_of_range' else 0
            self._request(first)
        elif kind == 'MISSION_ITEM_INT':
            if behaviour == 'impatient' and message.seq != self._requested:
                # ArduPilot's answer to an item it did not ask for: in a transfer, which goes
                # on, INVALID_SEQUENCE; after it, MAV_MISSION_ERROR.
                self._send(mav.mission_ack_encode(
                    255, 0, MAV.MAV_MISSION_ERROR if self._requested is None
                    else MAV.MAV_MISSION_INVALID_SEQUENCE, 0))
                return
            if 0 <= message.seq < len(self.stored):
                self.stored[message.seq] = message
            following = 0 if behaviour == 'loop' else message.seq + 1
            if following < len(self.stored):
                self._request(following)
            else:
                self._requested = None
                self._send(mav.mission_ack_encode(255, 0, MAV.MAV_MISSION_ACCEPTED, 0))
        elif kind == 'MISSION_REQUEST_LIST':
            extra = 1 if behaviour == 'wrong_count' else 0
            self._send(mav.mission_count_encode(255, 0, len(self.stored) + extra, 0))
        elif kind == 'MISSION_REQUEST_INT' and 0 <= message.seq < len(self.stored):
            item = self.stored[message.seq]
            if item is None:
                return
            x, command = item.x, item.command
            if behaviour == 'wrong_item' and message.seq == len(self.stored) - 1:
                # Home (row 0) is compared by its command alone, the others by place too.
                if message.seq == 0:
                    command = MAV.MAV_CMD_NAV_TAKEOFF
                else:
                    x += 10_000_000
            self._send(mav.mission_item_int_encode(
                255, 0, item.seq, item.frame, command, item.current, item.autocontinue,
                item.param1, item.param2, item.param3, item.param4, x, item.y, item.z, 0))
