"""The MAVLink link to a vehicle: connect, upload a mission and read it back.

Speaks the MAVLink mission protocol (MISSION_COUNT, MISSION_REQUEST_INT, MISSION_ITEM_INT,
MISSION_ACK) over any connection pymavlink opens: ``tcp:127.0.0.1:5760``,
``udpin:0.0.0.0:14550``, ``/dev/ttyACM0,115200``. Every item request has a timeout; a silent
vehicle gets the last message again, up to ``retries`` times; a refusal that the autopilot
gives while it is still busy (ArduCopter answers MAV_MISSION_NO_SPACE to a MISSION_COUNT sent
right after connecting) restarts the upload after a pause. Every other MAV_MISSION_RESULT is a
:class:`~uav_comm_planner.errors.VehicleLinkError` whose message names it.

After an upload the mission is read back and compared item by item with what was sent
(:func:`~uav_comm_planner.vehicle.mavlink.items.mismatches`, in the fields the autopilot
stores). Rows become messages and messages rows in :mod:`.items`.
"""

from __future__ import annotations

from dataclasses import dataclass
import time
from typing import Sequence

from pymavlink import mavutil

from uav_comm_planner.errors import VehicleLinkError
from uav_comm_planner.vehicle.mavlink.items import (from_message, item_int_message,
                                                    mismatches, MISSION_TYPE, MissionItem)

MAV = mavutil.mavlink
#: Refusals an autopilot gives while busy (parameters or a previous transfer still loading).
TRANSIENT_RESULTS = (MAV.MAV_MISSION_NO_SPACE, MAV.MAV_MISSION_DENIED,
                     MAV.MAV_MISSION_OPERATION_CANCELLED)


@dataclass(frozen=True)
class LinkSettings:
    """How patient the link is: per-message timeout, retries of a silent step, busy retries."""

    timeout_s: float = 2.0
    retries: int = 5
    busy_retries: int = 5
    busy_pause_s: float = 1.0


def result_name(result: int) -> str:
    """``MAV_MISSION_INVALID_PARAM1`` for 5, the number itself when unknown."""
    entry = MAV.enums['MAV_MISSION_RESULT'].get(result)
    return entry.name if entry is not None else f'MAV_MISSION_RESULT {result}'


def connect(url: str, *, timeout_s: float = 30.0, source_system: int = 255):
    """Open ``url`` and wait for the vehicle's heartbeat; return the pymavlink connection.

    The connection's ``target_system`` and ``target_component`` are the vehicle's. Raises
    :class:`VehicleLinkError` when the URL cannot be opened or no heartbeat comes in time.
    """
    try:
        link = mavutil.mavlink_connection(url, source_system=source_system, autoreconnect=False)
    except (OSError, ValueError) as exc:
        raise VehicleLinkError(f'cannot open {url!r}: {exc}') from exc
    heartbeat = link.wait_heartbeat(timeout=timeout_s)
    if heartbeat is None:
        link.close()
        raise VehicleLinkError(f'no heartbeat from {url!r} within {timeout_s:g} s: is the '
                               f'vehicle on that link?')
    return link


def _receive(link, types: Sequence[str], timeout_s: float):
    """The next message of one of ``types`` addressed to us, or None after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while (left := deadline - time.monotonic()) > 0:
        try:
            message = link.recv_match(type=list(types), blocking=True, timeout=left)
        except (OSError, ConnectionError) as exc:
            raise VehicleLinkError(f'link lost: {exc}') from exc
        if message is None:
            return None
        if getattr(message, 'mission_type', MISSION_TYPE) != MISSION_TYPE:
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
        raise VehicleLinkError(f'link lost while sending: {exc}') from exc


def upload_mission(link, items: Sequence[MissionItem],
                   settings: LinkSettings = LinkSettings()) -> None:
    """Upload ``items`` (row 0 is home) and wait for MAV_MISSION_ACCEPTED.

    Raises :class:`VehicleLinkError` on a refusal, with the MAV_MISSION_RESULT's name and the
    item it concerns, or when the vehicle stays silent through every retry.
    """
    if not items:
        raise VehicleLinkError('an empty mission cannot be uploaded')
    for attempt in range(settings.busy_retries + 1):
        result, seq = _upload_once(link, items, settings)
        if result == MAV.MAV_MISSION_ACCEPTED:
            return
        if result not in TRANSIENT_RESULTS or attempt == settings.busy_retries:
            where = f' at item {seq}' if seq is not None else ''
            raise VehicleLinkError(f'the vehicle refused the mission{where}: '
                                   f'{result_name(result)}')
        time.sleep(settings.busy_pause_s)


def _upload_once(link, items: Sequence[MissionItem],
                 settings: LinkSettings) -> tuple[int, int | None]:
    """One transfer: the vehicle's final MAV_MISSION_RESULT and the last item it asked for."""
    count = link.mav.mission_count_encode(link.target_system, link.target_component,
                                          len(items), MISSION_TYPE)
    last_sent = count
    requested: int | None = None
    silent = 0
    _send(link, count)
    while True:
        message = _receive(link, ('MISSION_REQUEST_INT', 'MISSION_REQUEST', 'MISSION_ACK'),
                           settings.timeout_s)
        if message is None:
            silent += 1
            if silent > settings.retries:
                at = 'the mission count' if requested is None else f'item {requested}'
                raise VehicleLinkError(f'the vehicle stopped answering after {at} '
                                       f'({settings.retries} retries of '
                                       f'{settings.timeout_s:g} s)')
            _send(link, last_sent)
            continue
        silent = 0
        if message.get_type() == 'MISSION_ACK':
            return message.type, requested
        requested = message.seq
        if not 0 <= requested < len(items):
            raise VehicleLinkError(f'the vehicle asked for item {requested} of a '
                                   f'{len(items)}-item mission')
        last_sent = item_int_message(items[requested], requested, link.mav,
                                     link.target_system, link.target_component)
        _send(link, last_sent)


def download_mission(link, settings: LinkSettings = LinkSettings()) -> list[MissionItem]:
    """Read the vehicle's mission, row 0 (home) first."""
    request_list = link.mav.mission_request_list_encode(link.target_system,
                                                        link.target_component, MISSION_TYPE)
    count = _ask(link, request_list, ('MISSION_COUNT',), settings, 'the mission count').count
    items = []
    for seq in range(count):
        request = link.mav.mission_request_int_encode(link.target_system,
                                                      link.target_component, seq, MISSION_TYPE)
        message = _ask(link, request, ('MISSION_ITEM_INT',), settings, f'item {seq}',
                       seq=seq)
        items.append(from_message(message))
    _send(link, link.mav.mission_ack_encode(link.target_system, link.target_component,
                                            MAV.MAV_MISSION_ACCEPTED, MISSION_TYPE))
    return items


def _ask(link, request, types: Sequence[str], settings: LinkSettings, what: str, *,
         seq: int | None = None):
    for _ in range(settings.retries + 1):
        _send(link, request)
        deadline = time.monotonic() + settings.timeout_s
        while (left := deadline - time.monotonic()) > 0:
            message = _receive(link, (*types, 'MISSION_ACK'), left)
            if message is None:
                break
            if message.get_type() == 'MISSION_ACK':
                raise VehicleLinkError(f'the vehicle refused to send {what}: '
                                       f'{result_name(message.type)}')
            if seq is None or message.seq == seq:
                return message
    raise VehicleLinkError(f'no answer for {what} after {settings.retries} retries of '
                           f'{settings.timeout_s:g} s')


def upload_and_verify(link, items: Sequence[MissionItem],
                      settings: LinkSettings = LinkSettings()) -> None:
    """Upload, read back, and raise :class:`VehicleLinkError` unless the vehicle holds it."""
    upload_mission(link, items, settings)
    wrong = mismatches(items, download_mission(link, settings))
    if wrong:
        raise VehicleLinkError('the vehicle does not hold the mission uploaded: '
                               + '; '.join(wrong[:3]))
