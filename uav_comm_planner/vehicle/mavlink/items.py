"""A plan's MAVLink mission: the items an autopilot flies on the planned timing, as messages.

The timing comes from :mod:`uav_comm_planner.vehicle.flyable`: stops where the plan hovers,
legs of fly-through waypoints between them, one cruise speed per leg, holds shortened by what
the vehicle's starts and stops cost. The mission is

0. home (frame 0, absolute altitude), as QGroundControl and Mission Planner expect in row 0;
1. NAV_TAKEOFF to H above home (the vehicle climbs where it stands); for a plan with
   altitudes, to q0's altitude, and every waypoint below at its own planned altitude;
2. NAV_WAYPOINT at q0 (frame 3, relative altitude H), param1 = the hold at q0. The plan's
   clock starts when the vehicle holds there (with no hold: when it reaches q0); the climb
   and the transit from home to q0 are outside the horizon and not timed;
3. per leg, a DO_CHANGE_SPEED (ground speed) when its speed differs from the one in force,
   its fly-through waypoints (param1 = 0), then the stop it ends at with its hold in param1
   (seconds; whole seconds for ArduPilot, which stores a uint16: a longer hold repeats the
   waypoint);
4. NAV_LAND at qF, or NAV_RETURN_TO_LAUNCH.

A row becomes the MISSION_ITEM_INT the link sends (or the MISSION_ITEM a .waypoints file
holds) and a message read back becomes a row here, in one place; :func:`mismatches` tells a
mission from what the vehicle stores of it.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Sequence

import numpy as np
from pymavlink import mavutil

from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.errors import InvalidScenarioError, MissionExportError
from uav_comm_planner.vehicle.firmware import Firmware, firmware_named
from uav_comm_planner.vehicle.flyable import check_speed, Schedule, schedule_flight, VehiclePlan
from uav_comm_planner.vehicle.geodesy import enu_to_geodetic, Home
from uav_comm_planner.vehicle.limits import VehicleLimits

MAV = mavutil.mavlink
FRAME_GLOBAL = MAV.MAV_FRAME_GLOBAL                       # 0: absolute altitude (home row)
FRAME_MISSION = MAV.MAV_FRAME_MISSION                     # 2: no position (DO commands, RTL)
FRAME_RELATIVE_ALT = MAV.MAV_FRAME_GLOBAL_RELATIVE_ALT    # 3: altitude above home
NAV_WAYPOINT = MAV.MAV_CMD_NAV_WAYPOINT
NAV_TAKEOFF = MAV.MAV_CMD_NAV_TAKEOFF
NAV_LAND = MAV.MAV_CMD_NAV_LAND
NAV_RETURN_TO_LAUNCH = MAV.MAV_CMD_NAV_RETURN_TO_LAUNCH
DO_CHANGE_SPEED = MAV.MAV_CMD_DO_CHANGE_SPEED
SPEED_TYPE_GROUND = 1.0
THROTTLE_UNCHANGED = -1.0

#: Latitude and longitude are rounded to 1e-8 degree (about 1 mm), as the .plan file keeps
#: them. The .waypoints file holds 6 decimals, because pymavlink's mavwp writes every field
#: with %f: steps of 1e-6 degree (0.11 m of latitude), so a point moves by at most 6 cm, far
#: inside the 2 m waypoint radius.
DEGREE_DECIMALS = 8
#: Holds (s) and speeds (m/s) are rounded to 1e-6, so that a file holds 6.38, not the
#: 6.380000000002752 that timing arithmetic leaves (MAVLink carries them as float32 anyway).
VALUE_DECIMALS = 6
#: A plan's own altitudes are rounded to the centimetre: ArduPilot stores a waypoint's
#: altitude in whole centimetres (and reads 88.9528 m back as 88.95 m).
ALTITUDE_DECIMALS = 2
#: A hold split into more waypoints than this (about 49 days for ArduPilot) is refused.
MAX_HOLD_PARTS = 64
#: MISSION_ITEM_INT carries latitude and longitude in 1e-7 degree.
DEGREES_E7 = 1e7
MISSION_TYPE = MAV.MAV_MISSION_TYPE_MISSION
#: Commands whose frame the autopilot does not keep.
FRAMELESS_COMMANDS_BELOW = MAV.MAV_CMD_NAV_LAST
#: Parameters stored in float32; a parameter that differs by more than this is a mismatch.
PARAM_RELATIVE_TOLERANCE = 1e-6
#: Parameters (0-based) an autopilot does not store for a command: ArduCopter keeps no yaw
#: for NAV_LAND and reports its param4 as 1.
UNSTORED_PARAMS = {MAV.MAV_CMD_NAV_LAND: (3,)}
#: A global frame and its _INT twin mean the same; PX4 stores the twin.
INT_FRAMES = {MAV.MAV_FRAME_GLOBAL_INT: MAV.MAV_FRAME_GLOBAL,
              MAV.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: MAV.MAV_FRAME_GLOBAL_RELATIVE_ALT,
              MAV.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT: MAV.MAV_FRAME_GLOBAL_TERRAIN_ALT}

#: The fence's items (mission type MAV_MISSION_TYPE_FENCE): positions whose frame the
#: autopilots do not keep.
FENCE_COMMANDS = (MAV.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                  MAV.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
                  MAV.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION,
                  MAV.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION)

MISSION_ENDS = ('land', 'rtl')
#: The mission index of q0, after home (0) and the takeoff (1): the plan's clock starts when
#: the vehicle holds there, and a plan made in flight is flown from it.
Q0_SEQ = 2
#: The mission index of the takeoff.
TAKEOFF_SEQ = 1


@dataclass(frozen=True)
class MissionItem:
    """One MISSION_ITEM row: x, y in degrees (latitude, longitude), z in metres."""

    command: int
    frame: int
    params: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    current: bool = False
    autocontinue: bool = True


def mission_firmware(name: str) -> Firmware:
    """The firmware a mission is written for; a MissionExportError for an unknown name."""
    try:
        return firmware_named(name)
    except InvalidScenarioError as exc:
        raise MissionExportError(str(exc)) from None


def check_home(home: object) -> None:
    """Refuse (:class:`MissionExportError`) a home that is not a :class:`Home`."""
    if not isinstance(home, Home):
        raise MissionExportError(f'home must be a Home(latitude, longitude, altitude), got '
                                 f'{home!r}')


def _schedule(plan: PlanResult | VehiclePlan, firmware: str,
              limits: VehicleLimits | None) -> Schedule:
    """The timed flight of ``plan``: its own when it was made for a vehicle, else scheduled."""
    if isinstance(plan, VehiclePlan):
        if plan.schedule.firmware != firmware:
            raise MissionExportError(f'the plan was timed for {plan.schedule.firmware}, not '
                                     f'{firmware}: plan it again for {firmware}')
        return plan.schedule
    if not isinstance(plan, PlanResult):
        raise MissionExportError(f'a mission is made from a plan, got {type(plan).__name__}')
    limits = VehicleLimits() if limits is None else limits
    if not isinstance(limits, VehicleLimits):
        raise MissionExportError(f'limits must be VehicleLimits, got {limits!r}')
    try:
        check_speed(plan.scenario, limits)
        return schedule_flight(plan, limits, firmware=firmware)
    except InvalidScenarioError as exc:
        raise MissionExportError(str(exc)) from None


def build_mission_items(plan: PlanResult | VehiclePlan, home: Home, *, end: str = 'land',
                        firmware: str = 'ardupilot',
                        limits: VehicleLimits | None = None) -> list[MissionItem]:
    """The mission rows of a plan, home first (see the module docstring for their meaning).

    A :class:`~uav_comm_planner.vehicle.flyable.VehiclePlan` keeps its own timing; a plain
    :class:`PlanResult` is timed here for ``limits`` (ArduCopter's defaults when None).
    """
    check_home(home)
    if end not in MISSION_ENDS:
        raise MissionExportError(f'unknown mission end {end!r}: choose land or rtl')
    dialect = mission_firmware(firmware)
    schedule = _schedule(plan, firmware, limits)
    scenario = (plan.ideal if isinstance(plan, VehiclePlan) else plan).scenario
    yaw = dialect.waypoint_yaw
    altitude = scenario.altitude_m

    def height(value: float | None) -> float:
        return altitude if value is None else round(float(value), ALTITUDE_DECIMALS)

    # The rows in order, each waypoint first as (position, hold) and all of them converted to
    # latitude and longitude in one call (the same numbers as one call each, several times
    # faster: a 500-slot plan has tens of waypoints).
    rows: list[MissionItem | tuple[np.ndarray, float]] = [
        MissionItem(NAV_WAYPOINT, FRAME_GLOBAL, x=home.latitude_deg, y=home.longitude_deg,
                    z=home.altitude_m, current=True),
        MissionItem(NAV_TAKEOFF, FRAME_RELATIVE_ALT, (0.0, 0.0, 0.0, yaw), home.latitude_deg,
                    home.longitude_deg, height(schedule.stops[0].altitude_m))]
    in_force = None
    for index, stop in enumerate(schedule.stops):
        rows += [(stop.position_m, round(hold, VALUE_DECIMALS), height(stop.altitude_m))
                 for hold in _hold_parts(stop.hold_s, dialect.max_hold_s)]
        if index == len(schedule.legs):
            break
        leg = schedule.legs[index]
        if leg.speed_mps != in_force:
            in_force = leg.speed_mps
            rows.append(MissionItem(DO_CHANGE_SPEED, FRAME_MISSION,
                                    (SPEED_TYPE_GROUND, round(in_force, VALUE_DECIMALS),
                                     THROTTLE_UNCHANGED, 0.0)))
        heights = ([None] * len(leg.vertices) if leg.altitudes_m is None
                   else leg.altitudes_m.tolist())
        rows += [(vertex, 0.0, height(up))
                 for vertex, up in zip(leg.vertices[1:-1], heights[1:-1])]
    points = np.array([row[0] for row in rows if not isinstance(row, MissionItem)],
                      dtype=float).reshape(-1, 2)
    try:
        latitudes, longitudes, _ = enu_to_geodetic(points[:, 0], points[:, 1], 0.0, home)
    except InvalidScenarioError as exc:
        raise MissionExportError(str(exc)) from None
    places = iter(zip(latitudes.tolist(), longitudes.tolist()))
    items = []
    for row in rows:
        if not isinstance(row, MissionItem):
            latitude, longitude = next(places)
            row = MissionItem(NAV_WAYPOINT, FRAME_RELATIVE_ALT, (row[1], 0.0, 0.0, yaw),
                              round(latitude, DEGREE_DECIMALS), round(longitude, DEGREE_DECIMALS),
                              row[2])
        items.append(row)
    last = items[-1]
    if end == 'land':
        items.append(MissionItem(NAV_LAND, FRAME_RELATIVE_ALT, (0.0, 0.0, 0.0, yaw),
                                 last.x, last.y, 0.0))
    else:
        items.append(MissionItem(NAV_RETURN_TO_LAUNCH, FRAME_MISSION))
    _check_items(items)
    return items


def _check_items(items: Sequence[MissionItem]) -> None:
    """Refuse rows a mission file cannot carry: non-finite values (a NaN yaw excepted, PX4's
    "keep the heading"), latitudes beyond 90 or longitudes beyond 180 degrees."""
    for seq, item in enumerate(items):
        values = (*item.params[:3], item.x, item.y, item.z)
        if not all(math.isfinite(v) for v in values) or math.isinf(item.params[3]):
            raise MissionExportError(f'mission item {seq} holds a non-finite value: {values}')
        if item.frame != FRAME_MISSION and not (abs(item.x) <= 90.0 and abs(item.y) <= 180.0):
            raise MissionExportError(f'mission item {seq} is at latitude {item.x}, longitude '
                                     f'{item.y}, outside the globe')


def _hold_parts(hold_s: float, max_hold_s: float) -> list[float]:
    """``hold_s`` as holds of at most ``max_hold_s`` each that add up to it ([0.0] for none)."""
    if hold_s <= max_hold_s:
        return [hold_s]
    whole, rest = divmod(hold_s, max_hold_s)
    if whole + (rest > 0) > MAX_HOLD_PARTS:
        raise MissionExportError(
            f'a hold of {hold_s:g} s needs more than {MAX_HOLD_PARTS} waypoints of at most '
            f'{max_hold_s:g} s each; shorten horizon_s')
    return [max_hold_s] * int(whole) + ([rest] if rest > 0 else [])


# MAVLink messages: the rows a link sends and reads back, and the rows of a .waypoints file.

def item_int_message(item: MissionItem, seq: int, mav: MAV.MAVLink, target_system: int,
                     target_component: int, *,
                     mission_type: int = MISSION_TYPE) -> MAV.MAVLink_message:
    """``item`` as the MISSION_ITEM_INT of row ``seq`` (latitude and longitude in 1e-7 degree)
    of a mission or, by ``mission_type``, a fence, encoded by ``mav``: the link's own encoder,
    whose dialect follows the protocol version the vehicle speaks."""
    return mav.mission_item_int_encode(
        target_system, target_component, seq, item.frame, item.command, int(item.current),
        int(item.autocontinue), *item.params, int(round(item.x * DEGREES_E7)),
        int(round(item.y * DEGREES_E7)), float(item.z), mission_type)


def item_message(item: MissionItem, seq: int) -> MAV.MAVLink_message:
    """``item`` as the MISSION_ITEM of row ``seq`` (degrees): the rows pymavlink's mavwp writes
    to a .waypoints file."""
    return MAV.MAVLink_mission_item_message(
        target_system=0, target_component=0, seq=seq, frame=item.frame, command=item.command,
        current=int(item.current), autocontinue=int(item.autocontinue),
        param1=item.params[0], param2=item.params[1], param3=item.params[2],
        param4=item.params[3], x=item.x, y=item.y, z=item.z)


def from_message(message: MAV.MAVLink_message) -> MissionItem:
    """The row a MISSION_ITEM_INT (a vehicle's read-back) or a MISSION_ITEM (a row mavwp read
    from a .waypoints file) holds."""
    scale = DEGREES_E7 if message.get_type() == 'MISSION_ITEM_INT' else 1.0
    return MissionItem(
        command=message.command, frame=message.frame,
        params=(message.param1, message.param2, message.param3, message.param4),
        x=message.x / scale, y=message.y / scale, z=message.z,
        current=bool(message.current), autocontinue=bool(message.autocontinue))


def mismatches(sent: Sequence[MissionItem], stored: Sequence[MissionItem], *,
               home_row: bool = True) -> list[str]:
    """What differs between a mission and its read-back, one line per item; empty if same.

    Compared in the fields the autopilot stores: row 0, when it is home (``home_row``:
    ArduPilot; PX4's missions have none), by command only, since the autopilot replaces it
    with its own; DO commands without their frame (ArduPilot reports them in frame 0); a
    frame and its _INT twin as the same (PX4 reads frame 3 back as 6); fence items by their
    position and param1 (vertex count or radius) only, which is what both autopilots keep of
    them; coordinates to 1e-7 degree (MISSION_ITEM_INT's resolution), the rest to float32's.
    """
    if len(sent) != len(stored):
        return [f'the vehicle holds {len(stored)} items, the mission has {len(sent)}']
    lines = []
    for seq, (a, b) in enumerate(zip(sent, stored)):
        if a.command != b.command:
            lines.append(f'item {seq}: command {b.command}, expected {a.command}')
        elif (seq > 0 or not home_row) and not _same_item(a, b):
            lines.append(f'item {seq}: holds {_describe(b)}, expected {_describe(a)}')
    return lines


def _same_item(a: MissionItem, b: MissionItem) -> bool:
    if a.command in FENCE_COMMANDS:
        return (all(_same_param(p, q) for p, q in zip(a.params[:1], b.params[:1]))
                and round(a.x * DEGREES_E7) == round(b.x * DEGREES_E7)
                and round(a.y * DEGREES_E7) == round(b.y * DEGREES_E7))
    if a.command >= FRAMELESS_COMMANDS_BELOW or a.frame == MAV.MAV_FRAME_MISSION:
        positional = False
    else:
        positional = True
        if INT_FRAMES.get(a.frame, a.frame) != INT_FRAMES.get(b.frame, b.frame):
            return False
    unstored = UNSTORED_PARAMS.get(a.command, ())
    close = all(_same_param(p, q) for index, (p, q) in enumerate(zip(a.params, b.params))
                if index not in unstored)
    if not positional:
        return close
    return (close and round(a.x * DEGREES_E7) == round(b.x * DEGREES_E7)
            and round(a.y * DEGREES_E7) == round(b.y * DEGREES_E7)
            and math.isclose(a.z, b.z, rel_tol=PARAM_RELATIVE_TOLERANCE, abs_tol=1e-3))


def _same_param(sent: float, stored: float) -> bool:
    if math.isnan(sent):
        return True  # NaN asks the autopilot for its own default; it stores what it chose
    return math.isclose(sent, stored, rel_tol=PARAM_RELATIVE_TOLERANCE, abs_tol=1e-6)


def _describe(item: MissionItem) -> str:
    params = ', '.join(f'{p:g}' for p in item.params)
    return f'command {item.command} frame {item.frame} ({params}) at {item.x:.7f}, ' \
           f'{item.y:.7f}, {item.z:g}'


__all__ = [
    'FENCE_COMMANDS', 'MissionItem', 'build_mission_items', 'check_home', 'from_message',
    'item_int_message', 'item_message', 'mismatches', 'mission_firmware', 'Q0_SEQ', 'TAKEOFF_SEQ',
]
