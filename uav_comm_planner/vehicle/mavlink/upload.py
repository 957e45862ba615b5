"""Put a mission file on a vehicle: read the file, upload it, read it back.

The rows of a ``.waypoints`` or ``.plan`` file (:mod:`.files`) are uploaded with
MISSION_ITEM_INT (:mod:`.link`); success means the vehicle holds exactly the file's items.
"""

from __future__ import annotations

import os

from uav_comm_planner.vehicle.mavlink.files import read_mission_file
from uav_comm_planner.vehicle.mavlink.link import connect, LinkSettings, upload_and_verify
from uav_comm_planner.vehicle.mavlink.urls import parse_link_url


def upload_file(path: str | os.PathLike, url: str, *,
                settings: LinkSettings = LinkSettings(), connect_timeout_s: float = 30.0) -> int:
    """Upload the mission in ``path`` to the vehicle at ``url`` and verify it by reading it
    back; returns the number of items. The URL and the whole file are checked before any
    connection. Raises InvalidLinkUrlError for a URL it does not open, MissionFileError for a
    file it cannot read, VehicleLinkError for the link, each with the reason; the transfer
    ends by ``settings.deadline_s`` whatever the vehicle does."""
    parse_link_url(url)
    items = read_mission_file(path)
    link = connect(url, timeout_s=connect_timeout_s)
    try:
        upload_and_verify(link, items, settings)
    finally:
        link.close()
    return len(items)


__all__ = ['upload_file']
