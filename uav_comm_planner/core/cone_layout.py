"""The sparsity pattern of the SCA trajectory step's cone program, and its fixed right-hand side.

The program is :mod:`uav_comm_planner.core.fast_trajectory`'s: its columns (t, z, u, the partial
sums e, with a path budget the leg lengths s), its rows in cone order and where each entry of A
sits. The pattern depends on N, M, the block size and which optional rows are there, not on the
scenario, so it is built once per form and cached; what changes between steps (the node rows'
coefficients, the zone rows, b) is written into it by the stepper.
"""

from __future__ import annotations

from dataclasses import dataclass
import functools

import clarabel
import numpy as np
from scipy import sparse

from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.core.trajectory import KM


def block_slots(num_nodes: int) -> int:
    """K, the slots per partial sum of a node row: 4 N, at least 64.

    A node row summed over all M slots is dense; the sparse LDL factorisation orders dense rows
    last and then fills every cone row with N entries. Partial sums e_{n,k} over blocks of K
    slots keep every row short, so the fill stays on the variables; on N = 10..50 and
    M = 200..2000, K = 4 N was the fastest of K = 8..200, up to three times faster than no
    blocks, with fewer interior-point iterations. Small problems gain nothing from blocks
    and were seen to stop at AlmostSolved with them, so up to 64 slots have none.
    """
    return max(64, 4 * num_nodes)


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
class ConeLayout:
    """Sparsity pattern of A for N nodes, M slots and blocks of K slots.

    Columns: x = (t, z[1]_x, z[1]_y, ..., z[M]_x, z[M]_y, u[1], ..., u[M], e (N, B)), with
    B = ceil(M / K) blocks. Rows, in cone order: N node rows t + sum_k e_{n,k} <= C'_n and
    N B block rows (1/M) sum_{m in block k} W_{n,m} (u[m] - 2 w_n . z[m]) <= e_{n,k}
    (non-negative cone), 3 (M + 1) speed rows, with ``air_legs`` 3 (M + 1) airspeed rows (the
    same legs less the drift), 4 M epigraph rows, then ``zone_rows`` K rows per slot, in
    (m, k) order, of the zones' restriction (non-negative cone, 2 M K entries in (m, k,
    (z_x, z_y)) order at the end of the build order), then with ``path_budget`` M + 1 rows
    V delta - s[l] and the budget row L - sum_l s[l] (non-negative cone; columns s (M + 1,)
    after e, which are the first entries of the speed cones instead of V delta). ``values``
    holds A's entries in build order, where the 3 N M block coefficients, in (n, m, (z_x, z_y,
    u)) order, start at ``first_coefficient``; ``to_csc`` reorders such a list into CSC order.
    """

    num_nodes: int
    num_slots: int
    block_slots: int
    air_legs: bool
    indices: np.ndarray
    indptr: np.ndarray
    to_csc: np.ndarray
    values: np.ndarray
    zone_rows: int = 0
    path_budget: bool = False

    @property
    def num_blocks(self) -> int:
        return -(-self.num_slots // self.block_slots)

    @property
    def num_sums(self) -> int:
        """N B partial sums e_{n,k}, one column and one block row each; none for one block."""
        return _num_sums(self.num_nodes, self.num_slots, self.block_slots)

    @property
    def first_coefficient(self) -> int:
        return self.num_nodes + self.num_sums

    @property
    def num_leg_cones(self) -> int:
        """M + 1 speed cones, twice that with the airspeed's."""
        return (2 if self.air_legs else 1) * (self.num_slots + 1)

    @property
    def num_rows(self) -> int:
        return self.budget_row + 1 if self.path_budget else self.first_length_row

    @property
    def first_length_row(self) -> int:
        """The first row V delta - s[l] >= 0 (with ``path_budget``), after the zone rows."""
        return self.first_zone_row + self.zone_rows * self.num_slots

    @property
    def budget_row(self) -> int:
        """The row L - sum_l s[l] >= 0 (with ``path_budget``)."""
        return self.first_length_row + self.num_slots + 1

    @property
    def first_zone_row(self) -> int:
        return self.num_nodes + self.num_sums + 3 * self.num_leg_cones + 4 * self.num_slots

    @property
    def num_columns(self) -> int:
        return self.first_length_column + (self.num_slots + 1 if self.path_budget else 0)

    @property
    def first_length_column(self) -> int:
        """s[0], the first leg length (with ``path_budget``), after the partial sums."""
        return 1 + 3 * self.num_slots + self.num_sums

    @functools.cached_property
    def node_entries(self) -> tuple[np.ndarray, np.ndarray]:
        """The entries that change between steps (the block rows' z and u coefficients).

        Returns their positions in A's CSC data, ascending, and the indices of the same entries
        in the (N, M, 3) coefficient array, in the same order.
        """
        build_to_csc = np.empty_like(self.to_csc)
        build_to_csc[self.to_csc] = np.arange(len(self.to_csc))
        build = np.arange(self.first_coefficient,
                          self.first_coefficient + 3 * self.num_nodes * self.num_slots)
        order = np.argsort(build_to_csc[build])
        return build_to_csc[build][order], build[order] - self.first_coefficient

    @functools.cached_property
    def zone_entries(self) -> np.ndarray:
        """The zone rows' entries' positions in A's CSC data, in their build order."""
        build_to_csc = np.empty_like(self.to_csc)
        build_to_csc[self.to_csc] = np.arange(len(self.to_csc))
        count = 2 * self.zone_rows * self.num_slots
        return build_to_csc[len(self.to_csc) - count:]

    def matrix(self, values: np.ndarray) -> sparse.csc_matrix:
        """A (rows, columns) from entries in build order."""
        return sparse.csc_matrix((values[self.to_csc], self.indices, self.indptr),
                                 shape=(self.num_rows, self.num_columns))

    def clarabel_matrices(self, values: np.ndarray) -> tuple[CscLists, CscLists]:
        """P = 0 (columns x columns) and A from entries in build order, as Clarabel reads them."""
        a = CscLists(values[self.to_csc].tolist(), self.indices.tolist(), self.indptr.tolist(),
                     (self.num_rows, self.num_columns))
        p = CscLists([], [], [0] * (self.num_columns + 1), (self.num_columns, self.num_columns))
        return p, a

    @functools.cached_property
    def cones(self) -> tuple:
        """Node and block rows (non-negative), speed limits (M + 1 of dim 3, and as many for
        the airspeed), epigraphs (M of dim 4), the zone rows and the path budget's rows
        (non-negative, each where there are some)."""
        zones = ((clarabel.NonnegativeConeT(self.zone_rows * self.num_slots),)
                 if self.zone_rows else ())
        budget = ((clarabel.NonnegativeConeT(self.num_slots + 2),) if self.path_budget
                  else ())
        return ((clarabel.NonnegativeConeT(self.num_nodes + self.num_sums),)
                + (clarabel.SecondOrderConeT(3),) * self.num_leg_cones
                + (clarabel.SecondOrderConeT(4),) * self.num_slots + zones + budget)


def _speed_entries(first_row: int, num_slots: int) -> tuple[np.ndarray, ...]:
    """Leg l (l = 0..M) is s = (V delta, z[l + 1] - z[l]) with z[0] = q0, z[M + 1] = qF.

    Clarabel's form is s = b - A x, so z[l + 1] enters leg l with -1 and z[l] with +1.
    """
    z_col = np.arange(1, 1 + 2 * num_slots)              # slot m's z_x, z_y: 1 + 2m, 2 + 2m
    end_of_leg = first_row + 1 + 3 * ((z_col - 1) // 2) + (z_col - 1) % 2
    return (np.concatenate([end_of_leg, end_of_leg + 3]), np.concatenate([z_col, z_col]),
            np.repeat([-1.0, 1.0], 2 * num_slots))


def _epigraph_entries(first_row: int, num_slots: int) -> tuple[np.ndarray, ...]:
    """Slot m's cone is s = ((u + 1) / 2, z_x, z_y, (u - 1) / 2)."""
    slot = np.arange(num_slots)[:, None]
    u_col = 1 + 2 * num_slots + slot
    rows = first_row + 4 * slot + np.arange(4)
    cols = np.concatenate([u_col, 1 + 2 * slot, 2 + 2 * slot, u_col], axis=1)
    return rows.ravel(), cols.ravel(), np.tile([-0.5, -1.0, -1.0, -0.5], num_slots)


def _length_entries(first_speed_row: int, first_row: int, num_slots: int,
                    first_column: int) -> tuple[np.ndarray, ...]:
    """s[l] (column first_column + l) as the first entry of leg l's speed cone (s = b - A x
    with b 0 there), in row first_row + l, V delta - s[l], and in the budget row after them,
    L - sum_l s[l]."""
    legs = num_slots + 1
    s_col = first_column + np.arange(legs)
    return (np.concatenate([first_speed_row + 3 * np.arange(legs), first_row + np.arange(legs),
                            np.full(legs, first_row + legs)]),
            np.concatenate([s_col, s_col, s_col]),
            np.concatenate([-np.ones(legs), np.ones(legs), np.ones(legs)]))


def _zone_entries(first_row: int, num_slots: int, rows: int) -> tuple[np.ndarray, ...]:
    """Slot m's row k is s = b - A x with A's entries on z[m]_x and z[m]_y (set per step)."""
    row = first_row + np.arange(num_slots * rows)
    slot = np.repeat(np.arange(num_slots), rows)
    cols = np.stack([1 + 2 * slot, 2 + 2 * slot], axis=1)
    return np.repeat(row, 2), cols.ravel(), np.zeros(2 * num_slots * rows)


def _num_sums(num_nodes: int, num_slots: int, block: int) -> int:
    blocks = -(-num_slots // block)
    return 0 if blocks == 1 else num_nodes * blocks


def _sum_entries(num_nodes: int, num_slots: int,
                 block: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node rows (t and their e's), then block rows (z, u coefficients, then -e_{n,k}).

    With a single block the node rows take the coefficients themselves.
    """
    sums = _num_sums(num_nodes, num_slots, block)
    blocks = sums // num_nodes
    e_col = 1 + 3 * num_slots + np.arange(sums)
    node = np.arange(num_nodes)[:, None]
    slot = np.arange(num_slots)
    # (N, M): the row that takes slot m's coefficients of node n.
    block_row = (num_nodes + node * blocks + slot // block if sums
                 else np.broadcast_to(node, (num_nodes, num_slots)))
    # (N, M, 3): slot m's z_x, z_y and u columns in node n's block row.
    coefficient_cols = np.broadcast_to(np.stack([1 + 2 * slot, 2 + 2 * slot,
                                                 1 + 2 * num_slots + slot], axis=1),
                                       (num_nodes, num_slots, 3))
    first_rows = np.arange(num_nodes)
    rows = np.concatenate([first_rows, np.repeat(first_rows, blocks),
                           np.repeat(block_row.ravel(), 3), num_nodes + np.arange(sums)])
    cols = np.concatenate([np.zeros(num_nodes, dtype=int), e_col, coefficient_cols.ravel(),
                           e_col])
    vals = np.concatenate([np.ones(num_nodes + sums), np.zeros(3 * num_nodes * num_slots),
                           -np.ones(sums)])
    return rows, cols, vals


@functools.lru_cache(maxsize=8)
def cone_layout(num_nodes: int, num_slots: int, block: int | None = None, *,
                air_legs: bool = False, zone_rows: int = 0,
                path_budget: bool = False) -> ConeLayout:
    """The fixed sparsity pattern for N nodes, M slots and blocks of ``block`` slots
    (:func:`block_slots` by default; M or more for none), with the airspeed cones when
    ``air_legs``, ``zone_rows`` rows per slot for the zones and the leg lengths and their
    budget with ``path_budget``. Cached; arrays are read-only."""
    block = block_slots(num_nodes) if block is None else block
    sums = _num_sums(num_nodes, num_slots, block)
    first_speed_row = num_nodes + sums
    leg_sets = 2 if air_legs else 1
    parts = (_sum_entries(num_nodes, num_slots, block),
             *(_speed_entries(first_speed_row + 3 * (num_slots + 1) * k, num_slots)
               for k in range(leg_sets)),
             _epigraph_entries(first_speed_row + 3 * (num_slots + 1) * leg_sets, num_slots))
    first_zone_row = first_speed_row + 3 * (num_slots + 1) * leg_sets + 4 * num_slots
    first_length_column = 1 + 3 * num_slots + sums
    if path_budget:
        # Rows after the zone rows, entries before theirs: the zone entries stay last.
        parts += (_length_entries(first_speed_row, first_zone_row + zone_rows * num_slots,
                                  num_slots, first_length_column),)
    if zone_rows:
        parts += (_zone_entries(first_zone_row, num_slots, zone_rows),)
    rows, cols, values = (np.concatenate(arrays) for arrays in zip(*parts))
    # CSC order: by column, then by row; no entry repeats, so this is a permutation.
    to_csc = np.lexsort((rows, cols))
    counts = np.bincount(cols, minlength=first_length_column
                         + (num_slots + 1 if path_budget else 0))
    layout = ConeLayout(num_nodes=num_nodes, num_slots=num_slots, block_slots=block,
                        air_legs=air_legs, indices=rows[to_csc].astype(np.int32),
                        indptr=np.concatenate([[0], np.cumsum(counts)]).astype(np.int32),
                        to_csc=to_csc, values=values, zone_rows=zone_rows,
                        path_budget=path_budget)
    for array in (layout.indices, layout.indptr, layout.to_csc, layout.values):
        array.setflags(write=False)
    return layout


def fixed_right_hand_side(scenario: Scenario, layout: ConeLayout,
                          centre_m: np.ndarray) -> np.ndarray:
    """b of the step's cone program with zero node and zone rows: the speed (and airspeed)
    cones' limits and end points, the epigraph constants; centred kilometres about centre_m."""
    m = scenario.num_slots
    start = (np.asarray(scenario.start_m) - centre_m) / KM
    goal = (np.asarray(scenario.goal_m) - centre_m) / KM
    speed = np.zeros((m + 1, 3))
    speed[:, 0] = scenario.max_step_m / KM
    speed[0, 1:] = -start
    speed[m, 1:] = goal
    legs = [speed.ravel()]
    if layout.air_legs:
        # The same legs less the slot's drift, within V_air delta.
        air = speed.copy()
        air[:, 0] = scenario.max_air_step_m / KM
        air[:, 1:] -= scenario.drift_m / KM
        legs.append(air.ravel())
    epigraph = np.tile([0.5, 0.0, 0.0, -0.5], m)
    sum_rows = np.zeros(layout.num_nodes + layout.num_sums)
    zone_rows = np.zeros(layout.zone_rows * m)
    budget = []
    if layout.path_budget:
        # The speed cones bound each leg by s[l] (b 0 there); s[l] <= V delta; the budget
        # is set per step.
        budget = [np.full(m + 1, speed[0, 0]), np.zeros(1)]
        speed[:, 0] = 0.0
        legs[0] = speed.ravel()
    return np.concatenate([sum_rows, *legs, epigraph, zone_rows, *budget])
