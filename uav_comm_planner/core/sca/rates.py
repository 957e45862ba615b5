"""The node-rate block: t below every node's SCA bound (letter, problem (11)).

mean_m lbr_{n,m}(z) = C_n - (1/M) sum_m W_{n,m} ||z[m] - w_n||^2
(:func:`~uav_comm_planner.core.sca.surrogate.kilometre_rows`), so the block is
C_n - (1/M) sum_m W_{n,m} ||z[m] - w_n||^2 >= t for every node n.

In the cone program, with an epigraph variable u[m] >= ||z[m]||^2 (the rotated cone
||(z[m], (u[m] - 1) / 2)|| <= (u[m] + 1) / 2 of dimension 4) and
||z[m] - w_n||^2 = ||z[m]||^2 - 2 w_n . z[m] + ||w_n||^2, every node's row is linear:

    t + (1/M) sum_m W_{n,m} (u[m] - 2 w_n . z[m]) <= C_n - ||w_n||^2 (1/M) sum_m W_{n,m}.

Replacing ||z[m]||^2 by u[m] is exact: u appears only with non-negative weights on the small
side of each row, so some optimum has u[m] = ||z[m]||^2. The sum over m is split into partial
sums e_{n,k} over blocks of K slots (:func:`block_slots`), which keeps every row short.
Columns: u (M,), then e (N B,). Rows: N node rows and N B block rows (non-negative cone), then
M epigraph cones. The 3 N M coefficients (n, m, (z_x, z_y, u)) and the node rows' b change at
every step.

Dual certificate: lambda_n (the node rows' multipliers, normalised) weigh the f_n; L's part
is sum_n lambda_n f_n(z), strongly concave in z[m] with modulus (2/M) sum_n lambda_n W_{n,m}.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import clarabel
import cvxpy as cp
import numpy as np

from uav_comm_planner.core.sca.block import (Block, Columns, DualBound, Entries, Expansion,
                                             Frame, Variables)
from uav_comm_planner.core.sca.surrogate import (kilometre_rows, surrogate_coefficients,
                                                 with_offsets)


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
class NodeRows:
    """mean_m lbr_{n,m}(z) = constant_n - (1/M) sum_m weight_{n,m} ||z[m] - w_n||^2.

    weight: W (N, M), per km^2; constant: C (N,) bits per use (offsets included).
    """

    weight: np.ndarray
    constant: np.ndarray

    def values(self, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        """f_n(z) (N,) at z (M, 2) km, nodes w (N, 2) km in the same frame."""
        spread = ((z[None, :, :] - w[:, None, :]) ** 2).sum(axis=-1)
        return self.constant - (self.weight * spread).mean(axis=1)

    def bound(self, z: np.ndarray, w: np.ndarray) -> float:
        """min_n mean_m lbr_{n,m} at z (M, 2) km, nodes w (N, 2) km in the same frame."""
        return float(self.values(z, w).min())


class NodeRates(Block):
    """t <= every node's SCA bound (module docstring); with ``partial_sums`` False, every
    node row takes its M coefficients itself."""

    def __init__(self, frame: Frame, *, partial_sums: bool = True):
        super().__init__(frame)
        scenario = frame.scenario
        self.num_nodes, self.num_slots = scenario.num_nodes, scenario.num_slots
        self.block_slots = block_slots(self.num_nodes) if partial_sums else self.num_slots
        blocks = -(-self.num_slots // self.block_slots)
        self.num_blocks = blocks
        self.num_sums = 0 if blocks == 1 else self.num_nodes * blocks
        self.num_columns = self.num_slots + self.num_sums
        self.w = frame.nodes
        self._w_squared = (self.w ** 2).sum(axis=1)
        m = self.num_slots
        # Slot m's (z_x, z_y, u) coefficients in node n's row are W_{n,m} times these.
        self._factors = np.concatenate(
            [-2.0 / m * self.w, np.full((self.num_nodes, 1), 1.0 / m)], axis=1)[:, None, :]
        first = self.num_nodes + self.num_sums
        self.changing_entries = np.arange(first, first + 3 * self.num_nodes * m)
        self.changing_rows = np.arange(self.num_nodes)

    @property
    def form(self) -> tuple:
        return ('node rates', self.num_nodes, self.num_slots, self.block_slots)

    def cones(self) -> tuple:
        return ((clarabel.NonnegativeConeT(self.num_nodes + self.num_sums),)
                + (clarabel.SecondOrderConeT(4),) * self.num_slots)

    def pattern(self, columns: Columns) -> Entries:
        """Node rows (t and their e's), block rows (the coefficients, then -e_{n,k}), then the
        epigraph cones ((u + 1) / 2, z_x, z_y, (u - 1) / 2). With a single block the node rows
        take the coefficients themselves."""
        n, m, sums = self.num_nodes, self.num_slots, self.num_sums
        u_col = columns.first + np.arange(m)
        e_col = columns.first + m + np.arange(sums)
        node = np.arange(n)[:, None]
        slot = np.arange(m)
        # (N, M): the row that takes slot m's coefficients of node n.
        block_row = (n + node * self.num_blocks + slot // self.block_slots if sums
                     else np.broadcast_to(node, (n, m)))
        # (N, M, 3): slot m's z_x, z_y and u columns.
        coefficient_cols = np.broadcast_to(
            np.concatenate([columns.z, u_col[:, None]], axis=1), (n, m, 3))
        first_rows = np.arange(n)
        sums_part = Entries(
            rows=np.concatenate([first_rows, np.repeat(first_rows, self.num_blocks if sums
                                                       else 0),
                                 np.repeat(block_row.ravel(), 3), n + np.arange(sums)]),
            cols=np.concatenate([np.zeros(n, dtype=int), e_col, coefficient_cols.ravel(),
                                 e_col]),
            values=np.concatenate([np.ones(n + sums), np.zeros(3 * n * m), -np.ones(sums)]))
        first_cone = n + sums
        epigraph = Entries(
            rows=(first_cone + 4 * slot[:, None] + np.arange(4)).ravel(),
            cols=np.concatenate([u_col[:, None], columns.z, u_col[:, None]], axis=1).ravel(),
            values=np.tile([-0.5, -1.0, -1.0, -0.5], m))
        return Entries.join(sums_part, epigraph)

    def right_hand_side(self) -> np.ndarray:
        return np.concatenate([np.zeros(self.num_nodes + self.num_sums),
                               np.tile([0.5, 0.0, 0.0, -0.5], self.num_slots)])

    def at(self, expansion: Expansion) -> NodeRows:
        """The bound's weights and constants at q^k with power p, offsets added."""
        weight, constant = kilometre_rows(surrogate_coefficients(
            expansion.q_k, expansion.p, self.frame.scenario))
        return NodeRows(weight=weight, constant=with_offsets(constant, expansion.offsets))

    def coefficients(self, rows: NodeRows) -> np.ndarray:
        """(N, M, 3): slot m's (z_x, z_y, u) coefficients in node n's bound,
        (1/M) W_{n,m} (-2 w_n, 1)."""
        return rows.weight[:, :, None] * self._factors

    def update(self, rows: NodeRows) -> tuple[np.ndarray, np.ndarray]:
        """The coefficients, and b of the node rows: C_n - ||w_n||^2 (1/M) sum_m W_{n,m}."""
        b = rows.constant - self._w_squared * (rows.weight.sum(axis=1) / self.num_slots)
        return self.coefficients(rows).ravel(), b

    def constraints(self, v: Variables, rows: NodeRows) -> list[cp.Constraint]:
        m = self.num_slots
        return [rows.constant[n] - rows.weight[n] @ cp.sum(cp.square(v.z - self.w[n][None, :]),
                                                           axis=1) / m >= v.t
                for n in range(self.num_nodes)]

    def certificate(self, z: np.ndarray, rows: NodeRows, duals: Sequence,
                    bound: DualBound | None = None) -> DualBound | None:
        """The bound's start: lambda from the node rows' multipliers."""
        lam = np.maximum(np.array([float(d) for d in duals]), 0.0)
        if not np.all(np.isfinite(z)) or not lam.sum() > 0.0:
            return None
        lam = lam / lam.sum()
        f = rows.values(z, self.w)
        m = self.num_slots
        gradient = -(2.0 / m) * np.einsum('n,nm,nmk->mk', lam, rows.weight,
                                          z[None] - self.w[:, None])
        return DualBound(value=float(f.min()), lagrangian=float(lam @ f), gradient=gradient,
                         modulus=(2.0 / m) * (lam @ rows.weight))


__all__ = ['block_slots', 'NodeRates', 'NodeRows']
