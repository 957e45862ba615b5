"""The vehicle's home and whether a mission belongs there.

ArduPilot and PX4 report their home (where they armed, or their first fix) in HOME_POSITION
when asked (MAV_CMD_REQUEST_MESSAGE; older firmware MAV_CMD_GET_HOME_POSITION), and where they
are in GLOBAL_POSITION_INT. A mission planned for another place (its home row, or its first
waypoint, farther than a limit from the vehicle's home, or from its position while it has no
home) is refused before it is uploaded, with both positions in the message:
:func:`mission_far_from_vehicle`. The command line's ``upload`` and the node's link both check
every mission this way.
"""

from __future__ import annotations

import math
import time
from typing import Sequence

from pymavlink import mavutil

from uav_comm_planner.errors import MissionTooFarError, VehicleLinkLostError
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.mavlink.items import DEGREES_E7, MissionItem

MAV = mavutil.mavlink
#: The default limit: a mission farther than this from the vehicle is for another place.
HOME_DISTANCE_LIMIT_M = 1000.0
#: Mean Earth radius (IUGG), metres: great-circle distances for the messages and the check.
EARTH_RADIUS_M = 6_371_008.8
#: How often the home is asked for again while it is awaited, seconds (wall clock).
HOME_REQUEST_PERIOD_S = 1.0

LatLon = tuple[float, float]


def request_home(link) -> None:
    """Ask the vehicle for HOME_POSITION, both ways firmware answers."""
    link.mav.command_long_send(link.target_system, link.target_component,
                               MAV.MAV_CMD_REQUEST_MESSAGE, 0,
                               MAV.MAVLINK_MSG_ID_HOME_POSITION, 0, 0, 0, 0, 0, 0)
    link.mav.command_long_send(link.target_system, link.target_component,
                               MAV.MAV_CMD_GET_HOME_POSITION, 0, 0, 0, 0, 0, 0, 0, 0)


def home_of(message) -> Home | None:
    """The Home of a HOME_POSITION message (altitude above mean sea level), None for one at
    latitude and longitude 0 (no home yet) or out of range."""
    if message.latitude == 0 and message.longitude == 0:
        return None
    try:
        return Home(message.latitude / DEGREES_E7, message.longitude / DEGREES_E7,
                    message.altitude / 1000.0)
    except ValueError:
        return None


def position_of(message) -> LatLon | None:
    """Latitude, longitude of a GLOBAL_POSITION_INT, None before a fix (0, 0)."""
    if message.lat == 0 and message.lon == 0:
        return None
    return message.lat / DEGREES_E7, message.lon / DEGREES_E7


def distance_m(a: LatLon, b: LatLon) -> float:
    """Great-circle distance between two latitude, longitude pairs (degrees), metres."""
    phi_a, phi_b = math.radians(a[0]), math.radians(b[0])
    half = (math.sin((phi_b - phi_a) / 2) ** 2
            + math.cos(phi_a) * math.cos(phi_b) * math.sin(math.radians(b[1] - a[1]) / 2) ** 2)
    return 2 * EARTH_RADIUS_M * math.asin(min(1.0, math.sqrt(half)))


def first_waypoint(items: Sequence[MissionItem]) -> LatLon | None:
    """The first row after home (row 0) with a place (a takeoff without one is skipped)."""
    return next(((item.x, item.y) for item in items[1:] if (item.x, item.y) != (0.0, 0.0)),
                None)


def _text(distance: float) -> str:
    return f'{distance / 1000:.1f} km' if distance >= 10_000 else f'{distance:.0f} m'


def mission_far_from_vehicle(items: Sequence[MissionItem], home: Home | None,
                             position: LatLon | None, limit_m: float) -> str:
    """Why the mission ``items`` (row 0 its home) is not for a vehicle homed at ``home`` (or,
    without one, at ``position``), '' when it is: its home row or its first waypoint farther
    than ``limit_m`` from it."""
    if home is not None:
        where, anchor = "the vehicle's home", (home.latitude_deg, home.longitude_deg)
    elif position is not None:
        where, anchor = "the vehicle's position", position
    else:
        return ''
    if not items:
        return ''
    for what, point in (("the mission's home", (items[0].x, items[0].y)),
                        ("the mission's first waypoint", first_waypoint(items))):
        if point is None:
            continue
        gap = distance_m(point, anchor)
        if gap > limit_m:
            return (f'{what} ({point[0]:.7f}, {point[1]:.7f}) is {_text(gap)} from {where} '
                    f'({anchor[0]:.7f}, {anchor[1]:.7f}), farther than {limit_m:g} m: it was '
                    f'planned for another place; plan it with the vehicle\'s home')
    return ''


def wait_for_home(link, timeout_s: float) -> tuple[Home | None, LatLon | None]:
    """The vehicle's home and position, asking for the home until it comes or ``timeout_s``
    passes (then the latest position alone, or neither)."""
    deadline = time.monotonic() + timeout_s
    position = None
    asked = -math.inf
    while (left := deadline - time.monotonic()) > 0:
        if time.monotonic() - asked >= HOME_REQUEST_PERIOD_S:
            request_home(link)
            asked = time.monotonic()
        try:
            message = link.recv_match(type=['HOME_POSITION', 'GLOBAL_POSITION_INT'],
                                      blocking=True, timeout=min(left, 0.2))
        except (OSError, ConnectionError) as exc:
            raise VehicleLinkLostError(f'link lost while asking for the home: {exc}') from exc
        if message is None:
            continue
        if message.get_type() == 'HOME_POSITION':
            home = home_of(message)
            if home is not None:
                return home, position
        else:
            position = position_of(message) or position
    return None, position


def check_mission_home(link, items: Sequence[MissionItem], limit_m: float,
                       timeout_s: float) -> None:
    """Raise :class:`MissionTooFarError` unless the mission ``items`` belongs where the
    vehicle on ``link`` is (:func:`mission_far_from_vehicle`); a vehicle that tells neither
    its home nor its position within ``timeout_s`` is refused too. An infinite limit checks
    nothing."""
    if math.isinf(limit_m):
        return
    home, position = wait_for_home(link, timeout_s)
    if home is None and position is None:
        raise MissionTooFarError(f'the vehicle told neither its home nor its position within '
                                 f'{timeout_s:g} s: the mission\'s home cannot be checked')
    reason = mission_far_from_vehicle(items, home, position, limit_m)
    if reason:
        raise MissionTooFarError(f'mission refused before upload: {reason}')


__all__ = ['HOME_DISTANCE_LIMIT_M', 'check_mission_home', 'distance_m',
           'first_waypoint', 'home_of', 'mission_far_from_vehicle', 'position_of',
           'request_home', 'wait_for_home']
