"""Put a mission file on a vehicle: read the file, upload it, read it back.

``.waypoints`` files (QGC WPL 110, as pymavlink's mavwp reads them) and QGroundControl
``.plan`` files (their simple items, after the planned home position as row 0) become the rows
the link uploads with MISSION_ITEM_INT (:mod:`uav_comm_planner.vehicle.mavlink.link`); success
means the vehicle holds exactly the file's items.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

from pymavlink import mavwp

from uav_comm_planner.errors import VehicleLinkError
from uav_comm_planner.vehicle.mavlink.items import (FRAME_GLOBAL, from_message, MissionItem,
                                                    NAV_WAYPOINT)
from uav_comm_planner.vehicle.mavlink.link import connect, LinkSettings, upload_and_verify


def _number(value: object) -> float:
    """A .plan parameter: null is NaN (the autopilot's default)."""
    return math.nan if value is None else float(value)


def read_plan(path: str | os.PathLike) -> list[MissionItem]:
    """The rows of a QGroundControl .plan file: its planned home position, then its simple
    items; raises VehicleLinkError for a bad file or a complex item (survey, corridor...)."""
    target = Path(path)
    try:
        mission = json.loads(target.read_text(encoding='utf-8'))['mission']
        latitude, longitude, altitude = (float(v) for v in mission['plannedHomePosition'])
        items = [MissionItem(NAV_WAYPOINT, FRAME_GLOBAL, x=latitude, y=longitude, z=altitude,
                             current=True)]
        for entry in mission['items']:
            if entry.get('type') != 'SimpleItem':
                raise VehicleLinkError(f'{str(target)!r}: item {len(items)} is a '
                                       f'{entry.get("type")}; only simple items are uploaded')
            p = [_number(v) for v in entry['params']]
            if len(p) != 7:
                raise ValueError(f'item {len(items)} has {len(p)} params, not 7')
            items.append(MissionItem(int(entry['command']), int(entry['frame']),
                                     (p[0], p[1], p[2], p[3]), p[4], p[5], p[6],
                                     autocontinue=bool(entry.get('autoContinue', True))))
    except (OSError, UnicodeDecodeError) as exc:
        raise VehicleLinkError(f'{str(target)!r}: cannot read it: {exc}') from None
    except (ValueError, KeyError, TypeError) as exc:
        raise VehicleLinkError(f'{str(target)!r} is not a QGroundControl .plan mission: '
                               f'{exc}') from None
    return items


def read_mission_file(path: str | os.PathLike) -> list[MissionItem]:
    """The rows of a ``.waypoints`` or ``.plan`` mission, home first."""
    target = Path(path)
    if not target.is_file():
        raise VehicleLinkError(f'{str(target)!r}: no such mission file')
    if target.suffix.lower() == '.plan':
        return read_plan(target)
    return read_waypoints(target)


def read_waypoints(path: str | os.PathLike) -> list[MissionItem]:
    """The rows of a QGC WPL 110 file, home first; raises VehicleLinkError for a bad file."""
    target = Path(path)
    if target.suffix.lower() != '.waypoints':
        raise VehicleLinkError(f'{str(target)!r}: a mission is a .waypoints (QGC WPL 110) or a '
                               f'.plan (QGroundControl) file')
    if not target.is_file():
        raise VehicleLinkError(f'{str(target)!r}: no such mission file')
    loader = mavwp.MAVWPLoader()
    try:
        loader.load(str(target))
    except Exception as exc:  # noqa: B902 - mavwp raises bare Exceptions for a bad file
        raise VehicleLinkError(f'{str(target)!r} is not a QGC WPL 110 mission: {exc}') from None
    items = [from_message(loader.wp(i)) for i in range(loader.count())]
    if not items:
        raise VehicleLinkError(f'{str(target)!r} holds no mission item')
    return items


def upload_file(path: str | os.PathLike, url: str, *,
                settings: LinkSettings = LinkSettings(), connect_timeout_s: float = 30.0) -> int:
    """Upload the mission in ``path`` to the vehicle at ``url`` and verify it by reading it
    back; returns the number of items. Raises VehicleLinkError with the reason."""
    items = read_mission_file(path)
    link = connect(url, timeout_s=connect_timeout_s)
    try:
        upload_and_verify(link, items, settings)
    finally:
        link.close()
    return len(items)


__all__ = ['read_mission_file', 'read_plan', 'read_waypoints', 'upload_file']
