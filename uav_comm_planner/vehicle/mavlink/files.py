"""Mission files: QGC WPL 110 ``.waypoints`` and QGroundControl ``.plan``, written and read.

``.waypoints`` (QGroundControl, Mission Planner, MAVProxy) is written and read through
pymavlink's mavwp; ``.plan`` is QGroundControl's JSON (file version 1, mission version 2), its
planned home position standing for row 0 and its simple items for the other rows, and its
``geoFence`` holding the plan's zones (:mod:`uav_comm_planner.vehicle.fence`; a
``.waypoints`` file has no place for them).
:func:`export_mission` writes a plan's mission (:mod:`.items`) atomically; the readers return
the rows a link uploads (:mod:`.upload`). A file that cannot be written is a
:class:`~uav_comm_planner.errors.MissionExportError`, one that cannot be read a
:class:`~uav_comm_planner.errors.MissionFileError`.
"""

from __future__ import annotations

import io
import json
import math
import os
from pathlib import Path
from typing import Callable, Sequence

from pymavlink import mavutil, mavwp

from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.core.zones import Zones
from uav_comm_planner.errors import MissionExportError, MissionFileError
from uav_comm_planner.files import OutputFolder, read_text_file, write_with
from uav_comm_planner.vehicle.fence import fence_from_zones, GeoFence
from uav_comm_planner.vehicle.flyable import VehiclePlan
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink.items import (build_mission_items, check_home,
                                                    DO_CHANGE_SPEED, FRAME_GLOBAL,
                                                    FRAME_RELATIVE_ALT, from_message,
                                                    item_message, mission_firmware,
                                                    MissionItem, NAV_WAYPOINT)

MAV = mavutil.mavlink
MISSION_FORMATS = ('.waypoints', '.plan')
VEHICLE_TYPE_QUADROTOR = MAV.MAV_TYPE_QUADROTOR
QGC_ALTITUDE_MODE_RELATIVE = 1
#: QGroundControl's own default, for a mission that never moves (no speed to report).
QGC_DEFAULT_HOVER_SPEED_MPS = 5.0
#: A mission file larger than this is refused before it is read (a full 65 535-item
#: .waypoints file is about 6 MB).
MAX_MISSION_FILE_BYTES = 16 * 1024 * 1024
#: MISSION_COUNT carries a uint16: no MAVLink mission holds more items.
MAX_MISSION_ITEMS = 65535


# Writing.

def write_waypoints(items: Sequence[MissionItem], path: Path) -> None:
    """Write QGC WPL 110 through pymavlink's mavwp, then read it back to check it."""
    loader = mavwp.MAVWPLoader()
    for seq, item in enumerate(items):
        loader.add(item_message(item, seq))
    loader.save(str(path))
    check = mavwp.MAVWPLoader()
    if check.load(str(path)) != len(items):
        raise MissionExportError(f'{path}: mavwp read back a different number of items')


def _json_number(value: float) -> float | None:
    return None if math.isnan(value) else value


def plan_document(items: Sequence[MissionItem], home: Home, *,
                  firmware: str = 'ardupilot', zones: Zones | None = None) -> dict:
    """The QGroundControl .plan JSON object (file version 1, mission version 2), its
    geoFence holding ``zones`` (anchored at ``home``) when given."""
    autopilot = mission_firmware(firmware).autopilot
    speeds = [item.params[1] for item in items if item.command == DO_CHANGE_SPEED]
    default_speed = speeds[0] if speeds else QGC_DEFAULT_HOVER_SPEED_MPS
    return {
        'fileType': 'Plan',
        'version': 1,
        'groundStation': 'QGroundControl',
        'mission': {
            'version': 2,
            'firmwareType': autopilot,
            'vehicleType': VEHICLE_TYPE_QUADROTOR,
            'cruiseSpeed': default_speed,
            'hoverSpeed': default_speed,
            'globalPlanAltitudeMode': QGC_ALTITUDE_MODE_RELATIVE,
            'plannedHomePosition': [home.latitude_deg, home.longitude_deg, home.altitude_m],
            'items': [_plan_item(item, seq) for seq, item in enumerate(items[1:], start=1)],
        },
        'geoFence': (fence_from_zones(zones, home) if zones is not None
                     else GeoFence()).plan_section(),
        'rallyPoints': {'points': [], 'version': 2},
    }


def _plan_item(item: MissionItem, seq: int) -> dict:
    entry = {
        'type': 'SimpleItem',
        'autoContinue': item.autocontinue,
        'command': item.command,
        'doJumpId': seq,
        'frame': item.frame,
        'params': [_json_number(v) for v in (*item.params, item.x, item.y, item.z)],
    }
    if item.frame == FRAME_RELATIVE_ALT:
        entry.update(AMSLAltAboveTerrain=None, Altitude=item.z,
                     AltitudeMode=QGC_ALTITUDE_MODE_RELATIVE)
    return entry


def write_plan(items: Sequence[MissionItem], path: Path, home: Home, *,
               firmware: str = 'ardupilot', zones: Zones | None = None) -> None:
    """Write a QGroundControl .plan file (with ``zones`` as its geoFence)."""
    text = json.dumps(plan_document(items, home, firmware=firmware, zones=zones), indent=4,
                      allow_nan=False)
    path.write_text(text + '\n', encoding='utf-8')


def export_mission(plan: PlanResult | VehiclePlan, path: str | os.PathLike, home: Home, *,
                   end: str = 'land', firmware: str = 'ardupilot',
                   limits: VehicleLimits | None = None, zones: Zones | None = None) -> Path:
    """Write the plan as a mission file, format from the extension; return the path written.

    ``.waypoints``: QGC WPL 110 (QGroundControl, Mission Planner, MAVProxy); ``.plan``:
    QGroundControl JSON, with ``zones`` as its geoFence. The file is replaced atomically; on
    any failure a :class:`MissionExportError` says why and a previous file at ``path`` is left
    as it was.
    """
    check_mission_path(path)
    check_home(home)
    items = build_mission_items(plan, home, end=end, firmware=firmware, limits=limits)
    return write_mission_file(items, path, home, firmware=firmware, zones=zones)


def check_mission_path(path: str | os.PathLike) -> None:
    """Refuse (:class:`MissionExportError`) a mission file name of an unknown format."""
    target = Path(path)
    if target.suffix.lower() not in MISSION_FORMATS:
        raise MissionExportError(
            f'unknown mission format {target.suffix or "(no extension)"!r} for {str(target)!r}: '
            f'use a .waypoints or .plan file')


def write_mission_file(items: Sequence[MissionItem], path: str | os.PathLike, home: Home, *,
                       firmware: str = 'ardupilot', folder: OutputFolder | None = None,
                       zones: Zones | None = None) -> Path:
    """Write mission ``items`` (:func:`~.items.build_mission_items`) as the file ``path``, its
    format from the extension, atomically (as :func:`export_mission`; a .plan's geoFence holds
    ``zones``); return the path written. With ``folder`` (opened once,
    :class:`~uav_comm_planner.files.OutputFolder`) ``path`` is a bare name inside it, written
    relative to the folder's descriptor."""
    check_mission_path(path)
    check_home(home)
    target = Path(path)
    if target.suffix.lower() == '.plan':
        def writer(temporary: Path) -> None:
            write_plan(items, temporary, home, firmware=firmware, zones=zones)
    else:
        def writer(temporary: Path) -> None:
            write_waypoints(items, temporary)
    if folder is not None:
        return _write_atomically(folder.path / target, lambda: folder.write_with(
            str(path), writer))
    return _write_atomically(target, lambda: write_with(target, writer))


def _write_atomically(target: Path, write: Callable[[], Path]) -> Path:
    try:
        return write()
    except MissionExportError:
        raise
    except (OSError, ValueError, TypeError, mavwp.MAVWPError) as exc:
        raise MissionExportError(f'cannot write {str(target)!r}: {exc}; the previous file, if '
                                 f'any, is unchanged') from exc


# Reading.

def _number(value: object) -> float:
    """A .plan parameter: null is NaN (the autopilot's default)."""
    return math.nan if value is None else float(value)


def _mission_text(target: Path) -> str:
    """The text of a mission file, read safely (a regular file, without blocking, within
    :data:`MAX_MISSION_FILE_BYTES`) or a :class:`MissionFileError`."""
    return read_text_file(target, max_bytes=MAX_MISSION_FILE_BYTES, what='mission file',
                          error=MissionFileError)


def _check_item_count(target: Path, count: int) -> None:
    if count > MAX_MISSION_ITEMS:
        raise MissionFileError(f'{str(target)!r} holds {count} items, more than a MAVLink '
                               f'mission carries ({MAX_MISSION_ITEMS})')


def read_plan(path: str | os.PathLike) -> list[MissionItem]:
    """The rows of a QGroundControl .plan file: its planned home position, then its simple
    items; raises MissionFileError for a bad file or a complex item (survey, corridor...)."""
    target = Path(path)
    text = _mission_text(target)
    try:
        mission = json.loads(text)['mission']
        latitude, longitude, altitude = (float(v) for v in mission['plannedHomePosition'])
        entries = mission['items']
        if not isinstance(entries, list):
            raise TypeError(f'items is {type(entries).__name__}, not a list')
        _check_item_count(target, len(entries) + 1)
        items = [MissionItem(NAV_WAYPOINT, FRAME_GLOBAL, x=latitude, y=longitude, z=altitude,
                             current=True)]
        for entry in entries:
            if not isinstance(entry, dict):
                raise TypeError(f'item {len(items)} is {type(entry).__name__}, not an object')
            if entry.get('type') != 'SimpleItem':
                raise MissionFileError(f'{str(target)!r}: item {len(items)} is a '
                                       f'{entry.get("type")}; only simple items are uploaded')
            p = [_number(v) for v in entry['params']]
            if len(p) != 7:
                raise ValueError(f'item {len(items)} has {len(p)} params, not 7')
            items.append(MissionItem(int(entry['command']), int(entry['frame']),
                                     (p[0], p[1], p[2], p[3]), p[4], p[5], p[6],
                                     autocontinue=bool(entry.get('autoContinue', True))))
    except RecursionError:
        raise MissionFileError(f'{str(target)!r} is nested too deeply') from None
    except (ValueError, KeyError, TypeError, OverflowError) as exc:
        raise MissionFileError(f'{str(target)!r} is not a QGroundControl .plan mission: '
                               f'{exc}') from None
    return items


def read_mission_file(path: str | os.PathLike) -> list[MissionItem]:
    """The rows of a ``.waypoints`` or ``.plan`` mission, home first."""
    target = Path(path)
    if target.suffix.lower() == '.plan':
        return read_plan(target)
    return read_waypoints(target)


def read_waypoints(path: str | os.PathLike) -> list[MissionItem]:
    """The rows of a QGC WPL 110 (or 100) file, home first; raises MissionFileError for a bad
    file. The text is read safely once, then parsed by mavwp's own line reader."""
    target = Path(path)
    if target.suffix.lower() != '.waypoints':
        raise MissionFileError(f'{str(target)!r}: a mission is a .waypoints (QGC WPL 110) or a '
                               f'.plan (QGroundControl) file')
    lines = _mission_text(target).splitlines(keepends=True)
    version = lines[0].strip() if lines else ''
    readers = {'QGC WPL 110': '_read_waypoints_v110', 'QGC WPL 100': '_read_waypoints_v100'}
    if version not in readers:
        raise MissionFileError(f'{str(target)!r} is not a QGC WPL 110 mission: its first line '
                               f'is {version[:40]!r}')
    _check_item_count(target, sum(1 for line in lines[1:]
                                  if line.strip() and not line.startswith('#')))
    loader = mavwp.MAVWPLoader()
    try:
        getattr(loader, readers[version])(io.StringIO(''.join(lines[1:])))
        items = [from_message(loader.wp(i)) for i in range(loader.count())]
    except Exception as exc:  # noqa: B902 - mavwp raises bare Exceptions for a bad file
        raise MissionFileError(f'{str(target)!r} is not a QGC WPL 110 mission: {exc}') from None
    if not items:
        raise MissionFileError(f'{str(target)!r} holds no mission item')
    return items


__all__ = [
    'MISSION_FORMATS', 'check_mission_path', 'export_mission', 'plan_document',
    'read_mission_file', 'read_plan', 'read_waypoints', 'write_mission_file', 'write_plan',
    'write_waypoints',
]
