"""The node-rate block for a channel with a line-of-sight probability: t below every node's
bound (:mod:`~uav_comm_planner.core.sca.channel_bound`),

    C_n - (1/M) sum_m (W_{n,m} ||z[m] - w_n||^2 + A_{n,m} ||z[m] - w_n||) >= t,

in kilometres about the frame's centre (W per km^2, A per km, both >= 0: concave in z).

It is :class:`~uav_comm_planner.core.sca.rates.NodeRates` (the squared distances through the
epigraph u[m] >= ||z[m]||^2, the partial sums) with one more column per node and slot,
rho_{n,m} >= ||z[m] - w_n|| (a second-order cone of dimension 3: (rho, z_x - w_x, z_y - w_y)),
which enters node n's row with the coefficient A_{n,m} / M. Replacing ||z[m] - w_n|| by rho is
exact for the same reason as u: it appears only with non-negative weights on the small side.
Columns: u (M,), e (N B,), then rho (N M,); the N M coefficients of rho change at every step.

Dual certificate: L's part is sum_n lambda_n f_n(z), still strongly concave with the modulus of
the squared terms; -A ||z - w|| adds the supergradient -A (z - w) / ||z - w||, and where z sits
on a node (the corner) the element of the ball of radius A that cancels most of the slot's
supergradient.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import clarabel
import cvxpy as cp
import numpy as np

from uav_comm_planner.core.sca.block import Columns, DualBound, Entries, Expansion, Frame
from uav_comm_planner.core.sca.channel_bound import channel_coefficients
from uav_comm_planner.core.sca.rates import NodeRates, NodeRows
from uav_comm_planner.core.sca.surrogate import KM, with_offsets

#: Below this distance (km) a slot is on the node's corner for the certificate: 1 mm.
CORNER_KM = 1e-6


@dataclass(frozen=True)
class ChannelRows(NodeRows):
    """:class:`NodeRows` plus linear: A (N, M) per km, the weight of ||z[m] - w_n||."""

    linear: np.ndarray = None

    def values(self, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        gaps = np.sqrt(((z[None, :, :] - w[:, None, :]) ** 2).sum(axis=-1))
        return self.constant - (self.weight * gaps * gaps + self.linear * gaps).mean(axis=1)


class ChannelRates(NodeRates):
    """t <= every node's line-of-sight bound (module docstring)."""

    def __init__(self, frame: Frame, *, partial_sums: bool = True):
        super().__init__(frame, partial_sums=partial_sums)
        n, m = self.num_nodes, self.num_slots
        self._rho_first = self.num_columns
        self.num_columns += n * m
        sums = self.num_sums
        # NodeRates' entries: t and the e's in the node rows, 3 per node and slot, -e in the
        # block rows, 4 per slot in the epigraph cones; rho's coefficients come next.
        self._parent_entries = n + (n * self.num_blocks if sums else 0) + 3 * n * m + sums \
            + 4 * m
        self._parent_rows = n + sums + 4 * m
        self.changing_entries = np.concatenate([
            self.changing_entries, self._parent_entries + np.arange(n * m)])

    @property
    def form(self) -> tuple:
        return ('channel rates',) + super().form[1:]

    def cones(self) -> tuple:
        return super().cones() + (clarabel.SecondOrderConeT(3),) * (self.num_nodes
                                                                    * self.num_slots)

    def pattern(self, columns: Columns) -> Entries:
        """:class:`NodeRates`' entries, then rho's in the rows that take the slot's
        coefficients, then the cones (rho, z_x - w_x, z_y - w_y)."""
        parent = super().pattern(columns)
        assert len(parent.rows) == self._parent_entries
        n, m, sums = self.num_nodes, self.num_slots, self.num_sums
        rho_col = (columns.first + self._rho_first + np.arange(n * m)).reshape(n, m)
        node = np.arange(n)[:, None]
        slot = np.arange(m)
        block_row = (n + node * self.num_blocks + slot // self.block_slots if sums
                     else np.broadcast_to(node, (n, m)))
        coefficients = Entries(rows=block_row.ravel(), cols=rho_col.ravel(),
                               values=np.zeros(n * m))
        first_cone = self._parent_rows
        cone = first_cone + 3 * np.arange(n * m)[:, None] + np.arange(3)
        z_cols = np.broadcast_to(columns.z, (n, m, 2)).reshape(-1, 2)
        cone_entries = Entries(
            rows=cone.ravel(),
            cols=np.concatenate([rho_col.reshape(-1, 1), z_cols], axis=1).ravel(),
            values=-np.ones(3 * n * m))
        return Entries.join(parent, coefficients, cone_entries)

    def right_hand_side(self) -> np.ndarray:
        n, m = self.num_nodes, self.num_slots
        cones = np.zeros((n, m, 3))
        cones[:, :, 1:] = -self.w[:, None, :]
        return np.concatenate([super().right_hand_side(), cones.ravel()])

    def at(self, expansion: Expansion) -> ChannelRows:
        """The bound's coefficients at q^k with power p, in kilometres, offsets added."""
        coef = channel_coefficients(expansion.q_k, expansion.p, self.frame.scenario)
        constant = coef.constant.mean(axis=1)
        return ChannelRows(weight=coef.weight * KM ** 2,
                           constant=with_offsets(constant, expansion.offsets),
                           linear=coef.linear * KM)

    def update(self, rows: ChannelRows) -> tuple[np.ndarray, np.ndarray]:
        entries, b = super().update(rows)
        return np.concatenate([entries, (rows.linear / self.num_slots).ravel()]), b

    def constraints(self, v, rows: ChannelRows) -> list[cp.Constraint]:
        """The node rows, then per node the cones rho_{n,m} >= ||z[m] - w_n|| (their duals
        give the certificate's supergradient where z sits on a node)."""
        m = self.num_slots
        rho = cp.Variable((self.num_nodes, m))
        rows_ = [rows.constant[n]
                 - rows.weight[n] @ cp.sum(cp.square(v.z - self.w[n][None, :]), axis=1) / m
                 - rows.linear[n] @ rho[n] / m >= v.t for n in range(self.num_nodes)]
        cones = [cp.SOC(rho[n], (v.z - self.w[n][None, :]).T, axis=0)
                 for n in range(self.num_nodes)]
        return rows_ + cones

    def certificate(self, z: np.ndarray, rows: ChannelRows, duals: Sequence,
                    bound: DualBound | None = None) -> DualBound | None:
        """:class:`NodeRates`' certificate with -A ||z - w||'s supergradient -A u: u the unit
        vector (z - w) / ||z - w|| away from the node, and -mu / mu_0 from the cone's dual
        (mu_0, mu) on it (the element of the subdifferential the optimum uses). Either way
        -||x|| <= -u . x for ||u|| <= 1, so the Lagrangian with u . (z - w) in place of
        ||z - w|| is above the true one and smooth: its bound holds for the true one."""
        n_nodes = self.num_nodes
        node_duals, cone_duals = duals[:n_nodes], duals[n_nodes:]
        smooth = super().certificate(z, NodeRows(rows.weight, rows.constant), node_duals,
                                     bound)
        if smooth is None:
            return None
        lam = np.maximum(np.array([float(d) for d in node_duals]), 0.0)
        lam = lam / lam.sum()
        gaps = z[None] - self.w[:, None]                                   # (N, M, 2)
        lengths = np.sqrt((gaps ** 2).sum(axis=-1))
        units = gaps / np.maximum(lengths, 1e-300)[..., None]
        for n, dual in enumerate(cone_duals):
            corner = lengths[n] <= CORNER_KM
            if dual is None or not corner.any():
                continue
            mu0 = np.asarray(dual[0], dtype=float).reshape(-1)
            mu = -np.asarray(dual[1], dtype=float).reshape(2, -1).T
            scale = np.maximum(np.maximum(mu0, np.sqrt((mu ** 2).sum(axis=1))), 1e-300)
            units[n, corner] = (mu / scale[:, None])[corner]
        reach = lam[:, None] * rows.linear / self.num_slots                # (N, M)
        gradient = smooth.gradient - np.einsum('nm,nmk->mk', reach, units)
        smooth_values = rows.constant - (rows.weight * lengths ** 2).mean(axis=1)
        lagrangian = float(lam @ smooth_values) - float((reach * (units * gaps).sum(-1)).sum())
        f = rows.values(z, self.w)
        return DualBound(value=float(f.min()), lagrangian=lagrangian, gradient=gradient,
                         modulus=smooth.modulus)


__all__ = ['ChannelRates', 'ChannelRows', 'CORNER_KM']
