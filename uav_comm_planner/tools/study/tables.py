"""Monte Carlo studies: many random scenarios, every method on each, planned on Dask.

A study is a :class:`StudyDesign`: the number of random drops (``cases``), the study seed, and
for every setting (N, M, T, P_T, V, H, the radio settings, the area's side) a constant, a grid
of values or a range drawn per scenario (:class:`Draw`). With G grid points (the product of
every grid), row ``index`` is grid point ``index % G`` of drop ``index // G``. A drop's random
numbers come from ``numpy.random.SeedSequence(seed, spawn_key=(drop,))`` alone, so a row is
the same whichever worker plans it and in whatever order, and the grid points of one drop share
its nodes and drawn settings (common random numbers: differences between grid points are not
blurred by different drops). Every scenario is planned by each method of :data:`METHODS`.

Rows stream to a table as batches of scenarios complete: a Parquet folder (one part file per
batch, each written atomically) or a CSV file (rows appended and flushed). Running the same
study again plans only the rows the table lacks, so an interrupted study resumes where it
stopped and never loses or repeats a finished row. See ``docs/studies.md``.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
from dataclasses import dataclass, field
import functools
import itertools
import json
import logging
import math
import os
from pathlib import Path
import signal
import statistics
import sys
import tempfile
import time
from typing import Callable, Iterator, Mapping, Sequence, TextIO

import numpy as np

from uav_comm_planner.core import initial
from uav_comm_planner.core.drops import AREAS, random_nodes, random_scenario
from uav_comm_planner.core.model import average_rates
from uav_comm_planner.core.optimizer import optimal_power, plan, throughput_upper_bound
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.errors import InvalidScenarioError, PlannerError
from uav_comm_planner.files import write_text_atomic, write_with
from uav_comm_planner.tools.plots import METHOD_LABELS

INSTALL_HINT = ("pip install 'uav_comm_planner[study]' (or `make install`, which includes the "
                'study extra)')
#: Environment of every worker process: one BLAS thread, since each worker is one core.
BLAS_ONE_THREAD = {'OMP_NUM_THREADS': '1', 'OPENBLAS_NUM_THREADS': '1', 'MKL_NUM_THREADS': '1'}
#: Largest number of scenarios per Dask task.
MAX_BATCH = 50
TABLE_FORMAT = 'uav_comm_planner montecarlo 1'


class StudyError(PlannerError):
    """A study cannot start or go on (bad option, foreign table, missing extra, lost cluster)."""


# ---------------------------------------------------------------------------------------------
# The methods compared on every scenario.

@dataclass(frozen=True)
class Outcome:
    """What one method achieved on one scenario: min_n R_n in bit/s and how it got there."""

    min_throughput_bps: float
    iterations: int | None = None      # outer iterations (power steps) of Algorithm 1
    sca_steps: int | None = None       # trajectory (SCA) steps, all starts together
    status: str = 'exact'


@dataclass(frozen=True)
class Method:
    """A planning method of the study: a label for figures and ``run(scenario) -> Outcome``."""

    label: str
    run: Callable[[Scenario], Outcome]


def algorithm_outcome(settings: SolverSettings, scenario: Scenario) -> Outcome:
    """Algorithm 1 (:func:`~uav_comm_planner.core.optimizer.plan`) with ``settings``."""
    result = plan(scenario, settings)
    return Outcome(result.min_throughput, result.outer_iterations, result.trajectory_steps,
                   result.status)


def fixed_path_outcome(path: Callable[[Scenario], np.ndarray], scenario: Scenario) -> Outcome:
    """A fixed trajectory q = path(scenario) (M, 2) with its optimal (water-filling) power."""
    q = path(scenario)
    return Outcome(float(average_rates(q, optimal_power(q, scenario), scenario).min()))


def upper_bound_outcome(scenario: Scenario) -> Outcome:
    """:func:`~uav_comm_planner.core.optimizer.throughput_upper_bound`: no plan exceeds it."""
    return Outcome(throughput_upper_bound(scenario), status='bound')


#: Every method a study can run, by column prefix; a new method is one more entry.
METHODS: dict[str, Method] = {
    'default': Method('default plan (straight and hover starts)',
                      functools.partial(algorithm_outcome,
                                        SolverSettings(compute_baselines=False))),
    'letter': Method("letter's Algorithm 1",
                     functools.partial(algorithm_outcome,
                                       SolverSettings.letter(compute_baselines=False))),
    'straight': Method(METHOD_LABELS['straight'],
                       functools.partial(fixed_path_outcome, initial.straight_line)),
    'static': Method(METHOD_LABELS['static'],
                     functools.partial(fixed_path_outcome, initial.static_point)),
    'bound': Method('upper bound', upper_bound_outcome),
}
#: The letter's benchmarks, against which the figures show the gain of the other methods.
BASELINES = ('straight', 'static')


# ---------------------------------------------------------------------------------------------
# The design: what is drawn.

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


@dataclass(frozen=True)
class StudyDesign:
    """A Monte Carlo study: ``cases`` drops of random scenarios at each grid point.

    draws: setting name (:data:`SETTINGS`) -> :class:`Draw` (``horizon_s`` may be absent: T = M
    seconds); area: 'square' or 'disc'; endpoints: a rule of :data:`ENDPOINTS`; methods: keys
    of :data:`METHODS`, in table order.
    """

    cases: int
    seed: int = 0
    draws: Mapping[str, Draw] = field(default_factory=dict)
    area: str = 'square'
    endpoints: str = 'diagonal'
    methods: tuple[str, ...] = tuple(METHODS)

    def __post_init__(self) -> None:
        if isinstance(self.cases, bool) or not isinstance(self.cases, int) or self.cases < 1:
            raise InvalidScenarioError(f'cases must be an integer >= 1, got {self.cases!r}')
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

    @functools.cached_property
    def grid_points(self) -> list[dict[str, float | int]]:
        """Every combination of the grid settings' values (one point when nothing is a grid)."""
        names = [name for name, draw in self.draws.items() if not draw.is_range]
        values = [[self.draws[name].cast(v) for v in self.draws[name].grid] for name in names]
        return [dict(zip(names, combo)) for combo in itertools.product(*values)]

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
                'area': self.area, 'endpoints': self.endpoints, 'methods': list(self.methods)}

    @classmethod
    def from_dict(cls, data: Mapping) -> 'StudyDesign':
        if not isinstance(data, Mapping) or data.get('format') != TABLE_FORMAT:
            raise StudyError(f'not a study description of this version ({TABLE_FORMAT!r})')
        draws = dict(data['draws'])
        draws.setdefault('horizon_s', None)
        return cls(cases=data['cases'], seed=data['seed'], draws=draws, area=data['area'],
                   endpoints=data['endpoints'], methods=tuple(data['methods']))

    def differences(self, other: 'StudyDesign') -> list[str]:
        """The parts (other than ``cases``) in which two designs differ."""
        mine, theirs = self.to_dict(), other.to_dict()
        keys = [k for k in mine if k != 'cases' and mine[k] != theirs[k]]
        if 'draws' in keys:
            keys.remove('draws')
            keys += [name for name in SETTINGS
                     if mine['draws'].get(name) != theirs['draws'].get(name)]
        return keys


# ---------------------------------------------------------------------------------------------
# Rows: one scenario, every method.

def columns(design: StudyDesign) -> list[tuple[str, type]]:
    """The table's columns and their types (int, float, str), in order.

    index, drop, seed, area, endpoints; the settings of :data:`SETTINGS` (``horizon_s``
    always, T = M seconds when not drawn); start and goal (metres); for each method m:
    ``m_bps`` (min throughput, bit/s), ``m_iterations``, ``m_sca_steps``, ``m_s`` (wall
    time, seconds), ``m_status``; ``cpu_s``, the processor time of the whole row (below the
    sum of the wall times when the worker had to share its core); the row's ``status`` ('ok',
    'failed' when a method raised, 'invalid' when the scenario itself was refused) and
    ``error`` (empty when ok).
    """
    cols: list[tuple[str, type]] = [('index', int), ('drop', int), ('seed', int), ('area', str),
                                    ('endpoints', str)]
    cols += [(name, int if setting.integer else float) for name, setting in SETTINGS.items()]
    cols += [(name, float) for name in ('start_x_m', 'start_y_m', 'goal_x_m', 'goal_y_m')]
    for method in design.methods:
        cols += [(f'{method}_bps', float), (f'{method}_iterations', int),
                 (f'{method}_sca_steps', int), (f'{method}_s', float), (f'{method}_status', str)]
    return cols + [('cpu_s', float), ('status', str), ('error', str)]


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


def scenario_at(design: StudyDesign, index: int) -> Scenario:
    """The scenario of row ``index`` (raises InvalidScenarioError when it is refused)."""
    return _scenario(design, *row_settings(design, index))


def _scenario(design: StudyDesign, row: Mapping, nodes_rng: np.random.Generator) -> Scenario:
    fields = ('altitude_m', 'max_speed_mps', 'power_budget_w', 'bandwidth_hz',
              'noise_psd_dbm_per_hz', 'reference_gain')
    return random_scenario(row['nodes'], row['slots'], nodes_rng, side_m=row['side_m'],
                           horizon_s=row['horizon_s'], area=design.area,
                           start_m=(row['start_x_m'], row['start_y_m']),
                           goal_m=(row['goal_x_m'], row['goal_y_m']),
                           **{name: row[name] for name in fields})


def _one_line(exc: BaseException) -> str:
    text = ' '.join(str(exc).split()) or repr(exc)
    return f'{type(exc).__name__}: {text}'[:400]


def _empty_methods(design: StudyDesign, row: dict, status: str) -> None:
    for method in design.methods:
        row.update({f'{method}_bps': None, f'{method}_iterations': None,
                    f'{method}_sca_steps': None, f'{method}_s': None,
                    f'{method}_status': status})


def failed_row(design: StudyDesign, index: int, error: str) -> dict:
    """The row of a scenario whose task was lost (a worker died): settings and the error."""
    row, _ = row_settings(design, index)
    _empty_methods(design, row, 'lost')
    row.update(cpu_s=None, status='failed', error=error)
    return row


def evaluate(design: StudyDesign, index: int) -> dict:
    """Row ``index``: its settings, then every method of the design on its scenario.

    A scenario that is refused (an unreachable goal, say) gives status 'invalid'; a method
    that raises gives its columns None, its status 'error' and the row status 'failed' with
    the first error; the other methods still run.
    """
    cpu_began = time.process_time()
    row, nodes_rng = row_settings(design, index)
    errors = []
    try:
        scenario = _scenario(design, row, nodes_rng)
    except Exception as exc:  # every failure is a row, never a lost study
        _empty_methods(design, row, 'skipped')
        row.update(cpu_s=time.process_time() - cpu_began, status='invalid',
                   error=_one_line(exc))
        return row
    for method in design.methods:
        began = time.perf_counter()
        try:
            outcome = METHODS[method].run(scenario)
        except Exception as exc:  # every failure is a row, never a lost study
            outcome = Outcome(math.nan, status='error')
            errors.append(f'{method}: {_one_line(exc)}')
        row.update({
            f'{method}_bps': None if math.isnan(outcome.min_throughput_bps)
            else float(outcome.min_throughput_bps),
            f'{method}_iterations': outcome.iterations, f'{method}_sca_steps': outcome.sca_steps,
            f'{method}_s': time.perf_counter() - began, f'{method}_status': outcome.status})
    row.update(cpu_s=time.process_time() - cpu_began, status='failed' if errors else 'ok',
               error='; '.join(errors))
    return row


def plan_batch(design: StudyDesign, indices: Sequence[int]) -> list[dict]:
    """The rows of ``indices``, in order: one Dask task."""
    return [evaluate(design, index) for index in indices]


# ---------------------------------------------------------------------------------------------
# Tables on disk.

class StudyTable:
    """Rows on disk with the study's description; subclasses store them."""

    def __init__(self, path: Path, design: StudyDesign) -> None:
        self.path = Path(path)
        self.design = design
        self.columns = columns(design)

    # The description file beside (CSV) or inside (Parquet) the table.
    description: Path

    def exists(self) -> bool:
        raise NotImplementedError

    def create(self) -> None:
        raise NotImplementedError

    def append(self, rows: Sequence[dict]) -> None:
        raise NotImplementedError

    def rows(self) -> list[dict]:
        """Every row on disk, in the order written."""
        raise NotImplementedError

    def indices(self) -> set[int]:
        """The rows already in the table; refuses a table holding one row twice."""
        seen = [row['index'] for row in self.rows()]
        if len(set(seen)) != len(seen):
            raise StudyError(f'{self.path} holds some rows twice; it was not written by this '
                             'package alone')
        return set(seen)


class ParquetTable(StudyTable):
    """A folder ``NAME.parquet/`` of part files ``part-<first index>.parquet``, one per
    completed batch, and ``_study.json``, the study's description.

    Each part is written to a hidden temporary file in the folder and renamed over its name
    (:func:`uav_comm_planner.files.write_with`), so a part is there whole or not at all, and
    an interrupted write leaves at most a hidden temporary file. Parquet readers (pyarrow,
    pandas, polars, DuckDB) read the folder as one table and skip names that start with '.'
    or '_'.
    """

    @property
    def description(self) -> Path:
        return self.path / '_study.json'

    @functools.cached_property
    def schema(self):
        import pyarrow as pa
        kinds = {int: pa.int64(), float: pa.float64(), str: pa.string()}
        return pa.schema([(name, kinds[kind]) for name, kind in self.columns])

    def exists(self) -> bool:
        if self.path.is_file():
            raise StudyError(f'{self.path} is a file; a Parquet study is a folder of parts: '
                             'choose another --out')
        return self.path.is_dir() and any(self.path.iterdir())

    def create(self) -> None:
        self.path.mkdir(exist_ok=True)

    def _parts(self) -> list[Path]:
        return sorted(self.path.glob('part-*.parquet'))

    def append(self, rows: Sequence[dict]) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq
        table = pa.Table.from_pylist(list(rows), schema=self.schema)
        name = self.path / f'part-{min(row["index"] for row in rows):09d}.parquet'
        if name.exists():
            raise StudyError(f'{name} exists already; the table was changed by hand')
        write_with(name, lambda temporary: pq.write_table(table, temporary))

    def rows(self) -> list[dict]:
        import pyarrow.parquet as pq
        rows = []
        for part in self._parts():
            table = pq.read_table(part)
            if table.schema.names != self.schema.names:
                raise StudyError(f'{part} has other columns than this study')
            rows += table.to_pylist()
        return rows


class CsvTable(StudyTable):
    """A CSV file with a header row, and ``NAME.csv.json``, the study's description, beside it.

    Each batch is appended as whole lines, flushed and synced; a last line cut short by a
    crash is dropped when the study resumes. Empty fields are missing values.
    """

    @property
    def description(self) -> Path:
        return self.path.with_name(self.path.name + '.json')

    def exists(self) -> bool:
        if self.path.is_dir():
            raise StudyError(f'{self.path} is a folder; choose another --out')
        return self.path.exists()

    def create(self) -> None:
        write_text_atomic(self.path, ','.join(name for name, _ in self.columns) + '\n')

    def _cut_partial_line(self) -> None:
        with open(self.path, 'rb+') as table:
            data = table.read()
            if data and not data.endswith(b'\n'):
                table.truncate(data.rfind(b'\n') + 1)

    def append(self, rows: Sequence[dict]) -> None:
        names = [name for name, _ in self.columns]
        with open(self.path, 'a', newline='', encoding='utf-8') as table:
            writer = csv.writer(table, lineterminator='\n')
            writer.writerows([['' if row[name] is None else
                               (f'{row[name]:.17g}' if isinstance(row[name], float)
                                else row[name]) for name in names] for row in rows])
            table.flush()
            os.fsync(table.fileno())

    def rows(self) -> list[dict]:
        self._cut_partial_line()
        kinds = dict(self.columns)
        with open(self.path, newline='', encoding='utf-8') as table:
            reader = csv.DictReader(table)
            if reader.fieldnames != list(kinds):
                raise StudyError(f'{self.path} has other columns than this study')
            return [{name: _from_text(text, kinds[name]) for name, text in row.items()}
                    for row in reader]


def _from_text(text: str, kind: type):
    if kind is str:
        return text
    return None if text == '' else kind(text)


TABLES: dict[str, type[StudyTable]] = {'.parquet': ParquetTable, '.csv': CsvTable}


def table_for(path: str | os.PathLike, design: StudyDesign) -> StudyTable:
    """The table kind the suffix names: ``.parquet`` (a folder) or ``.csv``."""
    path = Path(path)
    try:
        kind = TABLES[path.suffix.lower()]
    except KeyError:
        raise StudyError(f'--out {str(path)!r}: name a .parquet folder or a .csv file') from None
    return kind(path, design)


def saved_design(path: str | os.PathLike) -> StudyDesign | None:
    """The design stored with the table at ``path``, or None when there is no table."""
    probe = table_for(path, StudyDesign(cases=1))
    if not probe.exists():
        return None
    try:
        return StudyDesign.from_dict(json.loads(probe.description.read_text(encoding='utf-8')))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise StudyError(f'{path} is not a study table of this package ({probe.description}: '
                         f'{exc})') from None


def open_table(path: str | os.PathLike, design: StudyDesign) -> tuple[StudyTable, set[int]]:
    """The table at ``path`` for ``design`` and the rows it holds (created when missing).

    A table of another study (other seed, settings, area, endpoints or methods) is refused;
    ``cases`` may grow (or shrink) to extend a study or plan only its first drops.
    """
    previous = saved_design(path)
    table = table_for(path, design)
    if previous is None:
        folder = table.path.parent
        if not folder.is_dir():
            raise StudyError(f'folder {str(folder)!r} for {str(table.path)!r} does not exist')
        table.create()
        write_text_atomic(table.description, json.dumps(design.to_dict(), indent=1) + '\n')
        return table, set()
    different = design.differences(previous)
    if different:
        raise StudyError(f'{path} holds another study (it differs in {", ".join(different)}); '
                         'run it with the same options, or choose another --out')
    if previous.cases != design.cases:
        write_text_atomic(table.description, json.dumps(design.to_dict(), indent=1) + '\n')
    return table, table.indices()


def read_table(path: str | os.PathLike) -> tuple[StudyDesign, list[dict]]:
    """The design and the rows of the table at ``path``, sorted by index."""
    design = saved_design(path)
    if design is None:
        raise StudyError(f'no study table at {str(path)!r}')
    return design, sorted(table_for(path, design).rows(), key=lambda row: row['index'])


# ---------------------------------------------------------------------------------------------
# Running on Dask.

def require_extra(*, parquet: bool) -> None:
    """Raise StudyError with the install command when Dask (or pyarrow) is missing."""
    try:
        import dask  # noqa: F401
        import distributed  # noqa: F401
        if parquet:
            import pyarrow  # noqa: F401
    except ImportError as exc:
        raise StudyError(f'montecarlo needs the study extra ({exc.name} is missing): '
                         f'{INSTALL_HINT}') from None


@contextlib.contextmanager
def _blas_one_thread() -> Iterator[None]:
    """Give worker processes spawned inside one BLAS thread each, whatever the caller's
    environment says (Dask's nanny reads it before its pre-spawn defaults)."""
    saved = {name: os.environ.get(name) for name in BLAS_ONE_THREAD}
    os.environ.update(BLAS_ONE_THREAD)
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def worker_info() -> dict:
    """Run on each worker before the study: imports the planner there (the first task does
    not pay for it) and reports the BLAS thread setting."""
    return {'pid': os.getpid(), 'omp_num_threads': os.environ.get('OMP_NUM_THREADS')}


def ignore_interrupts() -> bool:
    """Run on the embedded cluster's workers: Ctrl-C reaches the whole process group, but it
    is for the study's own process, which then stops the workers itself."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the worker's main thread: leave it
        return False
    return True


@contextlib.contextmanager
def dask_client(*, workers: int | None = None, scheduler: str | None = None,
                connect_timeout_s: float = 30.0) -> Iterator[object]:
    """A ``distributed.Client``: on the cluster at ``scheduler``, or on an embedded
    LocalCluster of ``workers`` single-threaded worker processes (default: one per core)."""
    import distributed
    # Dask reports every start and stop at INFO; a study shows its own progress instead.
    dask_logger = logging.getLogger('distributed')
    level = dask_logger.level
    dask_logger.setLevel(logging.WARNING)
    cluster = client = None
    try:
        if scheduler:
            try:
                client = distributed.Client(scheduler, timeout=f'{connect_timeout_s}s')
                client.wait_for_workers(1, timeout=connect_timeout_s)
            except (OSError, TimeoutError) as exc:
                if client is None:
                    raise StudyError(f'cannot reach the Dask scheduler at {scheduler}: '
                                     f'{exc}') from None
                raise StudyError(f'no Dask worker joined {scheduler} within '
                                 f'{connect_timeout_s:g} s; start one with `dask worker '
                                 f'{scheduler} --nthreads 1`') from None
        else:
            # The scheduler's web server on a free port of this host only: several studies
            # on one machine do not fight over 8787.
            with _blas_one_thread():
                cluster = distributed.LocalCluster(
                    n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                    processes=True, dashboard_address='127.0.0.1:0',
                    silence_logs=logging.ERROR)
            client = distributed.Client(cluster)
            client.run(ignore_interrupts)
        yield client
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
        dask_logger.setLevel(level)


def batches_of(indices: Sequence[int], size: int) -> list[list[int]]:
    return [list(indices[i:i + size]) for i in range(0, len(indices), size)]


def auto_batch_size(rows: int, slots: int) -> int:
    """About 8 tasks per worker slot (for balance at the end), at most :data:`MAX_BATCH`."""
    return max(1, min(MAX_BATCH, math.ceil(rows / (8 * max(1, slots)))))


class Progress:
    """One status line on ``stream``: rows done, a bar, rate and time left, failures.

    Redrawn in place on a terminal; elsewhere a line at most every ``every_s`` seconds.
    """

    def __init__(self, total: int, done: int, stream: TextIO | None, *,
                 every_s: float = 5.0) -> None:
        self.total, self.done, self.start_done = total, done, done
        self.failed = 0
        self.stream = stream
        self.tty = bool(stream is not None and getattr(stream, 'isatty', lambda: False)())
        self.every_s = every_s
        self.began = time.perf_counter()
        self.last_shown = -math.inf
        self.width = 0
        self.shown_done = -1

    @property
    def rate(self) -> float:
        elapsed = time.perf_counter() - self.began
        return (self.done - self.start_done) / elapsed if elapsed > 0 else 0.0

    def line(self) -> str:
        fraction = self.done / self.total if self.total else 1.0
        bar = '#' * int(24 * fraction)
        rate = self.rate
        left = (self.total - self.done) / rate if rate > 0 else math.inf
        left_text = f'{left:.0f} s left' if math.isfinite(left) else '-- s left'
        return (f'montecarlo {self.done}/{self.total} rows [{bar:<24}] {100 * fraction:3.0f}% '
                f'{rate:.2f} scenarios/s, {left_text}, {self.failed} failed')

    def update(self, rows: int, failed: int) -> None:
        self.done += rows
        self.failed += failed
        self.show()

    def show(self, *, final: bool = False) -> None:
        if self.stream is None:
            return
        now = time.perf_counter()
        if self.tty:
            line = self.line()
            self.stream.write('\r' + line.ljust(self.width) + ('\n' if final else ''))
            self.width = len(line)
        elif (final and self.done != self.shown_done) or now - self.last_shown >= self.every_s:
            self.stream.write(self.line() + '\n')
            self.last_shown, self.shown_done = now, self.done
        self.stream.flush()


@dataclass(frozen=True)
class StudyRun:
    """What one run of a study did: rows planned now, the table's size, times."""

    planned: int
    failed: int
    in_table: int
    total: int
    workers: int
    batch_size: int
    startup_s: float
    wall_s: float
    cpu_s: float
    coordinator_cpu_s: float = 0.0

    @property
    def rate(self) -> float:
        """Scenarios per second of wall time, from the first task to the last row written."""
        return self.planned / self.wall_s if self.wall_s > 0 else math.nan

    # coordinator_cpu_s: processor time of this process (client, and the embedded cluster's
    # scheduler) while the rows were planned.

    @property
    def cpu_share(self) -> float:
        """Processor time of the rows over wall time x workers: 1 when every worker planned
        on a core of its own all the time; less for scheduling, transfers, and other programs
        taking the cores."""
        return self.cpu_s / (self.wall_s * self.workers) if self.wall_s > 0 else math.nan


def run_study(design: StudyDesign, out: str | os.PathLike, *, workers: int | None = None,
              scheduler: str | None = None, batch_size: int | None = None,
              limit: int | None = None, progress: TextIO | None = None) -> StudyRun:
    """Plan the rows of ``design`` that the table at ``out`` lacks, on Dask.

    ``limit`` plans at most that many rows in this run (the rest on the next); ``batch_size``
    scenarios go to each task (default :func:`auto_batch_size`). Rows are written as batches
    complete. KeyboardInterrupt stops the study after cancelling the queued tasks; the rows
    written so far stay, and the next run goes on from there.
    """
    require_extra(parquet=Path(out).suffix.lower() == '.parquet')
    if workers is not None and workers < 1:
        raise StudyError(f'--workers must be >= 1, got {workers}')
    if batch_size is not None and not 1 <= batch_size <= 10 * MAX_BATCH:
        raise StudyError(f'--batch must be in 1..{10 * MAX_BATCH}, got {batch_size}')
    if limit is not None and limit < 1:
        raise StudyError(f'--limit must be >= 1, got {limit}')
    table, done = open_table(out, design)
    todo = [i for i in range(design.total_rows) if i not in done]
    if limit is not None:
        todo = todo[:limit]
    in_table = len(done & set(range(design.total_rows)))
    if not todo:
        return StudyRun(0, 0, in_table, design.total_rows, 0, 0, 0.0, 0.0, 0.0)
    began = time.perf_counter()
    with dask_client(workers=workers, scheduler=scheduler) as client:
        try:
            infos = client.run(worker_info)
        except Exception as exc:
            raise StudyError(f'the workers cannot run the planner ({_one_line(exc)}); install '
                             f'uav_comm_planner with the study extra where they run') from None
        threads = sum(client.nthreads().values())
        size = batch_size or auto_batch_size(len(todo), threads)
        startup_s = time.perf_counter() - began
        if progress is not None:
            pinned = all(info['omp_num_threads'] == '1' for info in infos.values())
            progress.write(f'montecarlo: {len(todo)} scenarios to plan ({in_table} of '
                           f'{design.total_rows} in {out}), {len(infos)} workers with '
                           f'{threads} threads, batches of {size}; cluster ready in '
                           f'{startup_s:.1f} s'
                           + ('' if pinned else '; warning: OMP_NUM_THREADS is not 1 on every '
                              'worker') + '\n')
        bar = Progress(design.total_rows, in_table, progress)
        planned = failed = 0
        cpu = 0.0
        compute_began = time.perf_counter()
        coordinator_began = time.process_time()
        futures = {}
        for batch in batches_of(todo, size):
            future = client.submit(plan_batch, design, batch, pure=False)
            futures[future] = batch
        import distributed
        try:
            for future in distributed.as_completed(list(futures)):
                try:
                    rows = future.result()
                except Exception as exc:  # a worker died: the batch's rows carry the error
                    rows = [failed_row(design, i, f'task lost: {_one_line(exc)}')
                            for i in futures[future]]
                table.append(rows)
                future.release()
                bad = sum(row['status'] != 'ok' for row in rows)
                planned += len(rows)
                failed += bad
                cpu += sum(row['cpu_s'] or 0.0 for row in rows)
                bar.update(len(rows), bad)
        except KeyboardInterrupt:
            client.cancel(list(futures))
            raise
        finally:
            bar.show(final=True)
        wall_s = time.perf_counter() - compute_began
        coordinator_cpu_s = time.process_time() - coordinator_began
    return StudyRun(planned, failed, in_table + planned, design.total_rows, len(infos), size,
                    startup_s, wall_s, cpu, coordinator_cpu_s)


# ---------------------------------------------------------------------------------------------
# Summary and scaling measurement.

def summary(design: StudyDesign, rows: Sequence[dict]) -> str:
    """Mean min throughput of each method over the rows where every method succeeded, and the
    mean gain of the Algorithm 1 methods over each baseline."""
    ok = [row for row in rows if row['status'] == 'ok']
    lines = [f'{len(rows)} rows, {len(ok)} ok, {len(rows) - len(ok)} failed or invalid']
    if not ok:
        return '\n'.join(lines)
    lines.append(f'{"method":<44}{"mean min throughput (bit/s)":>28}{"mean time (s)":>15}')
    for method in design.methods:
        values = [row[f'{method}_bps'] for row in ok]
        times = [row[f'{method}_s'] for row in ok]
        lines.append(f'{METHODS[method].label:<44}{statistics.fmean(values):>28.6g}'
                     f'{statistics.fmean(times):>15.4f}')
    for method in design.methods:
        if method in BASELINES or method == 'bound':
            continue
        for baseline in (b for b in BASELINES if b in design.methods):
            gains = [row[f'{method}_bps'] / row[f'{baseline}_bps'] - 1.0 for row in ok
                     if row[f'{baseline}_bps'] > 0]
            if gains:
                lines.append(f'{method} over {baseline}: mean gain '
                             f'{100 * statistics.fmean(gains):.1f} %')
    return '\n'.join(lines)


def format_run(run: StudyRun) -> str:
    if run.planned == 0:
        return f'nothing to plan: {run.in_table} of {run.total} rows are in the table'
    return (f'planned {run.planned} scenarios ({run.failed} failed) in {run.wall_s:.1f} s on '
            f'{run.workers} workers: {run.rate:.2f} scenarios/s, batches of {run.batch_size}, '
            f'workers on a core {100 * run.cpu_share:.0f} % of the time; cluster start '
            f'{run.startup_s:.1f} s; '
            f'{run.in_table} of {run.total} rows in the table')


def measure_scaling(design: StudyDesign, worker_counts: Sequence[int], repeats: int, *,
                    batch_size: int | None = None, out: TextIO = sys.stdout) -> dict[int, list]:
    """Run the whole study afresh ``repeats`` times with each worker count, alternating (and
    reversing the order every other round, so that a change of load on the machine falls on
    both sides); print each run and the median rates. Returns {workers: [StudyRun, ...]}."""
    runs: dict[int, list[StudyRun]] = {k: [] for k in worker_counts}
    with tempfile.TemporaryDirectory(prefix='study-scaling-') as folder:
        for repeat in range(repeats):
            order = list(worker_counts) if repeat % 2 == 0 else list(worker_counts)[::-1]
            for count in order:
                target = Path(folder) / f'run-{repeat}-{count}.parquet'
                run = run_study(design, target, workers=count, batch_size=batch_size)
                runs[count].append(run)
                print(f'round {repeat + 1}, {count} worker(s): {run.rate:.2f} scenarios/s '
                      f'({run.planned} in {run.wall_s:.2f} s, workers on a core '
                      f'{100 * run.cpu_share:.0f} % of the time, this process '
                      f'{100 * run.coordinator_cpu_s / run.wall_s:.0f} % of a core, cluster '
                      f'start {run.startup_s:.1f} s)', file=out, flush=True)
    medians = {k: statistics.median(r.rate for r in v) for k, v in runs.items()}
    for count, rate in medians.items():
        print(f'{count} worker(s): median {rate:.2f} scenarios/s', file=out)
    base = min(medians)
    for count in medians:
        if count != base:
            ratios = [a.rate / b.rate for a, b in zip(runs[count], runs[base])]
            print(f'scaling {base} -> {count} workers: {medians[count] / medians[base]:.2f}x '
                  f'(median rates; per round {", ".join(f"{r:.2f}" for r in ratios)})',
                  file=out, flush=True)
            per_cpu = {k: statistics.median(r.planned / r.cpu_s for r in runs[k])
                       for k in (base, count)}
            share = per_cpu[count] / per_cpu[base]
            print(f'per second of worker processor time: {per_cpu[base]:.2f} scenarios with '
                  f'{base}, {per_cpu[count]:.2f} with {count} ({share:.2f} of it: what '
                  f'distributing costs when each worker has a core of its own)',
                  file=out, flush=True)
    return runs


# ---------------------------------------------------------------------------------------------
# Command line.

DESCRIPTION = ('Monte Carlo study: random scenarios planned by every method on Dask, '
               'streamed to a Parquet or CSV table; resumable; CDF and gain figures')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``uav-comm-planner montecarlo``."""
    design = parser.add_argument_group(
        'study design', 'settings take a value (5), a grid (1,2,5: every value, crossed with '
        'the other grids) or a range drawn per scenario (4:12, or 0.5:20:log); write negative '
        'values as --noise-dbm=-170:-160')
    design.add_argument('--cases', type=int, default=None,
                        help='random drops per grid point (default 100)')
    design.add_argument('--seed', type=int, default=None, help='study seed (default 0)')
    for name, setting in SETTINGS.items():
        default = 'M seconds' if setting.default is None else setting.default
        design.add_argument(setting.flag, dest=f'draw_{name}', metavar='VALUE|A,B|LOW:HIGH',
                            default=None, help=f'{setting.help} (default {default})'
                            if setting.default is not None else setting.help)
    design.add_argument('--area', choices=AREAS, default=None,
                        help='nodes uniform in the square or in the disc inscribed in it '
                             '(default square)')
    design.add_argument('--endpoints', choices=tuple(ENDPOINTS), default=None,
                        help='start and goal: diagonal (0,0)->(side,side), across '
                             '(0,side/2)->(side,side/2), centre (a loop from the centre), '
                             'random (both uniform in the area); default diagonal')
    design.add_argument('--methods', default=None, metavar='NAME,NAME',
                        help=f'methods to run, of {",".join(METHODS)} (default all)')
    run = parser.add_argument_group('running')
    run.add_argument('--out', type=Path, default=None, metavar='TABLE.parquet|TABLE.csv',
                     help='the table: a .parquet folder of parts or a .csv file; an existing '
                          'table of the same study is resumed (default study.parquet)')
    run.add_argument('--workers', type=int, default=None,
                     help='worker processes of the embedded cluster (default: one per core)')
    run.add_argument('--scheduler', default=None, metavar='tcp://HOST:8786',
                     help='run on this existing Dask cluster instead')
    run.add_argument('--batch', type=int, default=None,
                     help=f'scenarios per task (default: about 8 tasks per worker, at most '
                          f'{MAX_BATCH})')
    run.add_argument('--limit', type=int, default=None,
                     help='plan at most this many rows now; the next run goes on')
    run.add_argument('--quiet', action='store_true', help='no progress line')
    figures = parser.add_argument_group('figures (PDF or PNG by suffix)')
    figures.add_argument('--figure', type=Path, default=None, metavar='CDF.pdf|CDF.png',
                         help='the CDF of the min throughput of every method')
    figures.add_argument('--figures-dir', type=Path, default=None, metavar='DIR',
                         help='write cdf, gain and time figures into DIR')
    figures.add_argument('--figure-format', choices=('pdf', 'png'), default='pdf',
                         help='format of the figures in --figures-dir (default pdf)')
    figures.add_argument('--gain-against', choices=tuple(SETTINGS), default=None,
                         help='setting on the gain figure\'s x axis (default: the first '
                              'swept setting, N when nothing is swept)')
    scaling = parser.add_argument_group('measuring')
    scaling.add_argument('--scaling', action='store_true',
                         help='instead of a table: time the study (in a temporary folder) '
                              'with 1 worker and with --workers (default all cores), '
                              'alternating, and print scenarios/s and the speed-up')
    scaling.add_argument('--repeats', type=int, default=3,
                         help='rounds of --scaling (default 3)')
    scaling.add_argument('--quick', action='store_true',
                         help='a small design (40 drops, N 2:4, M 20) unless set otherwise')


QUICK = {'cases': 40, 'draw_nodes': '2:4', 'draw_slots': '20', 'draw_side_m': '800'}


def design_from_args(args: argparse.Namespace, saved: StudyDesign | None) -> StudyDesign:
    """The design the options describe. With none of the design options, an existing
    table's own design (``--cases`` may still change it)."""
    options = {name: getattr(args, f'draw_{name}') for name in SETTINGS}
    others = {name: getattr(args, name) for name in ('seed', 'area', 'endpoints', 'methods')}
    if saved is not None and all(v is None for v in (*options.values(), *others.values())):
        if args.cases is None:
            return saved
        return StudyDesign(cases=args.cases, seed=saved.seed, draws=saved.draws,
                           area=saved.area, endpoints=saved.endpoints, methods=saved.methods)
    if args.quick:
        for key, value in QUICK.items():
            if key.startswith('draw_') and options[key[5:]] is None:
                options[key[5:]] = value
    draws = {name: value for name, value in options.items() if value is not None}
    if options['horizon_s'] is None:
        draws['horizon_s'] = None
    cases = args.cases if args.cases is not None else QUICK['cases'] if args.quick else 100
    methods = tuple(m.strip() for m in others['methods'].split(',')) \
        if others['methods'] else tuple(METHODS)
    return StudyDesign(cases=cases, seed=0 if others['seed'] is None else others['seed'],
                       draws=draws, area=others['area'] or 'square',
                       endpoints=others['endpoints'] or 'diagonal', methods=methods)


def draw_figures(args: argparse.Namespace, out: Path) -> list[Path]:
    """The figures the options ask for, from the table at ``out``."""
    if args.figure is None and args.figures_dir is None:
        return []
    from uav_comm_planner.tools.study import plots
    design, rows = read_table(out)
    written = []
    if args.figure is not None:
        written.append(plots.cdf_figure(design, rows, args.figure))
    if args.figures_dir is not None:
        written += plots.all_figures(design, rows, args.figures_dir,
                                     fmt=args.figure_format, against=args.gain_against)
    return written


def command(args: argparse.Namespace) -> int:
    """``uav-comm-planner montecarlo``: exit 0 done, 2 bad input, 130 interrupted."""
    out = args.out or Path('study.parquet')
    require_extra(parquet=args.scaling or out.suffix.lower() == '.parquet')
    for path in (args.figure,):
        if path is not None and path.suffix.lower() not in ('.pdf', '.png'):
            raise StudyError(f'--figure {str(path)!r}: name a .pdf or .png file')
    for folder in (args.figure.parent if args.figure else None, args.figures_dir):
        if folder is not None and not folder.is_dir():
            raise StudyError(f'folder {str(folder)!r} does not exist')
    if args.figure is not None or args.figures_dir is not None:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise StudyError(f'figures need matplotlib: {INSTALL_HINT}') from None
    if args.scaling:
        if args.repeats < 1:
            raise StudyError(f'--repeats must be >= 1, got {args.repeats}')
        design = design_from_args(args, None)
        counts = sorted({1, args.workers or os.cpu_count() or 1})
        print(f'scaling of {design.total_rows} scenarios ({", ".join(design.swept) or "fixed"}'
              f' swept), {args.repeats} rounds, workers {counts}', flush=True)
        measure_scaling(design, counts, args.repeats, batch_size=args.batch)
        return 0
    design = design_from_args(args, saved_design(out))
    try:
        run = run_study(design, out, workers=args.workers, scheduler=args.scheduler,
                        batch_size=args.batch, limit=args.limit,
                        progress=None if args.quiet else sys.stderr)
    except KeyboardInterrupt:
        table, done = open_table(out, design)
        print(f'\ninterrupted: {len(done)} of {design.total_rows} rows are in {out}; run the '
              'same command to go on', file=sys.stderr)
        return 130
    print(format_run(run))
    design, rows = read_table(out)
    print(summary(design, rows))
    for path in draw_figures(args, out):
        print(f'wrote {path}')
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='python -m uav_comm_planner.tools.study',
                                     description=DESCRIPTION)
    add_arguments(parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return command(args)
    except PlannerError as exc:
        print(f'montecarlo: error: {exc}', file=sys.stderr)
        return 2
