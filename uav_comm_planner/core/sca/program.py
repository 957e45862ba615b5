"""The blocks of one SCA step, and their cone program for Clarabel.

:func:`step_blocks` lists the blocks of a scenario's step; both the reference step and the
fast step are built from that list. :class:`ConeProgram` places the blocks' rows one after
another and their own columns after t and z, and keeps A's pattern in Clarabel's compressed
columns with the positions of the entries that change between steps; it depends on the
blocks' forms only (never on the scenario's numbers), so :func:`cone_program` builds it once
per form and caches it.
"""

from __future__ import annotations

from dataclasses import dataclass
import threading
from typing import Callable, Sequence

import numpy as np
from scipy import sparse

from uav_comm_planner.core.energy import horizon_energy_j, JOULES_PER_WH
from uav_comm_planner.core.feasibility import project_onto_speed_limit
from uav_comm_planner.core.sca.block import Block, BlockFactory, Columns, Frame
from uav_comm_planner.core.sca.channel_rates import ChannelRates
from uav_comm_planner.core.sca.energy import EnergyBudget
from uav_comm_planner.core.sca.legs import LegLimits
from uav_comm_planner.core.sca.path_budget import PathBudget
from uav_comm_planner.core.sca.rates import NodeRates
from uav_comm_planner.core.sca.zones import ZoneHalfPlanes
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.core.zone_rows import zone_model
from uav_comm_planner.errors import InfeasibleHorizonError, InvalidScenarioError


def step_blocks(frame: Frame, *, keep_path_length: bool = False, partial_sums: bool = True,
                extra: Sequence[BlockFactory] = (), zone_pieces: int | None = None,
                zone_also: np.ndarray | None = None) -> list[Block]:
    """The blocks of the SCA step for ``frame``'s scenario: the node rates (always first: they
    define t; :class:`ChannelRates` for a channel with a line-of-sight probability), the legs,
    the zones where there are some, the energy budget where there is one, the ``extra``
    blocks, and with
    ``keep_path_length`` the path budget (last: its certificate picks its multiplier's
    direction against the others'). ``zone_pieces`` (None: all) bounds the zone pieces whose
    rows each slot gets, the nearest to q^k and to ``zone_also`` (:class:`ZoneHalfPlanes`)."""
    rates = ChannelRates if frame.scenario.channel_model.has_cusp else NodeRates
    blocks: list[Block] = [rates(frame, partial_sums=partial_sums),
                           LegLimits(frame, lengths=keep_path_length)]
    model = zone_model(frame.scenario.zones)
    if model is not None and model.rows_per_slot:
        blocks.append(ZoneHalfPlanes(frame, zone_pieces, zone_also))
    if frame.scenario.energy_budget_wh is not None:
        blocks.append(EnergyBudget(frame))
    blocks.extend(make(frame) for make in extra)
    if keep_path_length:
        blocks.append(PathBudget(frame))
    return blocks


def start_filter(scenario: Scenario,
                 extra: Sequence[BlockFactory] = ()) -> Callable[[np.ndarray], bool]:
    """Whether a start q (M, 2) metres, projected onto the speed limit, is admitted by every
    block of the step (:meth:`Block.admits`: the energy budget, the extra blocks); always,
    without such blocks."""
    if not extra and scenario.energy_budget_wh is None:
        return lambda q: True
    built = step_blocks(Frame.of(scenario), extra=extra)

    def admitted(q: np.ndarray) -> bool:
        q = project_onto_speed_limit(np.asarray(q, dtype=float), scenario)
        return all(block.admits(q) for block in built)
    return admitted


def no_start_error(scenario: Scenario, straight: np.ndarray) -> InvalidScenarioError:
    """The refusal when no start keeps the step's blocks (``straight``: the straight line
    q0 -> qF at uniform speed, (M, 2) metres, whose energy it states)."""
    if scenario.energy_budget_wh is not None:
        line = horizon_energy_j(straight, scenario, scenario.airframe)
        return InfeasibleHorizonError(
            f'no start keeps the energy budget of {scenario.energy_budget_wh:.4g} Wh (the '
            f'straight line q0 -> qF at uniform speed needs {line / JOULES_PER_WH:.4g} Wh); '
            f'raise energy_budget_wh, or give a start that keeps it (extra_starts)')
    return InvalidScenarioError('no start keeps the extra blocks: give a start that does '
                                '(extra_starts) or loosen them')


@dataclass(frozen=True)
class CscLists:
    """A sparse matrix in compressed columns, in the attributes Clarabel reads from a
    ``scipy.sparse.csc_matrix`` (``data``, ``indices``, ``indptr``, ``shape``,
    ``has_canonical_format``), held as lists: Clarabel converts its input element by element,
    and reads a list several times faster than an array (about 0.1 ms a solver at N = 3,
    M = 50, a tenth of a letter-sized SCA step)."""

    data: list[float]
    indices: list[int]
    indptr: list[int]
    shape: tuple[int, int]
    has_canonical_format: bool = True     # sorted row indices, no duplicates


@dataclass(frozen=True)
class ConeProgram:
    """A's pattern for a list of blocks (module docstring).

    x = (t, z[1]_x, z[1]_y, ..., z[M]_x, z[M]_y, each block's own columns); the rows are the
    blocks' in their order, and so are the cones. ``values`` holds A's entries in build order
    (the blocks' patterns one after another) and ``to_csc`` reorders it into CSC order;
    ``changing`` holds the CSC positions of the blocks' changing entries (``changing_build``
    their indices in build order), and
    ``changing_rows`` the rows of their changing b, both in block order.
    """

    num_slots: int
    forms: tuple
    first_rows: tuple[int, ...]
    first_columns: tuple[int, ...]
    num_rows: int
    num_columns: int
    cones: tuple
    indices: np.ndarray
    indptr: np.ndarray
    to_csc: np.ndarray
    values: np.ndarray
    changing: np.ndarray
    changing_build: np.ndarray
    changing_rows: np.ndarray

    def matrix(self, values: np.ndarray) -> sparse.csc_matrix:
        """A (rows, columns) from entries in build order."""
        return sparse.csc_matrix((values[self.to_csc], self.indices, self.indptr),
                                 shape=(self.num_rows, self.num_columns))

    def clarabel_matrices(self, values: np.ndarray) -> tuple[CscLists, CscLists]:
        """P = 0 (columns x columns) and A from entries in build order, as Clarabel reads
        them."""
        a = CscLists(values[self.to_csc].tolist(), self.indices.tolist(), self.indptr.tolist(),
                     (self.num_rows, self.num_columns))
        p = CscLists([], [], [0] * (self.num_columns + 1), (self.num_columns, self.num_columns))
        return p, a


_PROGRAMS: dict[tuple, ConeProgram] = {}
_PROGRAMS_LOCK = threading.Lock()
#: Forms whose programs are kept (least recently built dropped first).
PROGRAMS_KEPT = 8


def cone_program(blocks: Sequence[Block]) -> ConeProgram:
    """The cone program of these blocks, built once per (M, the blocks' forms); its arrays are
    read-only."""
    num_slots = blocks[0].frame.scenario.num_slots
    key = (num_slots, tuple(block.form for block in blocks))
    with _PROGRAMS_LOCK:
        program = _PROGRAMS.get(key)
    if program is None:
        program = _build(num_slots, key[1], blocks)
        with _PROGRAMS_LOCK:
            _PROGRAMS[key] = program
            while len(_PROGRAMS) > PROGRAMS_KEPT:
                del _PROGRAMS[next(iter(_PROGRAMS))]
    return program


def clear_programs() -> None:
    """Forget every cached program (the benchmark's cold runs)."""
    with _PROGRAMS_LOCK:
        _PROGRAMS.clear()


def _build(num_slots: int, forms: tuple, blocks: Sequence[Block]) -> ConeProgram:
    rows, cols, values, changing = [], [], [], []
    first_rows, first_columns = [], []
    row, column, entries = 0, 1 + 2 * num_slots, 0
    changing_rows, cones = [], []
    shared: dict[str, int] = {}
    for block in blocks:
        pattern = block.pattern(Columns(num_slots, column, dict(shared)))
        shared.update({name: column + offset for name, offset in block.shares.items()})
        first_rows.append(row)
        first_columns.append(column)
        rows.append(pattern.rows + row)
        cols.append(pattern.cols)
        values.append(pattern.values.astype(float))
        changing.append(entries + np.asarray(block.changing_entries, dtype=int))
        changing_rows.append(row + np.asarray(block.changing_rows, dtype=int))
        cones.extend(block.cones())
        row += block.num_rows
        column += block.num_columns
        entries += len(pattern.rows)
    rows, cols, values = (np.concatenate(arrays) for arrays in (rows, cols, values))
    # CSC order: by column, then by row; no entry repeats, so this is a permutation.
    to_csc = np.lexsort((rows, cols))
    build_to_csc = np.empty_like(to_csc)
    build_to_csc[to_csc] = np.arange(len(to_csc))
    counts = np.bincount(cols, minlength=column)
    program = ConeProgram(
        num_slots=num_slots, forms=forms, first_rows=tuple(first_rows),
        first_columns=tuple(first_columns), num_rows=row, num_columns=column,
        cones=tuple(cones), indices=rows[to_csc].astype(np.int32),
        indptr=np.concatenate([[0], np.cumsum(counts)]).astype(np.int32), to_csc=to_csc,
        values=values, changing=build_to_csc[np.concatenate(changing)],
        changing_build=np.concatenate(changing),
        changing_rows=np.concatenate(changing_rows))
    for array in (program.indices, program.indptr, program.to_csc, program.values,
                  program.changing, program.changing_build, program.changing_rows):
        array.setflags(write=False)
    return program


__all__ = ['clear_programs', 'cone_program', 'ConeProgram', 'CscLists', 'no_start_error',
           'PROGRAMS_KEPT', 'start_filter', 'step_blocks']
