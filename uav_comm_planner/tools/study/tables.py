"""The rows of a Monte Carlo study and the tables that keep them.

A row is one scenario and what every method of the design achieved on it (:func:`evaluate`).
Rows stream to a table as batches of scenarios complete: a Parquet folder (one part file per
batch, each written atomically) or a CSV file (rows appended and flushed). A table knows the
rows it holds, so running the same study again plans only the rows it lacks: an interrupted
study resumes where it stopped and never loses or repeats a finished row. See
``docs/studies.md``.
"""

from __future__ import annotations

import csv
import functools
import json
import math
import os
from pathlib import Path
import statistics
import time
from typing import Sequence, TYPE_CHECKING

from uav_comm_planner.core.fading import evaluate_fading
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.files import write_text_atomic, write_with
from uav_comm_planner.tools.plots import STATIC_CAVEAT
from uav_comm_planner.tools.study.design import (row_mismatch, row_scenario, row_settings,
                                                 SETTINGS, StudyDesign, StudyError)
from uav_comm_planner.tools.study.methods import BASELINES, BOUNDS, METHODS, Outcome

if TYPE_CHECKING:
    import pyarrow

#: A stored study design larger than this is refused before it is read.
MAX_DESCRIPTION_BYTES = 1024 * 1024


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
    cols += [(name, float) for name in fading_columns(design)]
    return cols + [('cpu_s', float), ('status', str), ('error', str)]


def fading_columns(design: StudyDesign) -> list[str]:
    """With a fading, for each planning method (not the bounds): ``m_ergodic_bps``, the mean
    over the draws of min_n R_n (the ergodic min throughput), and ``m_ergodic_std``, its
    standard deviation over the draws (:func:`~uav_comm_planner.core.fading.evaluate_fading`)."""
    if design.fading is None:
        return []
    return [f'{method}_ergodic_{part}' for method in design.methods if method not in BOUNDS
            for part in ('bps', 'std')]


def one_line(exc: BaseException) -> str:
    """An error as one short line for a table's ``error`` column: its type and message."""
    text = ' '.join(str(exc).split()) or repr(exc)
    return f'{type(exc).__name__}: {text}'[:400]


def _empty_methods(design: StudyDesign, row: dict, status: str) -> None:
    for method in design.methods:
        row.update({f'{method}_bps': None, f'{method}_iterations': None,
                    f'{method}_sca_steps': None, f'{method}_s': None,
                    f'{method}_status': status})
    row.update({name: None for name in fading_columns(design)})


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
        scenario = row_scenario(design, row, nodes_rng)
    except Exception as exc:  # every failure is a row, never a lost study
        _empty_methods(design, row, 'skipped')
        row.update(cpu_s=time.process_time() - cpu_began, status='invalid',
                   error=one_line(exc))
        return row
    faded: dict = {}
    for method in design.methods:
        began = time.perf_counter()
        try:
            outcome = METHODS[method].run(scenario)
        except Exception as exc:  # every failure is a row, never a lost study
            outcome = Outcome(math.nan, status='error')
            errors.append(f'{method}: {one_line(exc)}')
        row.update({
            f'{method}_bps': None if math.isnan(outcome.min_throughput_bps)
            else float(outcome.min_throughput_bps),
            f'{method}_iterations': outcome.iterations, f'{method}_sca_steps': outcome.sca_steps,
            f'{method}_s': time.perf_counter() - began, f'{method}_status': outcome.status})
        if design.fading is not None and method not in BOUNDS:
            faded.update(_faded(design, index, method, scenario, outcome))
    row.update(faded)                   # after every method's columns, as columns() has them
    row.update(cpu_s=time.process_time() - cpu_began, status='failed' if errors else 'ok',
               error='; '.join(errors))
    return row


def _faded(design: StudyDesign, index: int, method: str, scenario: Scenario,
           outcome: Outcome) -> dict:
    """A planning method's fading columns: its plan judged under row ``index``'s fading
    (None when the method made no plan)."""
    if outcome.plan is None:
        return {f'{method}_ergodic_bps': None, f'{method}_ergodic_std': None}
    q, p = outcome.plan
    evaluation = evaluate_fading(q, p, scenario, design.fading_for(index))
    return {f'{method}_ergodic_bps': evaluation.mean, f'{method}_ergodic_std': evaluation.std}


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
        rows = self.rows()
        seen = [row['index'] for row in rows]
        if len(set(seen)) != len(seen):
            raise StudyError(f'{self.path} holds some rows twice; it was not written by this '
                             'package alone')
        for row in rows:
            wrong = row_mismatch(self.design, row)
            if wrong:
                raise StudyError(f'{self.path}: {wrong}; the table was changed by hand: '
                                 'restore it or choose another --out')
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
    def schema(self) -> pyarrow.Schema:
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
        try:
            with open(self.path, newline='', encoding='utf-8') as table:
                reader = csv.DictReader(table)
                if reader.fieldnames != list(kinds):
                    raise StudyError(f'{self.path} has other columns than this study')
                return [{name: _from_text(text, kinds[name], self.path, line)
                         for name, text in row.items()}
                        for line, row in enumerate(reader, start=2)]
        except (UnicodeDecodeError, csv.Error) as exc:
            raise StudyError(f'{self.path} is not a CSV table of this package ({exc}); the '
                             'table was changed by hand: restore it or choose another --out'
                             ) from None


def _from_text(text: str | None, kind: type, path: Path, line: int) -> str | int | float | None:
    """A CSV field as its column's kind; a field that is not one (a table edited by hand) is a
    StudyError naming the file, the line and the value."""
    if kind is str and isinstance(text, str):
        return text
    if text == '':
        return None
    try:
        return kind(text)
    except (TypeError, ValueError, OverflowError):
        shown = repr(text) if text is None or len(text) <= 40 else repr(text[:40] + '...')
        what = {int: 'an integer', float: 'a number'}.get(kind, kind.__name__)
        raise StudyError(f'{path}:{line}: {shown} is not {what}; the table was changed by '
                         f'hand: restore it or choose another --out') from None


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
    from uav_comm_planner.files import read_text_file
    probe = table_for(path, StudyDesign(cases=1))
    if not probe.exists():
        return None
    try:
        text = read_text_file(probe.description, max_bytes=MAX_DESCRIPTION_BYTES,
                              what='study description', error=StudyError)
        return StudyDesign.from_dict(json.loads(text))
    except (OSError, ValueError, KeyError, TypeError, RecursionError) as exc:
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
# Summary.

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
                     f'{statistics.fmean(times):>15.4f}' + _caveat(method, '  '))
    lines += _fading_summary(design, ok)
    for method in design.methods:
        if method in BASELINES or method in BOUNDS:
            continue
        for bound in (b for b in BOUNDS if b in design.methods):
            gaps = [1.0 - row[f'{method}_bps'] / row[f'{bound}_bps'] for row in ok
                    if row[f'{bound}_bps'] > 0]
            if gaps:
                lines.append(f'{method} below the {bound}: median gap '
                             f'{100 * statistics.median(gaps):.2f} %, max '
                             f'{100 * max(gaps):.2f} %')
        for baseline in (b for b in BASELINES if b in design.methods):
            gains = [row[f'{method}_bps'] / row[f'{baseline}_bps'] - 1.0 for row in ok
                     if row[f'{baseline}_bps'] > 0]
            if gains:
                lines.append(f'{method} over {baseline}: mean gain '
                             f'{100 * statistics.fmean(gains):.1f} %' + _caveat(baseline, ' '))
    return '\n'.join(lines)


def _fading_summary(design: StudyDesign, ok: Sequence[dict]) -> list[str]:
    """Under the design's fading: each planning method's mean ergodic min throughput, the
    mean of its spread over the draws, and its share of the planned throughput."""
    if design.fading is None:
        return []
    fading = design.fading
    lines = [f'under {fading.model} fading'
             + (f' (K = {fading.k_factor_db:g} dB)' if fading.model == 'rician' else '')
             + f', {fading.samples} draws a case:',
             f'{"method":<44}{"mean ergodic min (bit/s)":>28}{"mean std":>12}{"of planned":>12}']
    for method in design.methods:
        if method in BOUNDS:
            continue
        means = [row[f'{method}_ergodic_bps'] for row in ok]
        spreads = [row[f'{method}_ergodic_std'] for row in ok]
        shares = [row[f'{method}_ergodic_bps'] / row[f'{method}_bps'] for row in ok
                  if row[f'{method}_bps']]
        lines.append(f'{METHODS[method].label:<44}{statistics.fmean(means):>28.6g}'
                     f'{statistics.fmean(spreads):>12.4g}'
                     f'{100 * statistics.fmean(shares) if shares else math.nan:>11.2f}%')
    return lines


def _caveat(method: str, gap: str) -> str:
    """The static point's caveat, to stand beside its number; '' for any other method."""
    return f'{gap}(the static point {STATIC_CAVEAT})' if method == 'static' else ''
