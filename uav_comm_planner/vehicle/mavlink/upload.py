"""Put a mission file, a fence file or both on a vehicle: read them, upload, read back.

The rows of a ``.waypoints`` or ``.plan`` file (:mod:`.files`) are uploaded with
MISSION_ITEM_INT (:mod:`.link`); the zones of a fence file (:mod:`uav_comm_planner.vehicle.
fence`: a ``.plan``'s geoFence or GeoJSON) as fence items (:mod:`.fence`). Success means the
vehicle holds exactly the files' items. A mission planned for another place than the
vehicle's is refused before it is uploaded (:mod:`.home`).
"""

from __future__ import annotations

from dataclasses import dataclass
import os

from uav_comm_planner.errors import MissionFileError, MissionTooFarError
from uav_comm_planner.vehicle.fence import read_checked_fence
from uav_comm_planner.vehicle.mavlink.fence import fence_items, MISSION_TYPE_FENCE
from uav_comm_planner.vehicle.mavlink.files import read_mission_file
from uav_comm_planner.vehicle.mavlink.home import check_mission_home, HOME_DISTANCE_LIMIT_M
from uav_comm_planner.vehicle.mavlink.link import (connect, LinkSettings, LinkWatch, SILENCE_S,
                                                   upload_and_verify)
from uav_comm_planner.vehicle.mavlink.urls import parse_link_url


@dataclass(frozen=True)
class Uploaded:
    """How many mission items and fence items the vehicle now holds (0: none sent)."""

    mission_items: int = 0
    fence_items: int = 0


def upload_files(url: str, *, mission: str | os.PathLike | None = None,
                 fence: str | os.PathLike | None = None,
                 settings: LinkSettings = LinkSettings(), connect_timeout_s: float = 30.0,
                 home_limit_m: float = HOME_DISTANCE_LIMIT_M) -> Uploaded:
    """Upload the mission in ``mission`` and the fence in ``fence`` (either or both) to the
    vehicle at ``url``, each verified by reading it back; the fence goes first, so that the
    vehicle never holds the new mission under an old fence. The URL and the whole of both
    files are checked before any connection; a mission whose home or first waypoint is farther
    than ``home_limit_m`` from the vehicle's home (or position) is refused before anything is
    uploaded (infinite: not checked). Raises InvalidLinkUrlError for a URL it does not open,
    MissionFileError (FenceFileError) for a file it cannot read, MissionTooFarError for a
    mission planned for another place, VehicleLinkError for the link or a refusal, each with
    the reason (VehicleLinkLostError when the link goes down or silent for SILENCE_S during a
    transfer); each transfer ends by ``settings.deadline_s`` whatever the vehicle does."""
    if mission is None and fence is None:
        raise MissionFileError('nothing to upload: give a mission file, a fence file or both')
    parse_link_url(url)
    if not home_limit_m > 0:
        raise MissionTooFarError(f'the home distance limit must be a positive number of '
                                 f'metres, got {home_limit_m!r}')
    items = read_mission_file(mission) if mission is not None else None
    zones = fence_items(read_checked_fence(fence)) if fence is not None else None
    link = connect(url, timeout_s=connect_timeout_s)
    link.watch = LinkWatch(silence_s=SILENCE_S)     # a cut UDP or serial link only goes quiet
    try:
        if items is not None:
            check_mission_home(link, items, home_limit_m, timeout_s=connect_timeout_s)
        if zones is not None:
            upload_and_verify(link, zones, settings, mission_type=MISSION_TYPE_FENCE)
        if items is not None:
            upload_and_verify(link, items, settings)
    finally:
        link.close()
    return Uploaded(len(items or ()), len(zones or ()))


def upload_file(path: str | os.PathLike, url: str, *,
                settings: LinkSettings = LinkSettings(), connect_timeout_s: float = 30.0,
                home_limit_m: float = HOME_DISTANCE_LIMIT_M) -> int:
    """Upload the mission in ``path`` to the vehicle at ``url`` and verify it by reading it
    back (:func:`upload_files`); returns the number of items."""
    return upload_files(url, mission=path, settings=settings,
                        connect_timeout_s=connect_timeout_s,
                        home_limit_m=home_limit_m).mission_items


__all__ = ['Uploaded', 'upload_file', 'upload_files']
