"""Put a mission file on a vehicle: read the file, upload it, read it back.

The rows of a ``.waypoints`` or ``.plan`` file (:mod:`.files`) are uploaded with
MISSION_ITEM_INT (:mod:`.link`); success means the vehicle holds exactly the file's items. A
mission planned for another place than the vehicle's is refused before it is uploaded
(:mod:`.home`).
"""

from __future__ import annotations

import os

from uav_comm_planner.errors import MissionTooFarError
from uav_comm_planner.vehicle.mavlink.files import read_mission_file
from uav_comm_planner.vehicle.mavlink.home import check_mission_home, HOME_DISTANCE_LIMIT_M
from uav_comm_planner.vehicle.mavlink.link import connect, LinkSettings, upload_and_verify
from uav_comm_planner.vehicle.mavlink.urls import parse_link_url


def upload_file(path: str | os.PathLike, url: str, *,
                settings: LinkSettings = LinkSettings(), connect_timeout_s: float = 30.0,
                home_limit_m: float = HOME_DISTANCE_LIMIT_M) -> int:
    """Upload the mission in ``path`` to the vehicle at ``url`` and verify it by reading it
    back; returns the number of items. The URL and the whole file are checked before any
    connection; a mission whose home or first waypoint is farther than ``home_limit_m`` from
    the vehicle's home (or position) is refused before the upload (infinite: not checked).
    Raises InvalidLinkUrlError for a URL it does not open, MissionFileError for a file it
    cannot read, MissionTooFarError for a mission planned for another place, VehicleLinkError
    for the link, each with the reason; the transfer ends by ``settings.deadline_s`` whatever
    the vehicle does."""
    parse_link_url(url)
    if not home_limit_m > 0:
        raise MissionTooFarError(f'the home distance limit must be a positive number of '
                                 f'metres, got {home_limit_m!r}')
    items = read_mission_file(path)
    link = connect(url, timeout_s=connect_timeout_s)
    try:
        check_mission_home(link, items, home_limit_m, timeout_s=connect_timeout_s)
        upload_and_verify(link, items, settings)
    finally:
        link.close()
    return len(items)


__all__ = ['upload_file']
