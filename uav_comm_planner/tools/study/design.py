"""The design of a Monte Carlo study: what is drawn, and the scenario of every row.

A study is a :class:`StudyDesign`: the number of random drops (``cases``), the study seed, and
for every setting (N, M, T, P_T, V, H, the radio settings, the area's side) a constant, a grid
of values or a range drawn per scenario (:class:`Draw`). With G grid points (the product of
every grid), row ``index`` is grid point ``index % G`` of drop ``index // G``. A drop's random
numbers come from ``numpy.random.SeedSequence(seed, spawn_key=(drop,))`` alone, so a row is
the same whichever worker plans it and in whatever order, and the grid points of one drop share
its nodes and drawn settings (common random numbers: differences between grid points are not
blurred by different drops). Every scenario is planned by each method of the design's list
(:data:`~uav_comm_planner.tools.study.methods.METHODS`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import functools
import itertools
import math
from typing import Mapping

import numpy as np

from uav_comm_planner.core.drops import AREAS, random_nodes, random_scenario
from uav_comm_planner.core.fading import Fading
from uav_comm_planner.core.scenario import MAX_NODE_SLOTS, Scenario
from uav_comm_planner.errors import InvalidScenarioError, PlannerError
from uav_comm_planner.tools.study.methods import METHODS

#: The format of a study's description, the file kept with its table.
TABLE_FORMAT = 'uav_comm_planner montecarlo 1'


#: The most rows (cases x grid points) a study may have (a run lists the rows it lacks).
MAX_ROWS = 1_000_000
#: The most nodes N and slots M a study's scenario may have: a drop is made before the planner
#: checks its compute budget (max_nodes, max_node_slots: such rows are then recorded as
#: invalid), so the drop itself stays small.
MAX_STUDY_NODES = 10_000
MAX_STUDY_SLOTS = MAX_NODE_SLOTS


class StudyError(PlannerError):
    """A study cannot start or go on (bad option, foreign table, missing extra, lost cluster)."""


@dataclass(frozen=True)
class Draw:
    """One setting of a study: a constant, a grid of values, or a range drawn per scenario.

    Written ``5`` (constant), ``1,2,5`` (grid: every value, crossed with the other grids),
    ``4:12`` (uniform in [4, 12]; for integer settings every integer from 4 to 12 equally
    likely) or ``0.5:20:log`` (log-uniform, real settings only).
    """

    grid: tuple[float, ...] = ()
    low: float = math.nan
    high: float = math.nan
    log: bool = False
    integer: bool = False

    def __post_init__(self) -> None:
        if self.grid:
            if not all(math.isfinite(v) for v in self.grid):
                raise InvalidScenarioError(f'grid values must be finite, got {self.grid}')
            if self.integer and any(v != int(v) for v in self.grid):
                raise InvalidScenarioError(f'expected integers, got {self.grid}')
            if len(set(self.grid)) != len(self.grid):
                raise InvalidScenarioError(f'a grid value is repeated in {self.grid}')
            return
        if not (math.isfinite(self.low) and math.isfinite(self.high) and self.low < self.high):
            raise InvalidScenarioError(
                f'a range needs finite low < high, got {self.low:g}:{self.high:g}')
        if self.integer and (self.low != int(self.low) or self.high != int(self.high)):
            raise InvalidScenarioError(f'expected integer bounds, got {self.text}')
        if self.log and (self.integer or self.low <= 0):
            raise InvalidScenarioError(
                f'a log range needs a real setting and positive bounds, got {self.text}')

    @classmethod
    def parse(cls, text: str, *, integer: bool = False) -> 'Draw':
        """``5``, ``1,2,5``, ``4:12`` or ``0.5:20:log`` (see the class)."""
        text = str(text).strip()
        parts = text.split(':')
        log = len(parts) == 3 and parts[2].strip().lower() == 'log'
        try:
            if len(parts) == 1:
                grid = tuple(float(v) for v in text.split(','))
            elif len(parts) == 2 or log:
                low, high = float(parts[0]), float(parts[1])
            else:
                raise ValueError(text)
        except ValueError:
            raise InvalidScenarioError(
                f'expected a value, a grid A,B,C or a range LOW:HIGH[:log], got {text!r}'
            ) from None
        if len(parts) == 1:
            return cls(grid=grid, integer=integer)
        return cls(low=low, high=high, log=log, integer=integer)

    @property
    def is_range(self) -> bool:
        return not self.grid

    @property
    def text(self) -> str:
        """The canonical spelling, as :meth:`parse` reads it."""
        if self.grid:
            return ','.join(f'{v:.17g}' for v in self.grid)
        return f'{self.low:.17g}:{self.high:.17g}' + (':log' if self.log else '')

    def sample(self, rng: np.random.Generator) -> float | int:
        """One value of the range drawn from ``rng``."""
        if self.integer:
            return int(rng.integers(int(self.low), int(self.high), endpoint=True))
        if self.log:
            return float(math.exp(rng.uniform(math.log(self.low), math.log(self.high))))
        return float(rng.uniform(self.low, self.high))

    def cast(self, value: float) -> float | int:
        return int(value) if self.integer else float(value)


@dataclass(frozen=True)
class Setting:
    """A setting of the study's scenarios: its table column, command-line flag and default."""

    flag: str
    default: str | None
    help: str
    integer: bool = False


#: The settings of every scenario, in the order their ranges are drawn; the keys are the
#: table's columns and the scenario's fields (``nodes`` is N, ``slots`` is M, ``side_m`` the
#: side of the area).
SETTINGS: dict[str, Setting] = {
    'nodes': Setting('--nodes', '8', 'number of ground nodes N', integer=True),
    'slots': Setting('--slots', '60', 'number of slots M', integer=True),
    'horizon_s': Setting('--horizon', None, 'horizon T, seconds (default M seconds: slots of '
                                            "1 s as in the letter)"),
    'altitude_m': Setting('--altitude', '100', 'UAV altitude H, metres'),
    'max_speed_mps': Setting('--speed', '100', 'maximum speed V, m/s'),
    'power_budget_w': Setting('--budget', '5', 'power budget P_T, watts'),
    'bandwidth_hz': Setting('--bandwidth', '1', 'total bandwidth B, Hz'),
    'noise_psd_dbm_per_hz': Setting('--noise-dbm', '-169', 'noise PSD sigma^2, dBm/Hz'),
    'reference_gain': Setting('--beta0', '1e-3', 'channel gain beta0 at 1 m (linear)'),
    'side_m': Setting('--side', '1500', 'side of the square the nodes are dropped in (the '
                                        'disc is inscribed in it), metres'),
}
#: Start and goal rules, as fractions of the side in the area's bounding box [0, side]^2;
#: 'random' draws both uniformly in the area.
ENDPOINTS: dict[str, tuple[tuple[float, float], tuple[float, float]] | None] = {
    'diagonal': ((0.0, 0.0), (1.0, 1.0)),
    'across': ((0.0, 0.5), (1.0, 0.5)),
    'centre': ((0.5, 0.5), (0.5, 0.5)),
    'random': None,
}


#: Keeps the fading's draws apart from the scenario's own (the nodes' and the endpoints').
FADING_STREAM = 7


@dataclass(frozen=True)
class StudyDesign:
    """A Monte Carlo study: ``cases`` drops of random scenarios at each grid point.

    draws: setting name (:data:`SETTINGS`) -> :class:`Draw` (``horizon_s`` may be absent: T = M
    seconds); area: 'square' or 'disc'; endpoints: a rule of :data:`ENDPOINTS`; methods: keys
    of :data:`METHODS`, in table order; fading: each plan is also judged under it (its
    ``seed`` is not used: each row draws its own, :meth:`fading_for`).
    """

    cases: int
    seed: int = 0
    draws: Mapping[str, Draw] = field(default_factory=dict)
    area: str = 'square'
    endpoints: str = 'diagonal'
    methods: tuple[str, ...] = tuple(METHODS)
    fading: Fading | None = None

    def __post_init__(self) -> None:
        if isinstance(self.cases, bool) or not isinstance(self.cases, int) or self.cases < 1:
            raise InvalidScenarioError(f'cases must be an integer >= 1, got {self.cases!r}')
        if self.cases > MAX_ROWS:
            raise InvalidScenarioError(f'cases must be at most {MAX_ROWS}, got {self.cases}')
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise InvalidScenarioError(f'seed must be an integer >= 0, got {self.seed!r}')
        unknown = set(self.draws) - set(SETTINGS)
        if unknown:
            raise InvalidScenarioError(f'unknown settings {sorted(unknown)}; '
                                       f'known: {list(SETTINGS)}')
        draws = {}
        for name, setting in SETTINGS.items():
            value = self.draws.get(name, setting.default)
            if isinstance(value, str):
                value = Draw.parse(value, integer=setting.integer)
            if value is not None and value.integer != setting.integer:
                value = Draw.parse(value.text, integer=setting.integer)
            if value is not None:
                draws[name] = value
        object.__setattr__(self, 'draws', draws)
        for name, bound in (('nodes', MAX_STUDY_NODES), ('slots', MAX_STUDY_SLOTS)):
            largest = _largest(draws.get(name))
            if largest > bound:
                raise InvalidScenarioError(f'{name} reach {largest:g}, more than {bound} a '
                                           f'scenario may have')
        # Counted before the grid is crossed: the rows grow as the product of the grids.
        points = math.prod(len(d.grid) for d in draws.values() if not d.is_range)
        if self.cases * points > MAX_ROWS:
            raise InvalidScenarioError(f'{self.cases} cases at {points} grid points are '
                                       f'{self.cases * points} rows, more than {MAX_ROWS}')
        if self.area not in AREAS:
            raise InvalidScenarioError(f'area must be one of {AREAS}, got {self.area!r}')
        if self.endpoints not in ENDPOINTS:
            raise InvalidScenarioError(
                f'endpoints must be one of {tuple(ENDPOINTS)}, got {self.endpoints!r}')
        methods = (self.methods,) if isinstance(self.methods, str) else tuple(self.methods)
        wrong = [m for m in methods if m not in METHODS]
        if not methods or wrong or len(set(methods)) != len(methods):
            raise InvalidScenarioError(
                f'methods must name distinct entries of {tuple(METHODS)}, got {self.methods!r}')
        object.__setattr__(self, 'methods', methods)
        if self.fading is not None and not isinstance(self.fading, Fading):
            raise InvalidScenarioError(f'fading must be a Fading or None, got '
                                       f'{type(self.fading).__name__}')

    @functools.cached_property
    def grid_points(self) -> list[dict[str, float | int]]:
        """Every combination of the grid settings' values (one point when nothing is a grid)."""
        names = [name for name, draw in self.draws.items() if not draw.is_range]
        values = [[self.draws[name].cast(v) for v in self.draws[name].grid] for name in names]
        return [dict(zip(names, combo)) for combo in itertools.product(*values)]

    def fading_for(self, index: int) -> Fading:
        """The fading row ``index`` is judged under: the design's, with a seed of the study's
        seed and the row alone (the same row, the same draws, on any worker)."""
        seed = int(np.random.SeedSequence([self.seed, index, FADING_STREAM]).generate_state(1)[0])
        return Fading(self.fading.model, self.fading.k_factor_db, self.fading.samples, seed)

    @property
    def total_rows(self) -> int:
        return self.cases * len(self.grid_points)

    @property
    def swept(self) -> list[str]:
        """The settings that vary between rows (grids of several values and ranges)."""
        return [name for name, draw in self.draws.items()
                if draw.is_range or len(draw.grid) > 1]

    def to_dict(self) -> dict:
        return {'format': TABLE_FORMAT, 'cases': self.cases, 'seed': self.seed,
                'draws': {name: draw.text for name, draw in self.draws.items()},
                'area': self.area, 'endpoints': self.endpoints, 'methods': list(self.methods),
                'fading': None if self.fading is None else {
                    'model': self.fading.model, 'k_factor_db': self.fading.k_factor_db,
                    'samples': self.fading.samples}}

    @classmethod
    def from_dict(cls, data: Mapping) -> 'StudyDesign':
        if not isinstance(data, Mapping) or data.get('format') != TABLE_FORMAT:
            raise StudyError(f'not a study description of this version ({TABLE_FORMAT!r})')
        draws = dict(data['draws'])
        draws.setdefault('horizon_s', None)
        fading = data.get('fading')
        if fading is not None:
            try:
                fading = Fading(**fading)
            except TypeError:
                raise StudyError(f'the study\'s fading is not one: {fading!r}') from None
        return cls(cases=data['cases'], seed=data['seed'], draws=draws, area=data['area'],
                   endpoints=data['endpoints'], methods=tuple(data['methods']),
                   fading=fading)

    def differences(self, other: 'StudyDesign') -> list[str]:
        """The parts (other than ``cases``) in which two designs differ."""
        mine, theirs = self.to_dict(), other.to_dict()
        keys = [k for k in mine if k != 'cases' and mine[k] != theirs.get(k)]
        if 'draws' in keys:
            keys.remove('draws')
            keys += [name for name in SETTINGS
                     if mine['draws'].get(name) != theirs['draws'].get(name)]
        return keys


def _largest(draw: Draw | None) -> float:
    """The largest value a draw gives (0 for an absent one)."""
    if draw is None:
        return 0.0
    return max(draw.grid) if draw.grid else draw.high


# ---------------------------------------------------------------------------------------------
# The rows' settings and scenarios.

def _generators(design: StudyDesign, drop: int) -> tuple[np.random.Generator, ...]:
    """Independent streams of one drop: settings, nodes, endpoints."""
    sequence = np.random.SeedSequence(design.seed, spawn_key=(drop,))
    return tuple(np.random.default_rng(child) for child in sequence.spawn(3))


def row_settings(design: StudyDesign, index: int) -> tuple[dict, np.random.Generator]:
    """The settings columns of row ``index`` and the generator its nodes are drawn from."""
    if not 0 <= index < design.total_rows:
        raise InvalidScenarioError(
            f'row {index} is outside the study (0..{design.total_rows - 1})')
    drop, point = divmod(index, len(design.grid_points))
    settings_rng, nodes_rng, endpoints_rng = _generators(design, drop)
    row: dict = {'index': index, 'drop': drop, 'seed': design.seed, 'area': design.area,
                 'endpoints': design.endpoints}
    grid = design.grid_points[point]
    for name in SETTINGS:
        # Ranges draw in the fixed order of SETTINGS, so that every grid point sees the same.
        draw = design.draws.get(name)
        if draw is None:  # the horizon, when not drawn: slots of 1 s
            row[name] = float(row['slots'])
        else:
            row[name] = draw.sample(settings_rng) if draw.is_range else grid[name]
    side = row['side_m']
    rule = ENDPOINTS[design.endpoints]
    if rule is None:
        start, goal = random_nodes(endpoints_rng, 2, side, area=design.area)
    else:
        start, goal = (side * np.asarray(point_) for point_ in rule)
    row.update(start_x_m=float(start[0]), start_y_m=float(start[1]),
               goal_x_m=float(goal[0]), goal_y_m=float(goal[1]))
    return row, nodes_rng


def row_mismatch(design: StudyDesign, row: Mapping) -> str | None:
    """What in a stored row is not its study's: an index below 0, a drop, seed, area or
    endpoints other than the index gives, a grid setting other than its grid point's, or a
    drawn setting outside its range; None for a row the study could have written. Cheap (no
    drawing), so that every row of a table is checked when it is resumed or read."""
    index = row.get('index')
    if not isinstance(index, int) or not 0 <= index < 2 ** 63:
        return f'index {str(index)[:24]} is not a row of a study'
    grid = design.grid_points
    drop, point = divmod(index, len(grid))
    fixed = {'drop': drop, 'seed': design.seed, 'area': design.area,
             'endpoints': design.endpoints, **grid[point]}
    for name, value in fixed.items():
        if row.get(name) != value:
            return f'row {index} has {name} {row.get(name)!r}, its study {value!r}'
    for name, draw in design.draws.items():
        if draw.is_range and not (isinstance(row.get(name), (int, float))
                                  and draw.low <= row[name] <= draw.high):
            return (f'row {index} has {name} {row.get(name)!r}, outside its study\'s range '
                    f'{draw.text}')
    return None


def scenario_at(design: StudyDesign, index: int) -> Scenario:
    """The scenario of row ``index`` (raises InvalidScenarioError when it is refused)."""
    return row_scenario(design, *row_settings(design, index))


def row_scenario(design: StudyDesign, row: Mapping, nodes_rng: np.random.Generator) -> Scenario:
    """The scenario of a row's settings (:func:`row_settings`), its nodes drawn from
    ``nodes_rng``; raises InvalidScenarioError when the scenario is refused."""
    fields = ('altitude_m', 'max_speed_mps', 'power_budget_w', 'bandwidth_hz',
              'noise_psd_dbm_per_hz', 'reference_gain')
    return random_scenario(row['nodes'], row['slots'], nodes_rng, side_m=row['side_m'],
                           horizon_s=row['horizon_s'], area=design.area,
                           start_m=(row['start_x_m'], row['start_y_m']),
                           goal_m=(row['goal_x_m'], row['goal_y_m']),
                           **{name: row[name] for name in fields})
