"""Problem settings: the scenario (what is flown) and the solver settings (how it is solved).

Both are frozen dataclasses validated on construction. Units are in the field names; the
planning frame is east-north metres with the ground at z = 0.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
import functools
import math
from typing import Sequence

import numpy as np

from uav_comm_planner.errors import InfeasibleHorizonError, InvalidScenarioError

#: Two ground nodes closer than this (metres) are treated as the same node.
DUPLICATE_NODE_DISTANCE_M = 1e-3

Point = tuple[float, float]

#: Initial trajectories Algorithm 1 can start from (see :mod:`uav_comm_planner.core.initial`).
START_NAMES = ('straight', 'hover')


def _point(name: str, value: Sequence[float]) -> Point:
    try:
        x, y = (float(v) for v in value)
    except (TypeError, ValueError) as exc:
        raise InvalidScenarioError(
            f'{name} must be a pair (x, y) in metres, got {value!r}') from exc
    if not (math.isfinite(x) and math.isfinite(y)):
        raise InvalidScenarioError(f'{name} must be finite, got ({x}, {y})')
    return (x, y)


def _positive(name: str, value: float) -> None:
    if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise InvalidScenarioError(f'{name} must be a positive finite number, got {value!r}')


@dataclass(frozen=True)
class Scenario:
    """One planning problem (letter, Section II).

    ground_nodes_m: the nodes w_n = (x_n, y_n), metres, at ground level.
    start_m, goal_m: launch point q0 and landing point qF, metres, flown at ``altitude_m``.
    The horizon ``horizon_s`` = T is split into ``num_slots`` = M slots of delta = T / M.
    ``noise_psd_dbm_per_hz`` is sigma^2; ``reference_gain`` is beta0 (linear, at 1 m).
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

    def __post_init__(self) -> None:
        nodes = self.ground_nodes_m
        if isinstance(nodes, np.ndarray):
            nodes = nodes.tolist()
        try:
            nodes = tuple(_point(f'ground node {i + 1}', w) for i, w in enumerate(nodes))
        except TypeError as exc:
            raise InvalidScenarioError(
                'ground_nodes_m must be a sequence of (x, y) pairs') from exc
        if not nodes:
            raise InvalidScenarioError('no ground nodes: give at least one (x, y) position')
        object.__setattr__(self, 'ground_nodes_m', nodes)
        object.__setattr__(self, 'start_m', _point('start_m', self.start_m))
        object.__setattr__(self, 'goal_m', _point('goal_m', self.goal_m))
        for name in ('altitude_m', 'max_speed_mps', 'horizon_s', 'bandwidth_hz',
                     'reference_gain', 'power_budget_w'):
            _positive(name, getattr(self, name))
        if not math.isfinite(self.noise_psd_dbm_per_hz):
            raise InvalidScenarioError(
                f'noise_psd_dbm_per_hz must be finite, got {self.noise_psd_dbm_per_hz!r}')
        if isinstance(self.num_slots, bool) or not isinstance(self.num_slots, (int, np.integer)) \
                or self.num_slots < 1:
            raise InvalidScenarioError(
                f'num_slots must be an integer >= 1, got {self.num_slots!r}')
        object.__setattr__(self, 'num_slots', int(self.num_slots))
        self._check_duplicates()
        self._check_reachable()

    def _check_duplicates(self) -> None:
        w = self.nodes
        gaps = np.linalg.norm(w[:, None, :] - w[None, :, :], axis=-1)
        gaps[np.diag_indices(len(w))] = np.inf
        i, j = np.unravel_index(np.argmin(gaps), gaps.shape)
        if gaps[i, j] < DUPLICATE_NODE_DISTANCE_M:
            i, j = sorted((int(i), int(j)))
            raise InvalidScenarioError(
                f'duplicate ground nodes: node {i + 1} and node {j + 1} are both at '
                f'{self.ground_nodes_m[i]}; give each node once')

    def _check_reachable(self) -> None:
        distance = math.dist(self.start_m, self.goal_m)
        reach = (self.num_slots + 1) * self.max_speed_mps * self.slot_s
        if distance > reach * (1 + 1e-12):
            raise InfeasibleHorizonError(
                f'goal unreachable: start and goal are {distance:.1f} m apart but the UAV covers '
                f'at most (M + 1) V delta = {reach:.1f} m in {self.num_slots + 1} legs; raise '
                f'horizon_s or max_speed_mps, or move the goal')

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

    @property
    def slot_s(self) -> float:
        """delta = T / M, seconds."""
        return self.horizon_s / self.num_slots

    @property
    def max_step_m(self) -> float:
        """V delta: the longest leg between consecutive waypoints, metres."""
        return self.max_speed_mps * self.slot_s

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
    :meth:`letter` gives the letter's Algorithm 1 exactly.
    """

    tolerance_bps: float = 0.0
    relative_tolerance: float = 1e-4
    max_outer_iterations: int = 50
    max_inner_iterations: int = 50
    max_nodes: int = 100
    compute_baselines: bool = True
    starts: tuple[str, ...] = START_NAMES

    @classmethod
    def letter(cls, **changes: object) -> 'SolverSettings':
        """The letter's Algorithm 1: the straight-line start only, absolute epsilon 0.01."""
        fields = dict(tolerance_bps=0.01, relative_tolerance=0.0, starts=('straight',))
        fields.update(changes)
        return cls(**fields)

    def __post_init__(self) -> None:
        if not math.isfinite(self.tolerance_bps) or self.tolerance_bps < 0:
            raise InvalidScenarioError(
                f'tolerance_bps must be >= 0 and finite, got {self.tolerance_bps!r}')
        if not math.isfinite(self.relative_tolerance) or not 0 <= self.relative_tolerance < 1:
            raise InvalidScenarioError(
                f'relative_tolerance must be in [0, 1), got {self.relative_tolerance!r}')
        if self.tolerance_bps == 0 and self.relative_tolerance == 0:
            raise InvalidScenarioError('tolerance_bps and relative_tolerance cannot both be 0')
        for name in ('max_outer_iterations', 'max_inner_iterations', 'max_nodes'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise InvalidScenarioError(f'{name} must be an integer >= 1, got {value!r}')
        self._check_starts()

    def _check_starts(self) -> None:
        starts = (self.starts,) if isinstance(self.starts, str) else tuple(self.starts)
        unknown = [name for name in starts if name not in START_NAMES]
        if not starts or unknown:
            raise InvalidScenarioError(
                f'starts must name one or more of {START_NAMES}, got {self.starts!r}')
        object.__setattr__(self, 'starts', tuple(dict.fromkeys(starts)))

    def check(self, scenario: Scenario) -> None:
        """Refuse a scenario with more nodes than ``max_nodes``."""
        if scenario.num_nodes > self.max_nodes:
            raise InvalidScenarioError(
                f'too many ground nodes: {scenario.num_nodes} given, the limit max_nodes is '
                f'{self.max_nodes}')


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
