"""The MAVLink link to a vehicle: connect, upload a mission or a fence and read it back.

Speaks the MAVLink mission protocol (MISSION_COUNT, MISSION_REQUEST_INT, MISSION_ITEM_INT,
MISSION_ACK), for the mission or the fence (``mission_type`` MAV_MISSION_TYPE_FENCE), over any
connection pymavlink opens: ``tcp:127.0.0.1:5760``, ``udpin:0.0.0.0:14550``,
``/dev/ttyACM0,115200``. Every item request has a timeout; a silent
vehicle gets the last message again, up to ``retries`` times; a refusal that the autopilot
gives while it is still busy (ArduCopter answers MAV_MISSION_NO_SPACE to a MISSION_COUNT sent
right after connecting) restarts the upload after a pause. Every other MAV_MISSION_RESULT is a
:class:`~uav_comm_planner.errors.VehicleLinkError` whose message names it. A link that goes
down during a transfer is a :class:`~uav_comm_planner.errors.VehicleLinkLostError`, whatever
the transport: an error of its socket or port (EOF, reset, refused), or, with a
:class:`LinkWatch` on the link, nothing at all heard for the watch's silence (a cut UDP or
serial link only goes quiet) or the link being stopped.

After an upload the mission is read back and compared item by item with what was sent
(:func:`~uav_comm_planner.vehicle.mavlink.items.mismatches`, in the fields the autopilot
stores). Rows become messages and messages rows in :mod:`.items`.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
import socket
import time
from typing import Callable, Sequence

from pymavlink import mavutil

from uav_comm_planner.errors import VehicleLinkError, VehicleLinkLostError
from uav_comm_planner.vehicle.limits import VehicleParameters
from uav_comm_planner.vehicle.mavlink.items import (from_message, item_int_message,
                                                    mismatches, MISSION_TYPE, MissionItem)
from uav_comm_planner.vehicle.mavlink.parameters import ParameterRead
from uav_comm_planner.vehicle.mavlink.urls import parse_link_url

MAV = mavutil.mavlink
#: MISSION_COUNT carries a uint16.
MAX_ITEMS = 65535
#: How often a connect that waits for the heartbeat asks whether to stop, seconds.
HEARTBEAT_POLL_S = 0.2
#: Refusals an autopilot gives while busy (parameters or a previous transfer still loading).
TRANSIENT_RESULTS = (MAV.MAV_MISSION_NO_SPACE, MAV.MAV_MISSION_DENIED,
                     MAV.MAV_MISSION_OPERATION_CANCELLED)
#: A transfer looks at the link's watch (:class:`LinkWatch`) at least this often, seconds.
WATCH_POLL_S = 0.1
#: A longer time between two looks is the process stalled, not the link silent: it counts as
#: this much silence only.
WATCH_STALL_S = 0.5
#: Nothing heard from the vehicle for this long (wall clock, while reading) is a lost link: a
#: vehicle sends its heartbeat at 1 Hz (the node's connection and the command line's upload).
SILENCE_S = 2.0
#: What each mission type is called in messages.
MISSION_TYPE_NAMES = {MAV.MAV_MISSION_TYPE_MISSION: 'mission',
                      MAV.MAV_MISSION_TYPE_FENCE: 'fence',
                      MAV.MAV_MISSION_TYPE_RALLY: 'rally points'}


@dataclass(frozen=True)
class LinkSettings:
    """How patient the link is: per-message timeout, retries of a silent step, busy retries,
    and ``deadline_s``, the most one upload and its read-back may take in all (a vehicle that
    trickles answers, or loops, cannot hold the link past it)."""

    timeout_s: float = 2.0
    retries: int = 5
    busy_retries: int = 5
    busy_pause_s: float = 1.0
    deadline_s: float = 300.0

    def __post_init__(self) -> None:
        for name in ('timeout_s', 'busy_pause_s', 'deadline_s'):
            value = getattr(self, name)
            least_ok = 0.0 if name == 'busy_pause_s' else math.ulp(0.0)
            if (isinstance(value, bool) or not isinstance(value, (int, float))
                    or not math.isfinite(value) or value < least_ok):
                raise VehicleLinkError(f'link setting {name} must be a positive number of '
                                       f'seconds, got {value!r}')
        for name in ('retries', 'busy_retries'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 1000:
                raise VehicleLinkError(f'link setting {name} must be an integer in 0..1000, '
                                       f'got {value!r}')


class Deadline:
    """The end of a transfer on the monotonic clock; :meth:`left` raises past it."""

    def __init__(self, seconds: float, what: str) -> None:
        self.seconds = seconds
        self.what = what
        self._end = time.monotonic() + seconds

    def left(self, most_s: float = math.inf) -> float:
        """Seconds left, at most ``most_s``; raises VehicleLinkError when none are left."""
        left = self._end - time.monotonic()
        if left <= 0:
            raise VehicleLinkError(f'{self.what} did not finish within its deadline of '
                                   f'{self.seconds:g} s')
        return min(left, most_s)


class LinkWatch:
    """What ends a transfer on a link besides its own timeouts, put on the link as its
    ``watch`` attribute: ``should_stop`` answering True (the link is being stopped), or no
    message at all from the link for ``silence_s`` while it is read (monotonic clock; a process
    stalled between two looks is not taken for a silent link): a cut UDP or serial link does
    not fail, it goes quiet, and an upload would otherwise wait out all its retries. Each is a
    :class:`VehicleLinkLostError`."""

    def __init__(self, *, silence_s: float = math.inf,
                 should_stop: Callable[[], bool] | None = None) -> None:
        self.silence_s = silence_s
        self._should_stop = should_stop
        self._count: int | None = None
        self._silent_s = 0.0
        self._looked: float | None = None

    def check(self, link) -> None:
        """Raise VehicleLinkLostError if the link is being stopped or has been silent."""
        if self._should_stop is not None and self._should_stop():
            raise VehicleLinkLostError('the link is being stopped')
        count = getattr(link, 'mav_count', None)     # messages parsed, from any sender
        now = time.monotonic()
        if count != self._count:
            self._count, self._silent_s = count, 0.0
        elif self._looked is not None:
            self._silent_s += min(now - self._looked, WATCH_STALL_S)
        self._looked = now
        if self._silent_s > self.silence_s:
            raise VehicleLinkLostError(f'link lost: nothing heard from the vehicle for '
                                       f'{self.silence_s:g} s')


def check_link(link) -> None:
    """Ask ``link``'s :class:`LinkWatch`, if it has one (raises VehicleLinkLostError)."""
    watch = getattr(link, 'watch', None)
    if watch is not None:
        watch.check(link)


def result_name(result: int) -> str:
    """``MAV_MISSION_INVALID_PARAM1`` for 5, the number itself when unknown."""
    entry = MAV.enums['MAV_MISSION_RESULT'].get(result)
    return entry.name if entry is not None else f'MAV_MISSION_RESULT {result}'


class _TimedTcp(mavutil.mavtcp):
    """pymavlink's TCP link, its connect bounded by a timeout (pymavlink's own blocks for as
    long as the kernel retries, minutes for a host that never answers), and a connection the
    vehicle closes or resets an OSError (pymavlink's own prints a line and reads nothing)."""

    def __init__(self, device: str, timeout_s: float, **options) -> None:
        self._connect_timeout_s = timeout_s
        super().__init__(device, **options)

    def do_connect(self) -> None:
        self.port = socket.create_connection(self.destination_addr,
                                             timeout=self._connect_timeout_s)
        self.port.setblocking(False)
        mavutil.set_close_on_exec(self.port.fileno())
        self.port.setsockopt(socket.SOL_TCP, socket.TCP_NODELAY, 1)

    def handle_eof(self) -> None:
        # pymavlink prints "EOF on TCP socket" and returns no data, at every read, for ever:
        # a closed link is an error here, raised once.
        raise ConnectionAbortedError('the vehicle closed the TCP connection (EOF)')

    def handle_disconnect(self) -> None:
        raise ConnectionResetError('the TCP connection to the vehicle was reset')


def connect(url: str, *, timeout_s: float = 30.0, source_system: int = 255,
            should_stop: Callable[[], bool] | None = None,
            parameters: Callable[[VehicleParameters], None] | None = None):
    """Open ``url`` and wait for the vehicle's heartbeat; return the pymavlink connection.

    The URL is checked first (:func:`~.urls.parse_link_url`: only live links, never a file to
    replay); ``timeout_s`` bounds the whole of it, the TCP connect and the heartbeat together.
    ``should_stop`` is asked every HEARTBEAT_POLL_S while the heartbeat is awaited, so that
    a link being stopped never waits out the timeout. The connection's ``target_system`` and
    ``target_component`` are the vehicle's. With ``parameters``, the vehicle's limit parameters
    are read on the connection as it is read (:class:`~.parameters.ParameterRead`) and each read
    handed to it. Raises
    :class:`~uav_comm_planner.errors.InvalidLinkUrlError` for a URL it does not open and
    :class:`VehicleLinkError` when the URL cannot be opened or no heartbeat comes in time.
    """
    parsed = parse_link_url(url)
    if not (math.isfinite(timeout_s) and timeout_s > 0):
        raise VehicleLinkError(f'the connect timeout must be a positive number of seconds, got '
                               f'{timeout_s!r}')
    deadline = time.monotonic() + timeout_s
    try:
        if parsed.scheme == 'tcp':
            link = _TimedTcp(f'{parsed.host}:{parsed.port}', timeout_s,
                             source_system=source_system, autoreconnect=False, retries=0)
        else:
            link = mavutil.mavlink_connection(str(parsed), source_system=source_system,
                                              autoreconnect=False)
    except (OSError, ValueError) as exc:
        raise VehicleLinkError(f'cannot open {url!r}: {exc}') from exc
    heartbeat = None
    try:
        while heartbeat is None and (left := deadline - time.monotonic()) > 0:
            if should_stop is not None and should_stop():
                link.close()
                raise VehicleLinkError(f'connecting to {url!r} was stopped')
            # A ground station's heartbeat first: PX4 answers on UDP only once it has heard
            # a sender (udpout:), and an ArduPilot vehicle takes it as any ground station's.
            link.mav.heartbeat_send(MAV.MAV_TYPE_GCS, MAV.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            heartbeat = link.wait_heartbeat(timeout=min(left, HEARTBEAT_POLL_S))
    except (OSError, ConnectionError) as exc:
        link.close()
        raise VehicleLinkLostError(f'link to {url!r} lost while waiting for the heartbeat: '
                                   f'{exc}') from exc
    if heartbeat is None:
        link.close()
        raise VehicleLinkError(f'no heartbeat from {url!r} within {timeout_s:g} s: is the '
                               f'vehicle on that link?')
    link.vehicle_autopilot = heartbeat.autopilot
    if parameters is not None:
        ParameterRead(heartbeat.autopilot).attach(link, parameters)
    return link


def has_home_row(link) -> bool:
    """Whether the vehicle's missions start with a home row (ArduPilot) or with their first
    real item (PX4), from the autopilot type of its heartbeat."""
    return getattr(link, 'vehicle_autopilot', None) != MAV.MAV_AUTOPILOT_PX4


def vehicle_seq(link, seq: int) -> int:
    """Mission item ``seq`` (counting the home row, as the mission files do) in ``link``'s
    vehicle's own numbering: one less for PX4, whose missions have no home row."""
    return seq if has_home_row(link) else seq - 1


def for_vehicle(link, items: Sequence[MissionItem]) -> Sequence[MissionItem]:
    """``items`` (row 0 is home, as the mission files hold them) as ``link``'s vehicle takes
    them: without the home row for PX4."""
    return items if has_home_row(link) else items[1:]


def _receive(link, types: Sequence[str], timeout_s: float, total: Deadline | None = None,
             mission_type: int = MISSION_TYPE):
    """The next message of one of ``types`` addressed to us about ``mission_type``, or None
    after ``timeout_s`` (cut to what is left of ``total``, which raises once it has passed);
    the link's watch is asked every WATCH_POLL_S meanwhile."""
    deadline = time.monotonic() + timeout_s
    while (left := deadline - time.monotonic()) > 0:
        if total is not None:
            left = total.left(left)
        check_link(link)
        try:
            message = link.recv_match(type=list(types), blocking=True,
                                      timeout=min(left, WATCH_POLL_S))
        except (OSError, ConnectionError) as exc:
            raise VehicleLinkLostError(f'link lost: {exc}') from exc
        if message is None:
            continue
        if getattr(message, 'mission_type', MISSION_TYPE) != mission_type:
            continue
        target = getattr(message, 'target_system', None)
        if target not in (None, 0, link.source_system):
            continue
        return message
    return None


def _send(link, message) -> None:
    try:
        link.mav.send(message)
    except (OSError, ConnectionError) as exc:
        raise VehicleLinkLostError(f'link lost while sending: {exc}') from exc


def _kind(mission_type: int) -> str:
    return MISSION_TYPE_NAMES.get(mission_type, f'mission type {mission_type}')


def upload_mission(link, items: Sequence[MissionItem],
                   settings: LinkSettings = LinkSettings(), *,
                   total: Deadline | None = None, mission_type: int = MISSION_TYPE) -> None:
    """Upload ``items`` (for the mission, row 0 is home) and wait for MAV_MISSION_ACCEPTED.

    Raises :class:`VehicleLinkError` on a refusal, with the MAV_MISSION_RESULT's name and the
    item it concerns, when the vehicle stays silent through every retry, asks for items out of
    range or over and over (a loop), or when ``total`` (by default ``settings.deadline_s``)
    passes.
    """
    kind = _kind(mission_type)
    if not items:
        raise VehicleLinkError(f'an empty {kind} cannot be uploaded')
    if len(items) > MAX_ITEMS:
        raise VehicleLinkError(f'a {kind} of {len(items)} items is more than MAVLink carries '
                               f'({MAX_ITEMS})')
    total = total or Deadline(settings.deadline_s, f'the {kind} upload')
    for attempt in range(settings.busy_retries + 1):
        result, seq = _upload_once(link, items, settings, total, mission_type)
        if result == MAV.MAV_MISSION_ACCEPTED:
            return
        if result not in TRANSIENT_RESULTS or attempt == settings.busy_retries:
            where = f' at item {seq}' if seq is not None else ''
            raise VehicleLinkError(f'the vehicle refused the {kind}{where}: '
                                   f'{result_name(result)}')
        time.sleep(total.left(settings.busy_pause_s))


def _upload_once(link, items: Sequence[MissionItem], settings: LinkSettings,
                 total: Deadline, mission_type: int) -> tuple[int, int | None]:
    """One transfer: the vehicle's final MAV_MISSION_RESULT and the last item it asked for."""
    count = link.mav.mission_count_encode(link.target_system, link.target_component,
                                          len(items), mission_type)
    last_sent = count
    requested: int | None = None
    silent = 0
    # Each item may be asked for again when our answer was lost, up to `retries` times.
    most_requests = len(items) * (settings.retries + 1)
    requests = out_of_sequence = 0
    kind = _kind(mission_type)
    _send(link, count)
    while True:
        message = _receive(link, ('MISSION_REQUEST_INT', 'MISSION_REQUEST', 'MISSION_ACK'),
                           settings.timeout_s, total, mission_type)
        if message is None:
            silent += 1
            if silent > settings.retries:
                at = f'the {kind} count' if requested is None else f'item {requested}'
                raise VehicleLinkError(f'the vehicle stopped answering after {at} '
                                       f'({settings.retries} retries of '
                                       f'{settings.timeout_s:g} s)')
            _send(link, last_sent)
            continue
        silent = 0
        if message.get_type() == 'MISSION_ACK':
            if (message.type == MAV.MAV_MISSION_INVALID_SEQUENCE and requested is not None
                    and out_of_sequence < most_requests):
                # An item the vehicle did not ask for: the answer to a request it had sent
                # again before our first answer came (ArduPilot resends after 1 s, 50 ms of
                # wall clock in a simulator at speed-up 20). It drops that item and goes on.
                out_of_sequence += 1
                continue
            return message.type, requested
        requested = message.seq
        if not 0 <= requested < len(items):
            raise VehicleLinkError(f'the vehicle asked for item {requested} of a '
                                   f'{len(items)}-item {kind}')
        requests += 1
        if requests > most_requests:
            raise VehicleLinkError(f'the vehicle keeps asking for items ({requests} requests '
                                   f'for a {len(items)}-item {kind}, the last for item '
                                   f'{requested}): it loops')
        last_sent = item_int_message(items[requested], requested, link.mav,
                                     link.target_system, link.target_component,
                                     mission_type=mission_type)
        _send(link, last_sent)


def download_mission(link, settings: LinkSettings = LinkSettings(), *,
                     expected: int | None = None, total: Deadline | None = None,
                     mission_type: int = MISSION_TYPE) -> list[MissionItem]:
    """Read the vehicle's mission (row 0, home, first) or, by ``mission_type``, its fence;
    with ``expected``, a vehicle that reports another item count is refused before any item
    is asked for."""
    kind = _kind(mission_type)
    total = total or Deadline(settings.deadline_s, f'the {kind} read-back')
    request_list = link.mav.mission_request_list_encode(link.target_system,
                                                        link.target_component, mission_type)
    count = _ask(link, request_list, ('MISSION_COUNT',), settings, f'the {kind} count',
                 total=total, mission_type=mission_type).count
    if expected is not None and count != expected:
        raise VehicleLinkError(f'the vehicle does not hold the {kind} uploaded: it reports '
                               f'{count} items, {expected} were uploaded')
    items = []
    for seq in range(count):
        request = link.mav.mission_request_int_encode(link.target_system,
                                                      link.target_component, seq, mission_type)
        message = _ask(link, request, ('MISSION_ITEM_INT',), settings, f'item {seq}',
                       seq=seq, total=total, mission_type=mission_type)
        try:
            items.append(from_message(message))
        except (TypeError, ValueError, OverflowError) as exc:
            raise VehicleLinkError(f'the vehicle sent item {seq} out of range: {exc}') from None
    _send(link, link.mav.mission_ack_encode(link.target_system, link.target_component,
                                            MAV.MAV_MISSION_ACCEPTED, mission_type))
    return items


def _ask(link, request, types: Sequence[str], settings: LinkSettings, what: str, *,
         seq: int | None = None, total: Deadline | None = None,
         mission_type: int = MISSION_TYPE):
    for _ in range(settings.retries + 1):
        _send(link, request)
        deadline = time.monotonic() + settings.timeout_s
        refused: int | None = None
        while (left := deadline - time.monotonic()) > 0:
            message = _receive(link, (*types, 'MISSION_ACK'), left, total, mission_type)
            if message is None:
                break
            if message.get_type() == 'MISSION_ACK':
                # A late copy of the upload's acceptance (PX4 repeats it), or a refusal: this
                # request's, or the late answer to an item the upload just before sent twice
                # (ArduPilot acks one that comes after the transfer MAV_MISSION_ERROR). The
                # request's own answer may still come; a refusal stands if it does not.
                if message.type != MAV.MAV_MISSION_ACCEPTED:
                    refused = message.type
                continue
            if seq is None or message.seq == seq:
                return message
        if refused is not None:
            raise VehicleLinkError(f'the vehicle refused to send {what}: '
                                   f'{result_name(refused)}')
    raise VehicleLinkError(f'no answer for {what} after {settings.retries} retries of '
                           f'{settings.timeout_s:g} s')


def upload_and_verify(link, items: Sequence[MissionItem],
                      settings: LinkSettings = LinkSettings(), *,
                      mission_type: int = MISSION_TYPE) -> None:
    """Upload ``items``, read them back, and raise :class:`VehicleLinkError` unless the
    vehicle holds them. A mission's row 0 is home (PX4 gets it without, :func:`for_vehicle`);
    a fence (``mission_type`` MAV_MISSION_TYPE_FENCE) has no home row on either autopilot."""
    kind = _kind(mission_type)
    total = Deadline(settings.deadline_s, f'the {kind} upload and its read-back')
    mission = mission_type == MISSION_TYPE
    if mission:
        items = for_vehicle(link, items)
    upload_mission(link, items, settings, total=total, mission_type=mission_type)
    stored = download_mission(link, settings, expected=len(items), total=total,
                              mission_type=mission_type)
    wrong = mismatches(items, stored, home_row=mission and has_home_row(link))
    if wrong:
        raise VehicleLinkError(f'the vehicle does not hold the {kind} uploaded: '
                               + '; '.join(wrong[:3]))
