"""Put a mission file on a vehicle: read the file, upload it, read it back.

``.waypoints`` files (QGC WPL 110, as pymavlink's mavwp reads them) become the rows the link
uploads with MISSION_ITEM_INT (:mod:`uav_comm_planner.vehicle.link`); success means the vehicle
holds exactly the file's items.
"""

from __future__ import annotations

import os
from pathlib import Path

from pymavlink import mavwp

from uav_comm_planner.errors import VehicleLinkError
from uav_comm_planner.vehicle.link import connect, LinkSettings, upload_and_verify
from uav_comm_planner.vehicle.mission import MissionItem


def read_waypoints(path: str | os.PathLike) -> list[MissionItem]:
    """The rows of a QGC WPL 110 file, home first; raises VehicleLinkError for a bad file."""
    target = Path(path)
    if target.suffix.lower() != '.waypoints':
        raise VehicleLinkError(f'{str(target)!r}: only .waypoints (QGC WPL 110) missions are '
                               f'uploaded; export the plan with --mission FILE.waypoints')
    if not target.is_file():
        raise VehicleLinkError(f'{str(target)!r}: no such mission file')
    loader = mavwp.MAVWPLoader()
    try:
        loader.load(str(target))
    except Exception as exc:  # noqa: B902 - mavwp raises bare Exceptions for a bad file
        raise VehicleLinkError(f'{str(target)!r} is not a QGC WPL 110 mission: {exc}') from None
    items = [MissionItem(command=w.command, frame=w.frame,
                         params=(w.param1, w.param2, w.param3, w.param4), x=w.x, y=w.y, z=w.z,
                         current=bool(w.current), autocontinue=bool(w.autocontinue))
             for w in (loader.wp(i) for i in range(loader.count()))]
    if not items:
        raise VehicleLinkError(f'{str(target)!r} holds no mission item')
    return items


def upload_file(path: str | os.PathLike, url: str, *,
                settings: LinkSettings = LinkSettings(), connect_timeout_s: float = 30.0) -> int:
    """Upload the mission in ``path`` to the vehicle at ``url`` and verify it by reading it
    back; returns the number of items. Raises VehicleLinkError with the reason."""
    items = read_waypoints(path)
    link = connect(url, timeout_s=connect_timeout_s)
    try:
        upload_and_verify(link, items, settings)
    finally:
        link.close()
    return len(items)


__all__ = ['read_waypoints', 'upload_file']
