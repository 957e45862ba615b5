"""ROS parameters <-> the planner's settings dataclasses.

Every field of :class:`~uav_comm_planner.core.scenario.Scenario`,
:class:`~uav_comm_planner.core.scenario.SolverSettings`, :class:`NodeSettings` and
:class:`~uav_comm_planner.vehicle.limits.VehicleLimits` becomes one ROS parameter of the same
name (``ground_nodes_m`` is published as ``ground_nodes``, the vehicle's limits with the prefix
``vehicle_``), typed from
the field's annotation: ``float`` -> double, ``int`` -> integer, ``bool``, ``str``, a tuple
of strings -> a string array, a point ``(x, y)`` -> a double array of two values, a tuple
of points -> a flat double array ``x1, y1, x2, y2, ...``. A field of any other type is not
exposed and keeps its default. Defaults are the letter's case I at a multirotor's 10 m/s
(:data:`DEFAULT_SCENARIO`) for the scenario and the dataclasses' own for the rest.
:func:`config_from_parameters` is the one way back from parameter values to validated
dataclasses.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
import math
import os
from pathlib import Path, PurePath
import typing
from typing import Any, Collection, Mapping, Sequence

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

from uav_comm_planner.core.energy import Battery, DEFAULT_RESERVE
from uav_comm_planner.core.fleet import FleetScenario
from uav_comm_planner.core.scenario import paper_scenario, Point, Scenario, SolverSettings
from uav_comm_planner.core.zones import Zones
from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.mission.energy import with_named_airframe
from uav_comm_planner.mission.request import check_goal_in_time, vehicle_limits
from uav_comm_planner.ros.fences import FenceReader
from uav_comm_planner.ros.fleet_params import (first_vehicle_ends, FLEET_DESCRIPTIONS, fleet_of,
                                               FleetNodeSettings)
from uav_comm_planner.vehicle.firmware import FIRMWARES
from uav_comm_planner.vehicle.flyable import check_speed
from uav_comm_planner.vehicle.geodesy import DEFAULT_HOME, Home, HOME_ALTITUDE_RANGE_M
from uav_comm_planner.vehicle.limits import VehicleLimits, VehicleParameters
from uav_comm_planner.vehicle.mavlink.battery import BATTERY_ACTIONS
from uav_comm_planner.vehicle.mavlink.files import MISSION_FORMATS
from uav_comm_planner.vehicle.mavlink.guided import STREAM_FALLBACKS
from uav_comm_planner.vehicle.mavlink.items import MISSION_ENDS
from uav_comm_planner.vehicle.mavlink.urls import parse_link_url

#: How a plan is flown with a link: a waypoint mission in AUTO, or streamed targets in GUIDED
#: (PX4: OFFBOARD).
FLIGHT_MODES = ('mission', 'stream')
#: Node settings that take one of a few names, and the names.
CHOICES = {'mission_end': MISSION_ENDS, 'mission_firmware': tuple(FIRMWARES),
           'flight_mode': FLIGHT_MODES, 'stream_fallback': STREAM_FALLBACKS,
           'battery_action': BATTERY_ACTIONS}

ParameterValue = typing.Union[bool, int, float, str, list]


@dataclass(frozen=True)
class NodeSettings:
    """How the node labels its output and where it writes the flight as a mission file.

    ``vehicle_aware`` plans for the vehicle's limits (the ``vehicle_*`` parameters, or the
    limits a ground station's parameter file ``vehicle_params_file`` sets) and publishes the
    plan as the vehicle flies it; off, the node publishes the optimiser's plan as is.

    ``mission_file`` empty means no mission is written; its extension chooses the format
    (``.waypoints`` or ``.plan``). It is a bare file name (no folder, no ``..``, not hidden)
    inside ``mission_dir``, a folder fixed when the node starts (a read-only parameter; empty
    means the node's working directory), so that whoever may set parameters cannot make the
    node write anywhere else. The home position anchors the planning frame's origin
    (east-north metres) on WGS84; ``home_altitude_m`` is above mean sea level.
    ``mavlink_url`` (empty: no vehicle link) is where every new plan is uploaded and the
    vehicle's telemetry read. A pose replans the rest of the mission only when the UAV is off
    the plan by more than ``replan_distance_m`` or ``replan_delay_s``, and at most once every
    ``replan_interval_s`` (mission clock seconds). ``flight_mode`` 'stream' flies each plan
    with a link as position, velocity and acceleration targets in GUIDED or PX4's OFFBOARD (the
    mission uploaded too); when the stream stops the vehicle goes on in AUTO or holds
    (``stream_fallback``).
    The autopilot's wind estimate is smoothed with the time constant ``wind_time_constant_s``
    and replaces ``wind_speed_mps`` / ``wind_from_deg`` in every plan; it replans when it is
    farther than ``wind_replan_mps`` from the wind of the plan in force. With a link, the
    vehicle's home is the planning frame's origin unless the home parameters are set, and a
    mission whose home or first waypoint is farther than ``home_distance_limit_m`` from the
    vehicle's home (or position) is refused before it is uploaded.
    """

    frame_id: str = 'map'
    mission_dir: str = ''
    mission_file: str = ''
    home_latitude_deg: float = DEFAULT_HOME[0]
    home_longitude_deg: float = DEFAULT_HOME[1]
    home_altitude_m: float = DEFAULT_HOME[2]
    mission_end: str = 'land'
    mission_firmware: str = 'ardupilot'
    mavlink_url: str = ''
    replan_distance_m: float = 20.0
    replan_delay_s: float = 5.0
    replan_interval_s: float = 10.0
    vehicle_aware: bool = True
    vehicle_params_file: str = ''
    flight_mode: str = 'mission'
    stream_fallback: str = 'auto'
    wind_time_constant_s: float = 20.0
    wind_replan_mps: float = 1.5
    home_distance_limit_m: float = 1000.0
    fence_file: str = ''
    fence_margin_m: float = Zones.margin_m
    airframe: str = ''
    energy_budget_wh: float = 0.0
    battery_wh: float = 0.0
    battery_reserve: float = DEFAULT_RESERVE
    battery_action: str = 'land'

    def __post_init__(self) -> None:
        if not isinstance(self.vehicle_aware, bool):
            raise InvalidScenarioError(f'vehicle_aware must be true or false, got '
                                       f'{self.vehicle_aware!r}')
        for name in ('frame_id', 'mission_dir', 'mission_file', 'vehicle_params_file',
                     'mavlink_url', 'fence_file', 'airframe', *CHOICES):
            if not isinstance(getattr(self, name), str):
                raise InvalidScenarioError(f'{name} must be a string, got '
                                           f'{getattr(self, name)!r}')
        if not self.frame_id.strip():
            raise InvalidScenarioError('frame_id must not be empty, e.g. "map"')
        for name in ('replan_distance_m', 'replan_delay_s', 'replan_interval_s',
                     'wind_time_constant_s', 'wind_replan_mps', 'home_distance_limit_m'):
            value = getattr(self, name)
            if (isinstance(value, bool) or not isinstance(value, (int, float))
                    or not math.isfinite(value) or value <= 0):
                raise InvalidScenarioError(
                    f'{name} must be a positive finite number, got {value!r}')
        for name in ('energy_budget_wh', 'battery_wh'):
            value = getattr(self, name)
            if (isinstance(value, bool) or not isinstance(value, (int, float))
                    or not math.isfinite(value) or value < 0):
                raise InvalidScenarioError(f'{name} must be a finite number >= 0 (0: none), '
                                           f'got {value!r}')
        Battery(1.0, self.battery_reserve)      # the reserve checked as a battery does
        margin = self.fence_margin_m
        if (isinstance(margin, bool) or not isinstance(margin, (int, float))
                or not math.isfinite(margin) or margin < 0):
            raise InvalidScenarioError(
                f'fence_margin_m must be a finite number >= 0, got {margin!r}')
        if '\0' in self.mission_dir:
            raise InvalidScenarioError('mission_dir must be a folder path')
        if self.mission_file:
            _check_bare_file_name(self.mission_file)
        if self.mavlink_url:
            # Checked on set: a bad link is refused now, not found by the link's thread later.
            parse_link_url(self.mavlink_url)
        try:
            self.home
        except InvalidScenarioError as exc:
            raise InvalidScenarioError(
                f'home_latitude_deg, home_longitude_deg, home_altitude_m: {exc}') from None
        for name, allowed in CHOICES.items():
            value = getattr(self, name)
            if value not in allowed:
                raise InvalidScenarioError(f'{name} must be one of {allowed}, got {value!r}')

    @property
    def mission_path(self) -> Path:
        """Where the mission is written: ``mission_file`` inside ``mission_dir``."""
        return Path(self.mission_dir or os.getcwd()) / self.mission_file

    @property
    def home(self) -> Home:
        """The WGS84 anchor of ``frame_id``."""
        return Home(self.home_latitude_deg, self.home_longitude_deg, self.home_altitude_m)


def _check_bare_file_name(name: str) -> None:
    """Refuse a mission file name that is not a plain, visible name with a mission suffix."""
    if ('/' in name or '\\' in name or '\0' in name or name.startswith('.')
            or name != name.strip()):
        raise InvalidScenarioError(
            f'mission_file must be a bare file name inside mission_dir (no folder, no "..", '
            f'not hidden), got {name!r}')
    suffix = PurePath(name).suffix.lower()
    if suffix not in MISSION_FORMATS:
        raise InvalidScenarioError(
            f'mission_file must end in one of {MISSION_FORMATS}, got {name!r}')


@dataclass(frozen=True)
class PlannerConfig:
    """Everything the node's parameters say: what to plan, how, for which vehicle, and how
    to publish it; ``fleet``: the UAVs planned together (None: one UAV, ``uavs`` 1), each
    vehicle's link in ``fleet_urls``."""

    scenario: Scenario
    settings: SolverSettings
    node: NodeSettings
    vehicle: VehicleLimits = VehicleLimits()
    fleet: FleetScenario | None = None
    fleet_urls: tuple[str, ...] = ()


#: ROS names of fields whose parameter is not named like the field.
PARAMETER_NAMES = {'ground_nodes_m': 'ground_nodes'}
#: The vehicle's limits are parameters named vehicle_<field>.
PREFIXES = {VehicleLimits: 'vehicle_'}
#: What the node plans when no parameter says otherwise: the letter's case I (nodes, radio,
#: start and goal) at a multirotor's 10 m/s, so over 400 s in 100 slots of 4 s.
DEFAULT_SCENARIO = paper_scenario('I', max_speed_mps=10.0, horizon_s=400.0, num_slots=100)

DESCRIPTIONS = {
    'ground_nodes_m': 'ground node positions w_n in frame_id as a flat list x1, y1, x2, y2, '
                      '... (metres); the ground_nodes topic replaces them',
    'altitude_m': 'flight altitude H above the ground nodes (m)',
    'max_speed_mps': 'speed limit V (m/s)',
    'horizon_s': 'mission duration T from launch to the last waypoint (s)',
    'num_slots': 'number of waypoints M; slot length delta = T / M',
    'start_m': 'launch point q0 as x, y in frame_id (m)',
    'goal_m': 'landing point qF as x, y in frame_id (m)',
    'bandwidth_hz': 'total bandwidth B shared equally by the nodes (Hz)',
    'noise_psd_dbm_per_hz': 'noise power spectral density sigma^2 (dBm/Hz)',
    'reference_gain': 'channel power gain beta0 at 1 m (linear)',
    'channel': 'channel: free-space, free-space:alpha=A, los:ENV (docs/channel.md)',
    'power_budget_w': 'total transmit power budget P_T over all nodes and slots (W)',
    'wind_speed_mps': 'wind speed (m/s) the plan is made for; 0: still air',
    'wind_from_deg': 'direction the wind blows from, degrees clockwise from north (as '
                     'weather reports and SIM_WIND_DIR give it)',
    'tolerance_bps': 'stop when an iteration gains at most this much (bit/s); epsilon',
    'relative_tolerance': 'stop when an iteration gains at most this fraction of the objective',
    'max_outer_iterations': 'limit on power steps of Algorithm 1',
    'max_inner_iterations': 'limit on SCA trajectory steps per power step',
    'max_nodes': 'largest number of ground nodes accepted (read-only: fixed at start-up)',
    'max_node_slots': 'compute budget: largest N x M, nodes times slots, a plan may take '
                      '(read-only: fixed at start-up)',
    'compute_baselines': 'also compute the straight-line and static-point baselines',
    'starts': 'initial trajectories Algorithm 1 is run from; the best plan is kept',
    'screened_tours': 'random tours screened as extra starts (0 to 100; 0: none)',
    'fast_steps': 'one SCA step per power step at a loose solver tolerance, then a tight '
                  'last step (false: full SCA loops at the tight tolerance)',
    'keep_path_length': 'every SCA step keeps the path no longer than it finds it (the '
                        'warm replans in flight set it themselves; on a first plan it binds '
                        "the letter's run too, which may then end lower)",
    'shortlist': 'how many starts, the best by one power step each, get one outer iteration '
                 'before the best is continued (1 to 100; the warm replans in flight use 1)',
    'frame_id': 'frame of the ground nodes, the UAV pose and every output',
    'mission_dir': 'folder of mission files, fixed at start-up (read-only); empty: the '
                   "node's working directory",
    'mission_file': 'write the planned flight to this file in mission_dir on every plan, and '
                    'the plan in force at once when set (a bare name ending in .waypoints or '
                    '.plan); empty: no mission file',
    'home_latitude_deg': 'WGS84 latitude of the frame origin (deg); the three home_* at their '
                         "defaults: the mission_firmware simulator's home (ArduPilot SITL's "
                         "CMAC, here; PX4 SITL's 47.397742, 8.545594, 489 m), or with "
                         "mavlink_url the vehicle's home",
    'home_longitude_deg': 'WGS84 longitude of the frame origin (deg)',
    'home_altitude_m': 'altitude of the frame origin above mean sea level (m)',
    'mission_end': 'what the mission does at the goal: land or rtl',
    'mission_firmware': 'mission dialect: ardupilot or px4',
    'mavlink_url': 'vehicle link as pymavlink takes it (tcp:HOST:PORT, udpin:0.0.0.0:14550, '
                   '/dev/ttyACM0,115200): every new plan is uploaded, telemetry starts the '
                   'mission clock at q0; empty: no link',
    'replan_distance_m': 'replan from uav_pose when the UAV is farther than this from the '
                         'planned path (m)',
    'replan_delay_s': 'replan from uav_pose when the UAV is this far behind or ahead of the '
                      'planned time (s)',
    'replan_interval_s': 'at most one replan from uav_pose in this many seconds',
    'home_distance_limit_m': "refuse to upload a mission whose home or first waypoint is "
                             "farther than this from the vehicle's home (or position) (m)",
    'vehicle_aware': 'plan for the vehicle_* limits and publish the plan as the vehicle flies '
                     'it (S-curve legs, holds shortened by starts and stops)',
    'vehicle_params_file': 'ground-station parameter file (NAME,VALUE lines) whose WPNAV_* / '
                           'MPC_* / NAV_ACC_RAD values win over the vehicle\'s own and the '
                           'defaults for the vehicle_* parameters not set explicitly; empty: none',
    'flight_mode': 'with mavlink_url, how each plan is flown: mission (uploaded, flown in AUTO) '
                   'or stream (uploaded too, then flown as position, velocity and acceleration '
                   'targets in GUIDED (PX4: OFFBOARD), timed on the autopilot clock)',
    'stream_fallback': 'when the stream stops (plan ended, node stopped, link lost): auto (go '
                       'on with the uploaded mission from the item ahead) or hold (BRAKE; PX4: '
                       'AUTO.LOITER)',
    'wind_time_constant_s': 'time constant of the smoothing of the autopilot\'s wind estimate '
                            '(autopilot s)',
    'wind_replan_mps': 'replan when the smoothed wind estimate is farther than this from the '
                       'wind of the plan in force (m/s)',
    'fence_file': 'fence file (a QGroundControl .plan geoFence or GeoJSON, docs/fences.md) '
                  'whose zones every plan keeps to and a link uploads as the vehicle\'s fence; '
                  'read when the node starts and again when home or fence_margin_m changes '
                  '(read-only); empty: none',
    'fence_margin_m': 'clearance every plan keeps from the fence\'s edges (m)',
    'airframe': "propulsion model of the vehicle (docs/energy.md): a name (zeng2019, "
                "arducopter-sitl-quad) or a YAML file; empty: for a vehicle_aware plan the "
                "firmware's default (ArduPilot: arducopter-sitl-quad, for speeds it flies); "
                'none: no energy model',
    'energy_budget_wh': "cap on the horizon's propulsion energy q0 -> qF (Wh); 0: none",
    'battery_wh': 'usable battery energy (Wh): the horizon gets what remains after the '
                  'reserve, takeoff and landing; 0: not stated (the energy is still reported, '
                  "against ArduCopter's default battery)",
    'battery_reserve': 'share of the battery kept at landing',
    'battery_action': 'with battery_wh and a link, what the vehicle is told when the battery '
                      'left cannot reach qF with the reserve: rtl, land (where it is) or hold',
    'vehicle_max_speed_mps': 'waypoint speed (WPNAV_SPEED / 100, MPC_XY_CRUISE; m/s); a vehicle_* '
                             'limit not set explicitly comes from vehicle_params_file, else '
                             "the vehicle's own (read over mavlink_url), else the firmware's "
                             'default (PX4: 5 m/s, 3 m/s/s, 4 m/s/s/s)',
    'vehicle_max_accel_mpss': 'waypoint acceleration (WPNAV_ACCEL / 100, MPC_ACC_HOR; m/s/s)',
    'vehicle_max_jerk_mpsss': 'waypoint jerk (WPNAV_JERK, MPC_JERK_AUTO; m/s/s/s)',
    'vehicle_airframe_speed_mps': 'top speed the airframe reaches, if below the waypoint '
                                  'speed (m/s; .inf: unknown)',
    'vehicle_jerk_time_s': 'time the jerk takes to build up: 2 ATC_INPUT_TC (s)',
    'vehicle_gust_margin_mps': 'airspeed kept in reserve for gusts when planning for a wind '
                               '(m/s)',
    **FLEET_DESCRIPTIONS,
}

#: The home parameters, latitude, longitude, altitude: set explicitly, they anchor the frame;
#: otherwise the firmware's simulator home does (or, with a link, the vehicle's home).
HOME_PARAMETERS_IN_ORDER = ('home_latitude_deg', 'home_longitude_deg', 'home_altitude_m')
HOME_PARAMETERS = frozenset(HOME_PARAMETERS_IN_ORDER)

#: Parameters that change only what is done with a plan, never the plan: changing one never
#: replans nor restarts the mission clock.
OUTPUT_ONLY = frozenset({
    'frame_id', 'mission_file', 'home_latitude_deg', 'home_longitude_deg', 'home_altitude_m',
    'mission_end', 'mission_firmware', 'mavlink_url', 'replan_distance_m', 'replan_delay_s',
    'replan_interval_s', 'flight_mode', 'stream_fallback', 'wind_time_constant_s',
    'wind_replan_mps', 'home_distance_limit_m', 'battery_action'})

#: Inclusive (low, high) limits shown to tools; the dataclasses check the exact domain.
RANGES = {
    'altitude_m': (0.0, 100000.0),
    'max_speed_mps': (0.0, 1000.0),
    'horizon_s': (0.0, 1.0e6),
    'num_slots': (1, 100000),
    'bandwidth_hz': (0.0, 1.0e12),
    'noise_psd_dbm_per_hz': (-300.0, 100.0),
    'reference_gain': (0.0, 1.0e6),
    'power_budget_w': (0.0, 1.0e6),
    'wind_speed_mps': (0.0, 100.0),
    'wind_from_deg': (0.0, 360.0),
    'tolerance_bps': (0.0, 1.0e12),
    'relative_tolerance': (0.0, 1.0),
    'max_outer_iterations': (1, 100000),
    'max_inner_iterations': (1, 100000),
    'max_nodes': (1, 100000),
    'max_node_slots': (1, 100000000),
    'home_latitude_deg': (-90.0, 90.0),
    'home_longitude_deg': (-180.0, 180.0),
    'home_altitude_m': HOME_ALTITUDE_RANGE_M,
    'replan_distance_m': (0.0, 1.0e6),
    'replan_delay_s': (0.0, 1.0e6),
    'replan_interval_s': (0.0, 1.0e6),
    'wind_time_constant_s': (0.0, 1.0e6),
    'wind_replan_mps': (0.0, 100.0),
    'home_distance_limit_m': (0.0, 1.0e7),
    'fence_margin_m': (0.0, 1.0e5),
    'energy_budget_wh': (0.0, 1.0e6),
    'battery_wh': (0.0, 1.0e6),
    'battery_reserve': (0.0, 0.99),
    'min_separation_m': (0.0, 1.0e5),
}
#: Fields whose value must be above the low limit of :data:`RANGES`, not at it (0 is refused):
#: a descriptor's range is inclusive, so theirs is stated in words instead.
ABOVE_LOW_LIMIT = frozenset({
    'altitude_m', 'max_speed_mps', 'horizon_s', 'bandwidth_hz', 'reference_gain',
    'power_budget_w', 'replan_distance_m', 'replan_delay_s', 'replan_interval_s',
    'wind_time_constant_s', 'wind_replan_mps', 'home_distance_limit_m'})
#: Parameters that only the node's start-up (overrides, a parameter file) may set: the
#: limits on the work a plan may take and where mission files go.
READ_ONLY = frozenset({'max_nodes', 'max_node_slots', 'mission_dir', 'fence_file', 'uavs'})

_SCALAR_KINDS = {bool: 'bool', int: 'int', float: 'float', str: 'str'}


def _kind(hint: Any) -> str | None:
    """How a field of type ``hint`` is carried by a ROS parameter, or None if it is not."""
    if hint in _SCALAR_KINDS:
        return _SCALAR_KINDS[hint]
    if hint == Point:
        return 'pair'
    if hint == tuple[Point, ...]:
        return 'pairs'
    if hint == tuple[str, ...]:
        return 'strings'
    return None


@dataclass(frozen=True)
class ParameterSpec:
    """One ROS parameter: its name, the dataclass field it fills, its default and its kind."""

    name: str
    owner: type
    field: str
    kind: str
    default: ParameterValue

    def descriptor(self) -> ParameterDescriptor:
        """The descriptor the node declares: description with units, and range if any."""
        descriptor = ParameterDescriptor(
            name=self.name,
            description=DESCRIPTIONS.get(self.name) or DESCRIPTIONS.get(
                self.field, f'{self.owner.__name__}.{self.field}'),
            read_only=self.field in READ_ONLY)
        if self.field in CHOICES:
            descriptor.additional_constraints = f'one of {", ".join(CHOICES[self.field])}'
        elif self.kind == 'pair':
            descriptor.additional_constraints = 'exactly two values: x, y'
        elif self.kind == 'pairs':
            descriptor.additional_constraints = 'an even number of values: x1, y1, x2, y2, ...'
        limits = RANGES.get(self.field)
        if limits and self.kind == 'float' and self.field in ABOVE_LOW_LIMIT:
            descriptor.additional_constraints = (f'greater than {limits[0]:g}, at most '
                                                 f'{limits[1]:g}')
        elif limits and self.kind == 'float':
            descriptor.floating_point_range = [FloatingPointRange(
                from_value=float(limits[0]), to_value=float(limits[1]), step=0.0)]
        elif limits and self.kind == 'int':
            descriptor.integer_range = [IntegerRange(
                from_value=int(limits[0]), to_value=int(limits[1]), step=1)]
        return descriptor


def to_parameter_value(value: Any, kind: str) -> ParameterValue:
    """A dataclass field value as a ROS parameter value of ``kind``."""
    if kind == 'pair':
        return [float(v) for v in value]
    if kind == 'pairs':
        return [float(v) for point in value for v in point]
    if kind == 'float':
        return float(value)
    if kind == 'strings':
        return [str(v) for v in value]
    return value


def coerced_value(value: Any, kind: str) -> Any:
    """``value`` as ``kind`` holds it where a ROS user's habitual spelling differs only in type:
    an integer where a double is declared (``power_budget_w:=2``, ``goal_m:=[2000, 0]``) and a
    whole-number double where an integer is (``num_slots:=100.0``). Anything else is returned
    as it is, for the parameter's own type check to refuse."""
    def is_number(v: Any) -> bool:
        return isinstance(v, (int, float)) and not isinstance(v, bool)

    if kind == 'float' and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if kind == 'int' and isinstance(value, float) and value.is_integer():
        return int(value)
    if (kind in ('pair', 'pairs') and not isinstance(value, (str, bytes))
            and isinstance(value, Sequence) and value and all(is_number(v) for v in value)
            and any(not isinstance(v, float) for v in value)):
        return [float(v) for v in value]
    return value


def from_parameter_value(name: str, value: Any, kind: str) -> Any:
    """A ROS parameter value back as the dataclass field value; refuses a wrong shape."""
    try:
        return _from_parameter_value(name, value, kind)
    except (TypeError, ValueError, OverflowError) as exc:
        if isinstance(exc, InvalidScenarioError):
            raise
        raise InvalidScenarioError(f'{name} has the wrong type: {value!r}') from None


def _from_parameter_value(name: str, value: Any, kind: str) -> Any:
    if kind == 'pair':
        values = [float(v) for v in value]
        if len(values) != 2:
            raise InvalidScenarioError(f'{name} must be two values x, y, got {len(values)}')
        return (values[0], values[1])
    if kind == 'pairs':
        values = [float(v) for v in value]
        if len(values) % 2:
            raise InvalidScenarioError(
                f'{name} must be a flat list x1, y1, x2, y2, ... with an even number of '
                f'values, got {len(values)}')
        return tuple(zip(values[0::2], values[1::2]))
    if kind == 'strings':
        return tuple(str(v) for v in value)
    return value


def _defaults(owner: type) -> Any:
    return DEFAULT_SCENARIO if owner is Scenario else owner()


def _specs_of(owner: type) -> list[ParameterSpec]:
    hints = typing.get_type_hints(owner)
    defaults = _defaults(owner)
    specs = []
    for field in fields(owner):
        kind = _kind(hints[field.name])
        if kind is None:
            continue
        name = PREFIXES.get(owner, '') + PARAMETER_NAMES.get(field.name, field.name)
        specs.append(ParameterSpec(
            name=name, owner=owner, field=field.name,
            kind=kind, default=to_parameter_value(getattr(defaults, field.name), kind)))
    return specs


OWNERS = (Scenario, SolverSettings, NodeSettings, VehicleLimits, FleetNodeSettings)
#: Settings fields that are not parameters, and why.
NOT_PARAMETERS = {
    (Scenario, 'max_airspeed_mps'): 'a vehicle-aware plan takes the airspeed from the vehicle '
                                    '(vehicle_airframe_speed_mps less vehicle_gust_margin_mps)',
    (Scenario, 'zones'): 'the zones come from fence_file, anchored at home',
    (Scenario, 'airframe'): 'named by the airframe parameter (a name or a file)',
    (Scenario, 'energy_budget_wh'): 'set from energy_budget_wh and battery_wh (the smaller)',
    (Scenario, 'altitude_range_m'): 'the node flies one altitude, altitude_m',
    (Scenario, 'max_climb_mps'): 'the node flies one altitude, altitude_m',
    (VehicleLimits, 'acceptance_radius_m'): "PX4's NAV_ACC_RAD: vehicle_params_file, the vehicle",
    (VehicleLimits, 'turn_gain'): "PX4's MPC_XY_TRAJ_P: vehicle_params_file, the vehicle",
    (VehicleLimits, 'max_position_error_m'): "PX4's MPC_XY_ERR_MAX: vehicle_params_file, the "
                                             'vehicle',
}


def parameter_specs() -> tuple[ParameterSpec, ...]:
    """Every parameter of the node, in declaration order: scenario, solver, node settings,
    vehicle, fleet."""
    return tuple(spec for owner in OWNERS for spec in _specs_of(owner))


def config_from_parameters(values: Mapping[str, Any],
                           explicit: Collection[str] | None = None, *,
                           fences: FenceReader | None = None,
                           vehicle_read: VehicleParameters | None = None) -> PlannerConfig:
    """Validated settings from parameter values by ROS name; missing names take defaults.

    The scenario's zones are those of ``fence_file`` (read by ``fences``, a node's
    :class:`FenceReader`; None: read now). With no ``home_*`` parameter in ``explicit``, home
    is ``mission_firmware``'s simulator home (its ``Firmware.sitl_home``).

    The vehicle's limits follow the one precedence rule
    (:func:`~uav_comm_planner.mission.request.vehicle_limits`): the ``vehicle_*`` parameters
    set explicitly (named in ``explicit``; None: every name in ``values``) over
    ``vehicle_params_file`` over ``vehicle_read`` (from the vehicle) over the defaults. Raises
    InvalidScenarioError (or its subclass InfeasibleHorizonError) with the reason.
    """
    explicit = set(values if explicit is None else explicit)
    chosen: dict[type, dict[str, Any]] = {owner: {} for owner in OWNERS}
    for spec in parameter_specs():
        value = from_parameter_value(spec.name, values.get(spec.name, spec.default), spec.kind)
        if (spec.field in ABOVE_LOW_LIMIT and isinstance(value, (int, float))
                and value > RANGES[spec.field][1]):
            # No descriptor range checks it (that would claim the low limit).
            raise InvalidScenarioError(f'{spec.name} must be at most '
                                       f'{RANGES[spec.field][1]:g}, got {value!r}')
        chosen[spec.owner][spec.field] = value
    node_fields = chosen[NodeSettings]
    if not HOME_PARAMETERS & explicit and node_fields['mission_firmware'] in FIRMWARES:
        # No home given: the firmware's simulator home, not the other firmware's.
        node_fields.update(zip(HOME_PARAMETERS_IN_ORDER,
                               FIRMWARES[node_fields['mission_firmware']].sitl_home))
    settings = SolverSettings(**chosen[SolverSettings])
    fleet = FleetNodeSettings(**chosen[FleetNodeSettings])
    chosen[Scenario].update(first_vehicle_ends(fleet))
    # The limit first: the scenario's own checks cost more the more nodes there are.
    settings.check_node_count(len(chosen[Scenario]['ground_nodes_m']))
    node = NodeSettings(**chosen[NodeSettings])
    # Every value checked, those a file gives way to included.
    VehicleLimits(**chosen[VehicleLimits])
    given = {spec.field: chosen[VehicleLimits][spec.field] for spec in parameter_specs()
             if spec.owner is VehicleLimits and spec.name in explicit}
    vehicle = vehicle_limits(given, node.vehicle_params_file, firmware=node.mission_firmware,
                             read=vehicle_read)
    if node.vehicle_aware:
        # A plan for the vehicle in wind keeps the vehicle's airspeed.
        chosen[Scenario]['max_airspeed_mps'] = vehicle.airspeed_for_wind_mps(
            chosen[Scenario]['wind_speed_mps'])
    scenario = with_named_airframe(
        Scenario(**chosen[Scenario], zones=(fences or FenceReader())(node)), node.airframe,
        firmware=node.mission_firmware if node.vehicle_aware else None,
        budget_wh=node.energy_budget_wh or None,
        battery=node_battery(node))
    settings.check(scenario)
    if node.vehicle_aware:
        check_speed(scenario, vehicle)
        check_goal_in_time(scenario, vehicle, node.mission_firmware)
    return PlannerConfig(scenario, settings, node, vehicle,
                         fleet_of(fleet, scenario, settings, node, vehicle), fleet.mavlink_urls)


def node_battery(node: NodeSettings) -> Battery | None:
    """The battery the node's parameters state (None: not stated)."""
    return Battery(node.battery_wh, node.battery_reserve) if node.battery_wh else None


def flat_pairs(points: Sequence[Sequence[float]]) -> list[float]:
    """Points ``[(x1, y1), (x2, y2), ...]`` as the flat list a parameter holds."""
    return to_parameter_value(points, 'pairs')


__all__ = ['FenceReader', 'HOME_PARAMETERS', 'NodeSettings', 'OUTPUT_ONLY', 'ParameterSpec',
           'PlannerConfig', 'coerced_value', 'config_from_parameters', 'flat_pairs',
           'from_parameter_value', 'parameter_specs', 'to_parameter_value']
