"""MAVLink mission export: the planned flight as items an autopilot flies on the planned timing.

The plan is a sequence of points P_0 = q0, P_m = q[m] (m = 1..M), P_{M+1} = qF, reached at
t_m = m delta, in east-north metres from ``home`` at altitude H above it. The mission is

0. home (frame 0, absolute altitude), as QGroundControl and Mission Planner expect in row 0;
1. NAV_TAKEOFF to H above home (the vehicle climbs where it stands);
2. NAV_WAYPOINT at q0 (frame 3, relative altitude H). Reaching it starts the plan's clock:
   the climb and the transit from home to q0 are outside the horizon and not timed;
3. per stop, a DO_CHANGE_SPEED (ground speed) when the leg's speed differs from the one in
   force, then NAV_WAYPOINT with param1 = hold time, seconds;
4. NAV_LAND at qF, or NAV_RETURN_TO_LAUNCH.

A stop is a run of consecutive plan points that all lie within ``merge_radius_m`` of each
other: the UAV hovers there (the letter's hovering over a node), so one waypoint with a hold
stands for the whole run. Its hold is the time the plan spends inside the run; the leg into it
ends at the run's first planned time, the leg out of it starts at the run's last.

Timing. Before each leg the UAV holds until the stop's planned departure; the leg then flies at
the first of the speed in force, the plan's own speed for the leg, and the speed that lands
exactly on the next planned arrival, that is on time within 5 % of a slot; so DO_CHANGE_SPEED
appears only where the speed really changes. Speeds follow the replayed clock, not the plan's,
so rounding never accumulates: a replay of the file (leg length / commanded speed, plus holds)
reaches every waypoint at its planned time within that tolerance. Commanded speeds stay within
[``min_speed_mps``, the plan's V]; a leg slower than ``min_speed_mps`` (autopilots do not hold a
crawl of a few cm/s) is flown at that speed after holding at its start for the time left over.
ArduPilot keeps a waypoint's hold in whole seconds (AP_Mission stores param1 of NAV_WAYPOINT
in a uint16, so at most 65535 s; a longer hold is written as repeated waypoints at the same
place, each holding at most that), so for ``firmware='ardupilot'`` holds are whole seconds,
rounded down unless within the tolerance of the next one, and the next leg slows down by the
fraction. Holds shorter than the tolerance are dropped: any hold makes the
vehicle stop at the waypoint. The replay is kinematic: the autopilot's acceleration and corner
rounding are not modelled.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
import json
import math
import os
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
from pymavlink import mavutil, mavwp

from uav_comm_planner.errors import InvalidScenarioError, MissionExportError
from uav_comm_planner.files import write_with
from uav_comm_planner.vehicle.geodesy import DEFAULT_HOME, enu_to_geodetic, Home
from uav_comm_planner.core.model import flown_path
from uav_comm_planner.core.optimizer import PlanResult

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

#: Plan points closer than this are one stop. ArduCopter's default waypoint radius
#: (WPNAV_RADIUS) is 2 m: the autopilot counts points this close as reached together anyway,
#: and at H = 100 m a 2 m offset changes the channel gain by under 0.04 %.
MERGE_RADIUS_M = 2.0
#: Slowest commanded ground speed; slower legs become a hold plus a leg at this speed.
MIN_SPEED_MPS = 0.5
#: Speeds are written to 1 cm/s; the replayed clock absorbs the rounding.
SPEED_DECIMALS = 2
#: Latitude and longitude to 1e-8 degree (about 1 mm).
DEGREE_DECIMALS = 8
#: The longest hold ArduPilot stores in one NAV_WAYPOINT (param1 kept as a uint16), seconds.
ARDUPILOT_MAX_HOLD_S = 65535.0
#: A hold split into more waypoints than this (about 49 days for ArduPilot) is refused.
MAX_HOLD_PARTS = 64
#: Keep the speed in force when it reaches the next stop within this fraction of a slot.
TIMING_TOLERANCE_SLOTS = 0.05

FIRMWARE_TYPES = {'ardupilot': MAV.MAV_AUTOPILOT_ARDUPILOTMEGA, 'px4': MAV.MAV_AUTOPILOT_PX4}
MISSION_ENDS = ('land', 'rtl')
VEHICLE_TYPE_QUADROTOR = MAV.MAV_TYPE_QUADROTOR
QGC_ALTITUDE_MODE_RELATIVE = 1
#: QGroundControl's own default, for a mission that never moves (no speed to report).
QGC_DEFAULT_HOVER_SPEED_MPS = 5.0


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


@dataclass(frozen=True)
class Stop:
    """A waypoint of the timed part of the mission, in the planning frame.

    position_m: (2,) east, north metres; plan_arrival_s, plan_departure_s: the planned times of
    the first and last plan point the stop stands for; arrival_s: replayed arrival;
    hold_s: the commanded hold; speed_mps: the speed commanded on the leg out of the stop
    (None for the last stop).
    """

    position_m: np.ndarray
    plan_arrival_s: float
    plan_departure_s: float
    arrival_s: float = 0.0
    hold_s: float = 0.0
    speed_mps: float | None = None
    points: tuple[int, ...] = field(default=())


def plan_points(result: PlanResult) -> tuple[np.ndarray, np.ndarray]:
    """The flown path q0, q[1..M], qF: (M + 2, 2) metres, and its planned times (M + 2,) s."""
    scenario = result.scenario
    q = np.asarray(result.trajectory, dtype=float).reshape(-1, 2)
    times = np.asarray(result.times, dtype=float).reshape(-1)
    if len(times) != len(q) or not (np.all(np.isfinite(q)) and np.all(np.isfinite(times))):
        raise MissionExportError('the plan has no finite trajectory with one time per waypoint')
    end_time = (len(q) + 1) * scenario.slot_s
    return flown_path(q, scenario), np.concatenate([[0.0], times, [end_time]])


def hover_runs(points: np.ndarray, merge_radius_m: float) -> list[tuple[int, int]]:
    """Split points (K, 2) into maximal runs [i, j] whose points are all within the radius.

    Greedy in time order: a run grows while the next point is within ``merge_radius_m`` of
    every point already in it, so the run's diameter never exceeds the radius.
    """
    runs = []
    first = 0
    for index in range(1, len(points) + 1):
        if index < len(points):
            gaps = np.linalg.norm(points[first:index] - points[index], axis=1)
            if gaps.max() <= merge_radius_m:
                continue
        runs.append((first, index - 1))
        first = index
    return runs


def _representative(points: np.ndarray, first: int, last: int, count: int) -> int:
    """The plan point that stands for run [first, last]: q0 or qF if inside, else its medoid."""
    if first == 0:
        return 0
    if last == count - 1:
        return last
    run = points[first:last + 1]
    spread = np.linalg.norm(run[:, None, :] - run[None, :, :], axis=-1).max(axis=1)
    return first + int(np.argmin(spread))


def group_stops(points: np.ndarray, times: np.ndarray, merge_radius_m: float) -> list[Stop]:
    """The stops of a path: points (K, 2) metres reached at times (K,) seconds."""
    return [Stop(position_m=points[_representative(points, i, j, len(points))].copy(),
                 plan_arrival_s=float(times[i]), plan_departure_s=float(times[j]),
                 points=tuple(range(i, j + 1)))
            for i, j in hover_runs(points, merge_radius_m)]


@dataclass(frozen=True)
class Pace:
    """How the stops are timed.

    Commanded speeds stay in [min_speed_mps, max_speed_mps]; a speed is kept while it reaches
    the next stop within ``tolerance_s`` of the planned time; holds are whole seconds when
    ``whole_second_holds`` (ArduPilot), else hundredths of a second.
    """

    min_speed_mps: float
    max_speed_mps: float
    tolerance_s: float
    whole_second_holds: bool = True

    def bound(self, speed_mps: float) -> float:
        """A speed rounded to 1 cm/s and clipped to the allowed range."""
        return min(max(round(speed_mps, SPEED_DECIMALS), self.min_speed_mps),
                   self.max_speed_mps)


def schedule_stops(stops: Sequence[Stop], pace: Pace) -> list[Stop]:
    """Give each stop its hold and the speed of the leg out of it, replaying the clock.

    The clock is 0 at the first stop. Before each leg the UAV holds until the stop's planned
    departure (plus, for a leg slower than the minimum speed, the time that leg would crawl);
    the leg then flies at the first of: the speed in force, the plan's own speed for the leg,
    the speed that lands exactly on the next planned arrival, that is on time.
    """
    scheduled: list[Stop] = []
    clock = 0.0
    in_force: float | None = None
    for stop, following in zip(stops, list(stops[1:]) + [None]):
        wait = max(0.0, stop.plan_departure_s - clock)
        if following is None:
            scheduled.append(replace(stop, arrival_s=clock, hold_s=_quantised_hold(wait, pace)))
            break
        length = float(np.linalg.norm(following.position_m - stop.position_m))
        target = following.plan_arrival_s
        hold = _hold_before_leg(length, clock + wait, target, pace) + wait
        hold = _quantised_hold(hold, pace)
        nominal = length / max(target - stop.plan_departure_s, 1e-9)
        in_force = _leg_speed(length, clock + hold, target, (in_force, nominal), pace)
        scheduled.append(replace(stop, arrival_s=clock, hold_s=hold, speed_mps=in_force))
        clock += hold + length / in_force
    return scheduled


def _hold_before_leg(length_m: float, ready_s: float, target_s: float, pace: Pace) -> float:
    """Extra hold so that a leg too slow to command is flown at the minimum speed instead."""
    flight_s = target_s - ready_s
    if flight_s <= 0.0:
        raise MissionExportError(
            f'cannot reach a waypoint {length_m:.1f} m away by t = {target_s:.2f} s: the '
            f'mission clock is already at {ready_s:.2f} s; the plan breaks its speed limit')
    return max(0.0, flight_s - length_m / pace.min_speed_mps)


def _leg_speed(length_m: float, departure_s: float, target_s: float,
               preferred: tuple[float | None, float], pace: Pace) -> float:
    """The first preferred speed that is on time within the tolerance, else the exact one."""
    def lateness(speed: float) -> float:
        return abs(departure_s + length_m / speed - target_s)

    in_force, nominal = preferred
    for speed in (in_force, pace.bound(nominal)):
        if speed is not None and lateness(speed) <= pace.tolerance_s:
            return speed
    remaining = target_s - departure_s
    return pace.bound(length_m / remaining if remaining > 1e-9 else pace.max_speed_mps)


def _quantised_hold(hold_s: float, pace: Pace) -> float:
    """Hundredths of a second, or whole seconds (ArduPilot's resolution).

    Whole seconds round to the nearest when that is within the tolerance (a clock a few ms
    late must not cost a second of hovering), else down, so that the next leg can slow down
    to absorb the fraction.
    """
    if hold_s <= pace.tolerance_s:
        return 0.0  # any hold stops the vehicle; a few ms are not worth a stop
    if not pace.whole_second_holds:
        return round(hold_s, 2)
    nearest = round(hold_s)
    return float(nearest if abs(hold_s - nearest) <= pace.tolerance_s else math.floor(hold_s))


def plan_stops(result: PlanResult, *, firmware: str = 'ardupilot',
               merge_radius_m: float = MERGE_RADIUS_M,
               min_speed_mps: float = MIN_SPEED_MPS) -> list[Stop]:
    """The timed stops of a plan, in the planning frame (no geodesy, no I/O)."""
    _check_firmware(firmware)
    if not (math.isfinite(merge_radius_m) and merge_radius_m >= 0):
        raise MissionExportError(f'merge_radius_m must be >= 0, got {merge_radius_m!r}')
    scenario = result.scenario
    if not (math.isfinite(min_speed_mps) and 0 < min_speed_mps < scenario.max_speed_mps):
        raise MissionExportError(f'min_speed_mps must be in (0, max_speed_mps = '
                                 f'{scenario.max_speed_mps}), got {min_speed_mps!r}')
    pace = Pace(min_speed_mps=min_speed_mps, max_speed_mps=scenario.max_speed_mps,
                tolerance_s=TIMING_TOLERANCE_SLOTS * scenario.slot_s,
                whole_second_holds=firmware == 'ardupilot')
    points, times = plan_points(result)
    return schedule_stops(group_stops(points, times, merge_radius_m), pace)


def _check_firmware(firmware: str) -> None:
    if firmware not in FIRMWARE_TYPES:
        raise MissionExportError(
            f'unknown firmware {firmware!r}: choose one of {", ".join(FIRMWARE_TYPES)}')


def build_mission_items(result: PlanResult, home: Home, *, end: str = 'land',
                        firmware: str = 'ardupilot', merge_radius_m: float = MERGE_RADIUS_M,
                        min_speed_mps: float = MIN_SPEED_MPS) -> list[MissionItem]:
    """The mission rows of a plan, home first (see the module docstring for their meaning).

    Raises :class:`~uav_comm_planner.errors.MissionExportError` when a row would hold a value
    outside its format's range (a non-finite number, a latitude beyond 90 degrees...).
    """
    if not isinstance(home, Home):
        raise MissionExportError(f'home must be a Home(latitude, longitude, altitude), got '
                                 f'{home!r}')
    if end not in MISSION_ENDS:
        raise MissionExportError(f'unknown mission end {end!r}: choose land or rtl')
    stops = plan_stops(result, firmware=firmware, merge_radius_m=merge_radius_m,
                       min_speed_mps=min_speed_mps)
    # PX4 reads a yaw of 0 as "face north"; NaN keeps its own heading mode. ArduCopter
    # ignores the waypoint yaw, and Mission Planner shows NaN as an error, so it gets 0.
    yaw = math.nan if firmware == 'px4' else 0.0
    altitude = result.scenario.altitude_m
    east = np.array([stop.position_m[0] for stop in stops])
    north = np.array([stop.position_m[1] for stop in stops])
    try:
        latitude, longitude, _ = enu_to_geodetic(east, north, 0.0, home)
    except InvalidScenarioError as exc:
        raise MissionExportError(str(exc)) from None
    latitude, longitude = latitude.round(DEGREE_DECIMALS), longitude.round(DEGREE_DECIMALS)
    items = [MissionItem(NAV_WAYPOINT, FRAME_GLOBAL, x=home.latitude_deg,
                         y=home.longitude_deg, z=home.altitude_m, current=True),
             MissionItem(NAV_TAKEOFF, FRAME_RELATIVE_ALT, (0.0, 0.0, 0.0, yaw),
                         home.latitude_deg, home.longitude_deg, altitude)]
    max_hold_s = ARDUPILOT_MAX_HOLD_S if firmware == 'ardupilot' else math.inf
    items += _stop_items(stops, latitude, longitude, altitude, yaw, max_hold_s=max_hold_s)
    if end == 'land':
        items.append(MissionItem(NAV_LAND, FRAME_RELATIVE_ALT, (0.0, 0.0, 0.0, yaw),
                                 float(latitude[-1]), float(longitude[-1]), 0.0))
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


def _stop_items(stops: Sequence[Stop], latitude: np.ndarray, longitude: np.ndarray,
                altitude_m: float, yaw: float, *,
                max_hold_s: float = math.inf) -> list[MissionItem]:
    """A waypoint per stop (latitude, longitude: (S,) degrees), each leg's speed before it;
    a hold longer than ``max_hold_s`` becomes repeated waypoints at the stop."""
    items = []
    speed_in_force = None
    for index, stop in enumerate(stops):
        if index > 0 and stops[index - 1].speed_mps != speed_in_force:
            speed_in_force = stops[index - 1].speed_mps
            items.append(MissionItem(DO_CHANGE_SPEED, FRAME_MISSION,
                                     (SPEED_TYPE_GROUND, speed_in_force, THROTTLE_UNCHANGED, 0.0)))
        for hold in _hold_parts(stop.hold_s, max_hold_s):
            items.append(MissionItem(NAV_WAYPOINT, FRAME_RELATIVE_ALT, (hold, 0.0, 0.0, yaw),
                                     float(latitude[index]), float(longitude[index]),
                                     altitude_m))
    return items


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


# Writers.

def _mavlink_message(item: MissionItem, seq: int) -> object:
    return MAV.MAVLink_mission_item_message(
        target_system=0, target_component=0, seq=seq, frame=item.frame, command=item.command,
        current=int(item.current), autocontinue=int(item.autocontinue),
        param1=item.params[0], param2=item.params[1], param3=item.params[2],
        param4=item.params[3], x=item.x, y=item.y, z=item.z)


def write_waypoints(items: Sequence[MissionItem], path: Path) -> None:
    """Write QGC WPL 110 through pymavlink's mavwp, then read it back to check it."""
    loader = mavwp.MAVWPLoader()
    for seq, item in enumerate(items):
        loader.add(_mavlink_message(item, seq))
    loader.save(str(path))
    check = mavwp.MAVWPLoader()
    if check.load(str(path)) != len(items):
        raise MissionExportError(f'{path}: mavwp read back a different number of items')


def _json_number(value: float) -> float | None:
    return None if math.isnan(value) else value


def plan_document(items: Sequence[MissionItem], home: Home, *,
                  firmware: str = 'ardupilot') -> dict:
    """The QGroundControl .plan JSON object (file version 1, mission version 2)."""
    _check_firmware(firmware)
    speeds = [item.params[1] for item in items if item.command == DO_CHANGE_SPEED]
    default_speed = speeds[0] if speeds else QGC_DEFAULT_HOVER_SPEED_MPS
    return {
        'fileType': 'Plan',
        'version': 1,
        'groundStation': 'QGroundControl',
        'mission': {
            'version': 2,
            'firmwareType': FIRMWARE_TYPES[firmware],
            'vehicleType': VEHICLE_TYPE_QUADROTOR,
            'cruiseSpeed': default_speed,
            'hoverSpeed': default_speed,
            'globalPlanAltitudeMode': QGC_ALTITUDE_MODE_RELATIVE,
            'plannedHomePosition': [home.latitude_deg, home.longitude_deg, home.altitude_m],
            'items': [_plan_item(item, seq) for seq, item in enumerate(items[1:], start=1)],
        },
        'geoFence': {'circles': [], 'polygons': [], 'version': 2},
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
               firmware: str = 'ardupilot') -> None:
    """Write a QGroundControl .plan file."""
    text = json.dumps(plan_document(items, home, firmware=firmware), indent=4, allow_nan=False)
    path.write_text(text + '\n', encoding='utf-8')


MISSION_FORMATS = ('.waypoints', '.plan')


def export_mission(result: PlanResult, path: str | os.PathLike, home: Home, *,
                   end: str = 'land', firmware: str = 'ardupilot',
                   merge_radius_m: float = MERGE_RADIUS_M) -> Path:
    """Write the plan as a mission file, format from the extension; return the path written.

    ``.waypoints``: QGC WPL 110 (QGroundControl, Mission Planner, MAVProxy); ``.plan``:
    QGroundControl JSON. The file is replaced atomically; on any failure a
    :class:`MissionExportError` says why and a previous file at ``path`` is left as it was.
    """
    target = Path(path)
    suffix = target.suffix.lower()
    if suffix not in MISSION_FORMATS:
        raise MissionExportError(
            f'unknown mission format {target.suffix or "(no extension)"!r} for {str(target)!r}: '
            f'use a .waypoints or .plan file')
    items = build_mission_items(result, home, end=end, firmware=firmware,
                                merge_radius_m=merge_radius_m)
    if suffix == '.plan':
        def writer(temporary: Path) -> None:
            write_plan(items, temporary, home, firmware=firmware)
    else:
        def writer(temporary: Path) -> None:
            write_waypoints(items, temporary)
    _write_atomically(target, writer)
    return target


def _write_atomically(target: Path, writer: Callable[[Path], None]) -> None:
    try:
        write_with(target, writer)
    except MissionExportError:
        raise
    except (OSError, ValueError, TypeError, mavwp.MAVWPError) as exc:
        raise MissionExportError(f'cannot write {str(target)!r}: {exc}; the previous file, if '
                                 f'any, is unchanged') from exc


__all__ = [
    'DEFAULT_HOME', 'Home', 'MERGE_RADIUS_M', 'MIN_SPEED_MPS', 'MissionItem', 'Pace', 'Stop',
    'build_mission_items', 'export_mission', 'group_stops', 'hover_runs', 'plan_document',
    'plan_points', 'plan_stops', 'schedule_stops', 'write_plan', 'write_waypoints',
]
