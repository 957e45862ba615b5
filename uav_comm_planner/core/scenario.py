"""Problem settings: the scenario (what is flown) and the solver settings (how it is solved).

Both are frozen dataclasses validated on construction. Units are in the field names; the
planning frame is east-north metres with the ground at z = 0.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
import functools
import math
import sys
from typing import Callable, Sequence

import numpy as np
from scipy.spatial import cKDTree

from uav_comm_planner.core.altitude_limits import check_scenario_altitudes
from uav_comm_planner.core.channel import Channel, parse_channel
from uav_comm_planner.core.numbers import real_number
from uav_comm_planner.core.propulsion import Airframe
from uav_comm_planner.core.zones import Zones
from uav_comm_planner.errors import (ComputeBudgetError, InfeasibleHorizonError,
                                     InvalidScenarioError)

#: Two ground nodes closer than this (metres) are treated as the same node.
DUPLICATE_NODE_DISTANCE_M = 1e-3

Point = tuple[float, float]

#: Initial trajectories Algorithm 1 can start from (see :mod:`uav_comm_planner.core.initial`).
START_NAMES = ('straight', 'hover')


#: Coordinates are east-north metres from a local origin; beyond 10 000 km they leave the Earth.
MAX_COORDINATE_M = 1.0e7
#: The shortest leg V delta a plan may have: below a micrometre no solver resolves the motion.
MIN_STEP_M = 1.0e-6
#: Default compute budget: the largest N x M (nodes times slots) a plan accepts.
MAX_NODE_SLOTS = 100_000
#: The most slots M a plan accepts, whatever N: each trajectory step is a cone programme
#: over every slot, and at M = 20 000 a default plan's nine steps take about 20 s on one core
#: (at M = 100 000, with N = 1 within the budget, well over a minute). 20 000 slots of a
#: second are five and a half hours of flight.
MAX_SLOTS = 20_000


def _point(name: str, value: Sequence[float]) -> Point:
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)) \
            or len(value) != 2:
        raise InvalidScenarioError(f'{name} must be a pair (x, y) in metres, got {value!r}')
    x, y = (real_number(name, v) for v in value)
    if not (math.isfinite(x) and math.isfinite(y)):
        raise InvalidScenarioError(f'{name} must be finite, got ({x}, {y})')
    if max(abs(x), abs(y)) > MAX_COORDINATE_M:
        raise InvalidScenarioError(
            f'{name} = ({x:g}, {y:g}) m is out of range: coordinates are metres from a local '
            f'origin, at most {MAX_COORDINATE_M:g} m')
    return (x, y)


def _positive(name: str, value: float) -> None:
    value = real_number(name, value)
    if not math.isfinite(value) or value <= 0:
        raise InvalidScenarioError(f'{name} must be a positive finite number, got {value!r}')


def _count(name: str, value: object) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) \
            or value < 1:
        raise InvalidScenarioError(f'{name} must be an integer >= 1, got {value!r}')
    return int(value)


def _integer_from(name: str, value: object, low: int, high: int) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) \
            or not low <= value <= high:
        raise InvalidScenarioError(
            f'{name} must be an integer from {low} to {high}, got {value!r}')
    return int(value)


def _flag(name: str, value: object) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise InvalidScenarioError(f'{name} must be True or False, got {value!r}')
    return bool(value)


def _finite_positive(name: str, compute: Callable[[], float], reason: str) -> float:
    """A derived quantity that must come out finite and positive (no overflow, no underflow)."""
    try:
        with np.errstate(all='raise'):
            value = float(compute())
    except (OverflowError, ZeroDivisionError, FloatingPointError):
        value = math.nan
    if not (math.isfinite(value) and value >= sys.float_info.min):
        found = 'overflows' if math.isnan(value) else f'is {value:g}'
        raise InvalidScenarioError(f'{name} {found}, out of floating-point range: {reason}')
    return value


def _check_scales(scenario: 'Scenario') -> None:
    """Refuse settings whose derived quantities leave floating point (overflow, underflow).

    Checked: sigma^2 (W/Hz), H^2, delta and V delta, the SNR per watt right above a node
    a_max = N beta0 / (H^2 B sigma^2), at the far corner of the area, and P_T a_max.
    """
    _finite_positive('sigma^2 (W/Hz)', lambda: scenario.noise_psd_w_per_hz,
                     'noise_psd_dbm_per_hz is outside what a double holds')
    _finite_positive('H^2 (m^2)', lambda: scenario.altitude_m ** 2, 'change altitude_m')
    _finite_positive('delta = T / M (s)', lambda: scenario.slot_s, 'change horizon_s or num_slots')
    step = _finite_positive('V delta (m)', lambda: scenario.max_step_m,
                            'change max_speed_mps, horizon_s or num_slots')
    if step < MIN_STEP_M:
        raise InvalidScenarioError(
            f'the longest leg V delta = {step:g} m is below {MIN_STEP_M:g} m: the UAV cannot '
            f'move measurably; raise max_speed_mps or horizon_s, or lower num_slots')
    scale = _finite_positive(
        'the SNR per watt at 1 m, N beta0 / (B sigma^2)',
        lambda: scenario.num_nodes * scenario.reference_gain / scenario.bandwidth_hz
        / scenario.noise_psd_w_per_hz, 'change reference_gain, bandwidth_hz or the noise')
    best = _finite_positive('the SNR per watt above a node, a_max', lambda: scale
                            / scenario.altitude_m ** 2, 'change altitude_m or the noise')
    _finite_positive('P_T a_max', lambda: best * scenario.power_budget_w,
                     'change power_budget_w or the noise')
    points = np.array((*scenario.ground_nodes_m, scenario.start_m, scenario.goal_m))
    span = float(np.ptp(points, axis=0).max())
    _finite_positive('the SNR per watt across the area', lambda: scale / (
        2 * span ** 2 + scenario.altitude_m ** 2), 'change altitude_m or the noise')


def _check_duplicates(scenario: Scenario) -> None:
    """Refuse two nodes within DUPLICATE_NODE_DISTANCE_M: O(N log N) with a k-d tree."""
    if scenario.num_nodes < 2:
        return
    pairs = cKDTree(scenario.nodes).query_pairs(
        np.nextafter(DUPLICATE_NODE_DISTANCE_M, 0.0), output_type='ndarray')
    if len(pairs):
        i, j = (int(v) for v in min(map(tuple, pairs.tolist())))
        raise InvalidScenarioError(
            f'duplicate ground nodes: node {i + 1} and node {j + 1} are both at '
            f'{scenario.ground_nodes_m[i]}; give each node once')


def _check_energy(scenario: Scenario) -> None:
    """The airframe is one; an energy budget needs it and at least the least energy any
    flight of the horizon takes (its M + 1 legs at the airframe's least power)."""
    if scenario.airframe is not None and not isinstance(scenario.airframe, Airframe):
        raise InvalidScenarioError(f'airframe must be an Airframe or None, got '
                                   f'{type(scenario.airframe).__name__}')
    if scenario.energy_budget_wh is None:
        return
    budget = real_number('energy_budget_wh', scenario.energy_budget_wh)
    if not (math.isfinite(budget) and budget > 0.0):
        raise InvalidScenarioError(
            f'energy_budget_wh must be positive and finite, got {scenario.energy_budget_wh!r}')
    object.__setattr__(scenario, 'energy_budget_wh', budget)
    if scenario.airframe is None:
        raise InvalidScenarioError('an energy budget needs an airframe (its propulsion '
                                   'model): give airframe')
    speed, power = scenario.airframe.least_power()
    least_wh = (scenario.num_slots + 1) * scenario.slot_s * power / 3600.0
    if budget < least_wh * (1 + 1e-9):
        raise InfeasibleHorizonError(
            f'energy budget {budget:.4g} Wh below what any flight of this horizon needs: '
            f'{least_wh:.4g} Wh ({scenario.horizon_s + scenario.slot_s:g} s of legs at the '
            f"airframe's least power, {power:.1f} W at {speed:.1f} m/s); raise "
            f'energy_budget_wh or shorten horizon_s')


def _check_zones(scenario: 'Scenario') -> None:
    """q0 and qF keep the zones' margin (a path between them may still be refused when the
    plan is made: :mod:`uav_comm_planner.core.detour`)."""
    zones = scenario.zones
    if zones is None:
        return
    if not isinstance(zones, Zones):
        raise InvalidScenarioError(f'zones must be a Zones or None, got {type(zones).__name__}')
    for name, point in (('start_m', scenario.start_m), ('goal_m', scenario.goal_m)):
        clearance = float(zones.clearance([point])[0])
        if clearance < zones.margin_m:
            where = ('inside a keep-out zone or outside the operating area'
                     if clearance < 0 else 'closer to a zone\'s edge than the margin')
            raise InfeasibleHorizonError(
                f'{name} {point} is {where}: its clearance from the zones is '
                f'{clearance:.2f} m, the margin is {zones.margin_m:g} m; move it or the zones')


def _check_wind(scenario: 'Scenario') -> None:
    """Wind and airspeed are real, and the UAV can hold its position against the wind."""
    speed = real_number('wind_speed_mps', scenario.wind_speed_mps)
    direction = real_number('wind_from_deg', scenario.wind_from_deg)
    if not (math.isfinite(speed) and speed >= 0.0):
        raise InvalidScenarioError(f'wind_speed_mps must be >= 0 and finite, got {speed!r}')
    if not math.isfinite(direction):
        raise InvalidScenarioError(f'wind_from_deg must be finite, got {direction!r}')
    object.__setattr__(scenario, 'wind_speed_mps', speed)
    object.__setattr__(scenario, 'wind_from_deg', direction)
    if scenario.max_airspeed_mps is not None:
        _positive('max_airspeed_mps', scenario.max_airspeed_mps)
        object.__setattr__(scenario, 'max_airspeed_mps', float(scenario.max_airspeed_mps))
    if speed >= scenario.airspeed_mps:
        raise InfeasibleHorizonError(
            f'a wind of {speed:g} m/s is at or above the airspeed the UAV may fly, '
            f'{scenario.airspeed_mps:g} m/s: it cannot hold its position against it; raise '
            f'max_airspeed_mps if the airframe is faster, or wait for less wind')


@dataclass(frozen=True)
class Scenario:
    """One planning problem (letter, Section II).

    ground_nodes_m: the nodes w_n = (x_n, y_n), metres, at ground level.
    start_m, goal_m: launch point q0 and landing point qF, metres, flown at ``altitude_m``.
    The horizon ``horizon_s`` = T is split into ``num_slots`` = M slots of delta = T / M.
    ``noise_psd_dbm_per_hz`` is sigma^2; ``reference_gain`` is beta0 (linear, at 1 m).

    ``max_speed_mps`` V bounds the speed over the ground (the letter's speed limit). Wind:
    ``wind_speed_mps`` blowing *from* ``wind_from_deg`` (clockwise from north, as weather
    reports and ArduPilot's SIM_WIND_DIR give it) moves the air at w (:attr:`wind_mps`), and a
    slot's ground velocity v must then also keep ||v - w|| <= V_air, the airspeed
    ``max_airspeed_mps`` (None: V). Without wind and with V_air >= V that adds nothing: the
    letter's problem exactly.

    ``zones`` (:class:`~uav_comm_planner.core.zones.Zones`, None: none) are where the UAV may
    fly: every slot point and every leg, q0 and qF included, keeps ``zones.margin_m`` inside
    the operating area and out of every keep-out zone.

    ``airframe`` (:class:`~uav_comm_planner.core.propulsion.Airframe`, None: none): its top
    airspeed bounds V_air; with ``energy_budget_wh`` the horizon's propulsion energy
    (:mod:`uav_comm_planner.core.energy`) is at most that.

    ``channel`` names the air-to-ground channel (:mod:`uav_comm_planner.core.channel`):
    'free-space' (the letter's), 'free-space:alpha=A', 'los:suburban', 'los:urban',
    'los:dense-urban', 'los:highrise-urban'; held as its canonical name.

    ``altitude_range_m`` (MIN, MAX) makes altitude a variable within it for the plans with
    altitudes (:mod:`uav_comm_planner.core.altitude`; :func:`plan` flies ``altitude_m``);
    ``max_climb_mps`` their climb limit (None: the planner's default; needs the range).
    """

    ground_nodes_m: tuple[Point, ...]
    altitude_m: float = 100.0
    max_speed_mps: float = 100.0
    horizon_s: float = 50.0
    num_slots: int = 50
    start_m: Point = (0.0, 0.0)
    goal_m: Point = (2000.0, 0.0)
    bandwidth_hz: float = 1.0
    noise_psd_dbm_per_hz: float = -169.0
    reference_gain: float = 1e-3
    power_budget_w: float = 5.0
    wind_speed_mps: float = 0.0
    wind_from_deg: float = 0.0
    max_airspeed_mps: float | None = None
    zones: Zones | None = None
    airframe: Airframe | None = None
    energy_budget_wh: float | None = None
    channel: str = 'free-space'
    altitude_range_m: tuple[float, float] | None = None
    max_climb_mps: float | None = None

    def __post_init__(self) -> None:
        nodes = self.ground_nodes_m
        if isinstance(nodes, np.ndarray):
            nodes = nodes.tolist()
        if isinstance(nodes, (str, bytes)) or not isinstance(nodes, Sequence):
            raise InvalidScenarioError(
                f'ground_nodes_m must be a sequence of (x, y) pairs, got {type(nodes).__name__}')
        nodes = tuple(_point(f'ground node {i + 1}', w) for i, w in enumerate(nodes))
        if not nodes:
            raise InvalidScenarioError('no ground nodes: give at least one (x, y) position')
        object.__setattr__(self, 'ground_nodes_m', nodes)
        object.__setattr__(self, 'start_m', _point('start_m', self.start_m))
        object.__setattr__(self, 'goal_m', _point('goal_m', self.goal_m))
        for name in ('altitude_m', 'max_speed_mps', 'horizon_s', 'bandwidth_hz',
                     'reference_gain', 'power_budget_w'):
            _positive(name, getattr(self, name))
            object.__setattr__(self, name, float(getattr(self, name)))
        noise = real_number('noise_psd_dbm_per_hz', self.noise_psd_dbm_per_hz)
        if not math.isfinite(noise):
            raise InvalidScenarioError(
                f'noise_psd_dbm_per_hz must be finite, got {self.noise_psd_dbm_per_hz!r}')
        object.__setattr__(self, 'noise_psd_dbm_per_hz', noise)
        object.__setattr__(self, 'num_slots', _count('num_slots', self.num_slots))
        object.__setattr__(self, 'channel', parse_channel(self.channel).name)
        check_scenario_altitudes(self)
        _check_energy(self)
        _check_wind(self)
        _check_scales(self)
        _check_duplicates(self)
        self._check_reachable()
        _check_zones(self)

    def _check_reachable(self) -> None:
        """Every leg of the straight line q0 -> qF at uniform speed is feasible: since the
        limits are the same convex set for every leg, the mean of any feasible path's legs is
        that leg, so the goal is reachable exactly when it is."""
        distance = math.dist(self.start_m, self.goal_m)
        if distance == 0.0:
            return
        legs = self.num_slots + 1
        direction = (np.asarray(self.goal_m) - np.asarray(self.start_m)) / distance
        fastest = self.fastest_ground_speed_mps(direction)
        reach = legs * fastest * self.slot_s
        if distance > reach * (1 + 1e-12):
            needed = distance * self.num_slots / (legs * fastest) if fastest > 0 else math.inf
            limit = ('the speed limit V' if fastest >= self.max_speed_mps * (1 - 1e-12)
                     else f'V and the airspeed {self.airspeed_mps:g} m/s in the wind')
            raise InfeasibleHorizonError(
                f'goal unreachable: start and goal are {distance:.1f} m apart but the UAV covers '
                f'at most {reach:.1f} m in {legs} legs ({fastest:.3g} m/s over the ground '
                f'towards the goal, {limit}); raise horizon_s to {needed:.1f} s or more, or '
                f'max_speed_mps, or move the goal')

    def fastest_ground_speed_mps(self, direction: Sequence[float]) -> float:
        """The fastest ground speed along the unit vector ``direction`` (east, north) that keeps
        both limits: min(V, :meth:`ground_speed_at_airspeed_mps`) (V in still air)."""
        if not self.airspeed_limited:
            return self.max_speed_mps
        return min(self.max_speed_mps, self.ground_speed_at_airspeed_mps(direction))

    def ground_speed_at_airspeed_mps(self, direction: Sequence[float]) -> float:
        """The ground speed g along the unit vector ``direction`` at which the airspeed is
        V_air: ||g u - w|| = V_air, g = u.w + sqrt(V_air^2 - |w|^2 + (u.w)^2), positive since
        |w| < V_air."""
        u = np.asarray(direction, dtype=float)
        w = self.wind_mps
        along = float(u @ w)
        return along + math.sqrt(max(self.airspeed_mps ** 2 - float(w @ w) + along ** 2, 0.0))

    # Derived quantities, in the letter's notation.

    @property
    def num_nodes(self) -> int:
        """N."""
        return len(self.ground_nodes_m)

    @functools.cached_property
    def nodes(self) -> np.ndarray:
        """w: (N, 2) metres (read-only; computed once, since the planner reads it every step)."""
        nodes = np.array(self.ground_nodes_m, dtype=float)
        nodes.setflags(write=False)
        return nodes

    @functools.cached_property
    def channel_model(self) -> Channel:
        """The :class:`~uav_comm_planner.core.channel.Channel` that ``channel`` names."""
        return parse_channel(self.channel)

    @property
    def slot_s(self) -> float:
        """delta = T / M, seconds."""
        return self.horizon_s / self.num_slots

    @property
    def max_step_m(self) -> float:
        """V delta: the longest leg between consecutive waypoints, metres."""
        return self.max_speed_mps * self.slot_s

    @property
    def wind_mps(self) -> np.ndarray:
        """w: (2,) m/s east and north, the velocity of the air (it blows *towards* it)."""
        towards = math.radians(self.wind_from_deg + 180.0)
        return self.wind_speed_mps * np.array([math.sin(towards), math.cos(towards)])

    @property
    def airspeed_mps(self) -> float:
        """V_air: the fastest the UAV moves through the air, m/s (V unless given), at most the
        airframe's top airspeed."""
        airspeed = self.max_speed_mps if self.max_airspeed_mps is None else self.max_airspeed_mps
        return airspeed if self.airframe is None else min(airspeed,
                                                          self.airframe.top_airspeed_mps)

    @property
    def airspeed_limited(self) -> bool:
        """Whether the airspeed disc ||v - w|| <= V_air constrains more than ||v|| <= V."""
        return self.wind_speed_mps > 0.0 or self.airspeed_mps < self.max_speed_mps

    @property
    def drift_m(self) -> np.ndarray:
        """w delta: (2,) metres the air moves in a slot."""
        return self.wind_mps * self.slot_s

    @property
    def max_air_step_m(self) -> float:
        """V_air delta: the longest a leg may be relative to the moving air, metres."""
        return self.airspeed_mps * self.slot_s

    @property
    def noise_psd_w_per_hz(self) -> float:
        """sigma^2 in W/Hz."""
        return 10.0 ** ((self.noise_psd_dbm_per_hz - 30.0) / 10.0)

    @property
    def times_s(self) -> np.ndarray:
        """Planned time of waypoint q[m], m = 1..M: (M,) seconds (q0 at 0, qF at (M+1) delta)."""
        return self.slot_s * np.arange(1, self.num_slots + 1)

    @property
    def path_times_s(self) -> np.ndarray:
        """Planned time of q0, q[1], ..., q[M], qF: (M + 2,) seconds, 0 to (M + 1) delta."""
        return self.slot_s * np.arange(self.num_slots + 2)

    def replace(self, **changes) -> 'Scenario':
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class SolverSettings:
    """How Algorithm 1 is run.

    The alternation stops when one power step plus its trajectory loop gains at most
    ``tolerance_bps`` (the letter's epsilon, absolute) or ``relative_tolerance`` times the
    current objective, whichever is larger; each SCA loop uses the same rule. The default
    rule is relative, because rates in bit/s scale with B and shrink with N: the letter's
    absolute 0.01 stops early when rates are small. ``starts`` names the initial
    trajectories Algorithm 1 is run from ('straight', 'hover'); the best plan is kept.
    ``screened_tours`` random tours (:mod:`~uav_comm_planner.core.tours`) are screened beside
    them; ``fast_steps`` runs one SCA step per power step at a loose interior-point tolerance,
    then at the tight one for the last steps (see :func:`~uav_comm_planner.core.optimizer.
    plan`). The straight start is then the letter's own run (:meth:`letter`'s rules), so the
    plan is never below the letter's Algorithm 1. Screened, every other start gets one power
    step; the best ``shortlist`` of them by it get one outer iteration, and the best of
    these is continued.
    ``keep_path_length`` adds one constraint to every SCA step: the path q0, q[1..M], qF no
    longer than that of the step's expansion point q^k (which meets it, so Algorithm 1 still
    never loses). A warm replan in flight sets it: the plan in force, which the vehicle was
    flying on time, is improved without spending the time its corners and stops need
    (:meth:`~uav_comm_planner.core.receding.RecedingProblem.for_scenario`). Set on a first plan,
    it binds the letter's run too, which is then no longer the letter's Algorithm 1.
    ``max_nodes`` and ``max_node_slots`` bound the work a plan may take: at most
    ``max_nodes`` ground nodes and at most ``max_node_slots`` = N x M (nodes times slots; the
    memory and the time of each step grow with it).
    :meth:`letter` gives the letter's Algorithm 1 exactly.
    """

    tolerance_bps: float = 0.0
    relative_tolerance: float = 1e-4
    max_outer_iterations: int = 50
    max_inner_iterations: int = 50
    max_nodes: int = 100
    max_node_slots: int = MAX_NODE_SLOTS
    compute_baselines: bool = True
    starts: tuple[str, ...] = START_NAMES
    screened_tours: int = 80
    fast_steps: bool = True
    keep_path_length: bool = False
    shortlist: int = 2

    @classmethod
    def letter(cls, **changes: object) -> 'SolverSettings':
        """The letter's Algorithm 1: the straight-line start only, absolute epsilon 0.01, no
        screened tours, full SCA loops at the solver's tight tolerance."""
        fields = dict(tolerance_bps=0.01, relative_tolerance=0.0, starts=('straight',),
                      screened_tours=0, fast_steps=False)
        fields.update(changes)
        return cls(**fields)

    def __post_init__(self) -> None:
        for name in ('tolerance_bps', 'relative_tolerance'):
            object.__setattr__(self, name, real_number(name, getattr(self, name)))
        if not math.isfinite(self.tolerance_bps) or self.tolerance_bps < 0:
            raise InvalidScenarioError(
                f'tolerance_bps must be >= 0 and finite, got {self.tolerance_bps!r}')
        if not math.isfinite(self.relative_tolerance) or not 0 <= self.relative_tolerance < 1:
            raise InvalidScenarioError(
                f'relative_tolerance must be in [0, 1), got {self.relative_tolerance!r}')
        if self.tolerance_bps == 0 and self.relative_tolerance == 0:
            raise InvalidScenarioError('tolerance_bps and relative_tolerance cannot both be 0')
        for name in ('max_outer_iterations', 'max_inner_iterations', 'max_nodes',
                     'max_node_slots'):
            object.__setattr__(self, name, _count(name, getattr(self, name)))
        checks = (('compute_baselines', _flag), ('screened_tours', _integer_from, 0, 100),
                  ('fast_steps', _flag), ('keep_path_length', _flag),
                  ('shortlist', _integer_from, 1, 100))
        for name, check, *bounds in checks:
            object.__setattr__(self, name, check(name, getattr(self, name), *bounds))
        self._check_starts()

    def _check_starts(self) -> None:
        starts = self.starts
        if isinstance(starts, str):
            starts = (starts,)
        elif not isinstance(starts, (Sequence, np.ndarray)) or not all(
                isinstance(name, str) for name in starts):
            raise InvalidScenarioError(
                f'starts must name one or more of {START_NAMES}, got {self.starts!r}')
        starts = tuple(starts)
        unknown = [name for name in starts if name not in START_NAMES]
        if not starts or unknown:
            raise InvalidScenarioError(
                f'starts must name one or more of {START_NAMES}, got {self.starts!r}')
        object.__setattr__(self, 'starts', tuple(dict.fromkeys(starts)))

    def check_node_count(self, count: int) -> None:
        """Refuse ``count`` ground nodes when it exceeds ``max_nodes`` (before any other work)."""
        if count > self.max_nodes:
            raise InvalidScenarioError(
                f'too many ground nodes: {count} given, the limit max_nodes is '
                f'{self.max_nodes}')

    def check(self, scenario: Scenario) -> None:
        """Refuse a scenario beyond the limits: ``max_nodes``, the compute budget N x M and
        :data:`MAX_SLOTS`."""
        if not isinstance(scenario, Scenario):
            raise InvalidScenarioError(
                f'plan needs a Scenario, got {type(scenario).__name__}')
        self.check_node_count(scenario.num_nodes)
        size = scenario.num_nodes * scenario.num_slots
        if size > self.max_node_slots:
            raise ComputeBudgetError(
                f'problem too large: N x M = {scenario.num_nodes} nodes x '
                f'{scenario.num_slots} slots = {size} exceeds the compute budget '
                f'max_node_slots = {self.max_node_slots}; lower num_slots or the node count')
        if scenario.num_slots > MAX_SLOTS:
            raise ComputeBudgetError(
                f'too many slots: M = {scenario.num_slots} exceeds the most a plan takes, '
                f'MAX_SLOTS = {MAX_SLOTS}; lower num_slots (longer slots)')


PAPER_NODES_M = ((200.0, 400.0), (1000.0, 200.0), (1800.0, 400.0))
PAPER_GOALS_M = {'I': (2000.0, 0.0), 'II': (2000.0, 500.0)}


def paper_scenario(case: str = 'I', **overrides) -> Scenario:
    """The letter's Section IV setting: case 'I' ends at (2000, 0), case 'II' at (2000, 500)."""
    key = str(case).upper()
    if key not in PAPER_GOALS_M:
        raise InvalidScenarioError(f"unknown case {case!r}: the letter has cases 'I' and 'II'")
    settings = dict(
        ground_nodes_m=PAPER_NODES_M, altitude_m=100.0, max_speed_mps=100.0, horizon_s=50.0,
        num_slots=50, start_m=(0.0, 0.0), goal_m=PAPER_GOALS_M[key], bandwidth_hz=1.0,
        noise_psd_dbm_per_hz=-169.0, reference_gain=1e-3, power_budget_w=5.0)
    settings.update(overrides)
    return Scenario(**settings)
