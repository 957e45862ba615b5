"""The zone block: the no-fly zones' and the operating area's restriction at q^k.

:mod:`~uav_comm_planner.core.zone_rows` turns the zones, at the current path, into K linear
rows per slot, a_{m,k} . q[m] >= o_{m,k} (metres): in centred kilometres
a . z[m] >= (o - a . c) / 1000. In the cone program they are M K non-negative rows,
s = b - A x with A = -a on z[m] and b = -(o - a . c) / 1000; every entry and every b changes
at every step (the rows are the restriction at each step's expansion point).

Dual certificate: eta_{m,k} >= 0 adds eta (a . z[m] - b'), supergradient eta a in z[m].
"""

from __future__ import annotations

from typing import Sequence

import clarabel
import cvxpy as cp
import numpy as np

from uav_comm_planner.core.feasibility import LEG_SLACK
from uav_comm_planner.core.model import flown_path
from uav_comm_planner.core.sca.block import (Block, Columns, DualBound, Entries, Expansion,
                                             Frame, Variables)
from uav_comm_planner.core.sca.surrogate import KM
from uav_comm_planner.core.zone_rows import zone_model, ZoneRows


class ZoneHalfPlanes(Block):
    """The zones' rows at q^k (module docstring); build it only for a scenario with zones."""

    def __init__(self, frame: Frame):
        super().__init__(frame)
        self.model = zone_model(frame.scenario.zones)
        if self.model is None:
            raise ValueError('ZoneHalfPlanes needs a scenario with zones')
        self.num_slots = frame.scenario.num_slots
        self.per_slot = self.model.rows_per_slot
        count = self.num_slots * self.per_slot
        self.changing_entries = np.arange(2 * count)
        self.changing_rows = np.arange(count)

    @property
    def form(self) -> tuple:
        return ('zones', self.num_slots, self.per_slot)

    def cones(self) -> tuple:
        count = self.num_slots * self.per_slot
        return (clarabel.NonnegativeConeT(count),) if count else ()

    def pattern(self, columns: Columns) -> Entries:
        """Slot m's row k on z[m]_x and z[m]_y, in (m, k, (x, y)) order."""
        rows = np.arange(self.num_slots * self.per_slot)
        slot = np.repeat(np.arange(self.num_slots), self.per_slot)
        return Entries(rows=np.repeat(rows, 2), cols=columns.z[slot].ravel(),
                       values=np.zeros(2 * len(rows)))

    def right_hand_side(self) -> np.ndarray:
        return np.zeros(self.num_slots * self.per_slot)

    def at(self, expansion: Expansion) -> ZoneRows:
        return self.model.rows(flown_path(expansion.q_k, self.frame.scenario))

    def offsets_km(self, rows: ZoneRows) -> np.ndarray:
        """(o - a . c) / 1000, (M, K): the rows' offsets in the frame."""
        return (rows.offsets - rows.normals @ self.frame.centre_m) / KM

    def update(self, rows: ZoneRows) -> tuple[np.ndarray, np.ndarray]:
        return -rows.normals.ravel(), -self.offsets_km(rows).ravel()

    def constraints(self, v: Variables, rows: ZoneRows) -> list[cp.Constraint]:
        offsets = self.offsets_km(rows)
        return [cp.sum(cp.multiply(rows.normals[:, k, :], v.z), axis=1) >= offsets[:, k]
                for k in range(self.per_slot)]

    def certificate(self, z: np.ndarray, rows: ZoneRows, duals: Sequence,
                    bound: DualBound) -> DualBound | None:
        if not duals:
            return bound
        slack = np.einsum('mkj,mj->mk', rows.normals, z) - self.offsets_km(rows)
        if slack.size and slack.min() < -LEG_SLACK * max(1.0, float(np.abs(z).max())):
            return None
        eta = np.maximum(np.stack([np.asarray(d, dtype=float).reshape(-1) for d in duals],
                                  axis=1), 0.0)
        return bound.plus(float((eta * slack).sum()),
                          np.einsum('mk,mkj->mj', eta, rows.normals))


__all__ = ['ZoneHalfPlanes']
