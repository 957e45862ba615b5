"""The zone block: the no-fly zones' and the operating area's restriction at q^k.

:mod:`~uav_comm_planner.core.zone_rows` turns the zones, at the current path, into K linear
rows per slot, a_{m,k} . q[m] >= o_{m,k} (metres): in centred kilometres
a . z[m] >= (o - a . c) / 1000. In the cone program they are M K non-negative rows,
s = b - A x with A = -a on z[m] and b = -(o - a . c) / 1000; every entry and every b changes
at every step (the rows are the restriction at each step's expansion point).

Dual certificate: eta_{m,k} >= 0 adds eta (a . z[m] - b'), supergradient eta a in z[m].
"""

from __future__ import annotations

from dataclasses import dataclass
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

#: The fast step's rows per slot come from this many polygon pieces at the most, the nearest
#: (:class:`ZoneHalfPlanes`); a step that breaks one left out is solved again with them all.
NEAREST_PIECES = 24
#: A broken row of the restriction that the step left out, in metres beyond this, makes the
#: step :meth:`ZoneHalfPlanes.complete` false (the solvers' own tolerance is about 1e-5 m
#: on the rows they have; the rows ask for a millimetre more than the margin).
LEFT_OUT_SLACK_M = 1e-6


@dataclass(frozen=True)
class ZoneStepRows:
    """The rows a step imposes (``rows``) and the whole restriction at q^k (``every``): the
    same object when the step imposes all of them."""

    rows: ZoneRows
    every: ZoneRows

    @property
    def normals(self) -> np.ndarray:
        return self.rows.normals

    @property
    def offsets(self) -> np.ndarray:
        return self.rows.offsets

    def slack(self, q: np.ndarray) -> np.ndarray:
        """The imposed rows' slack at q (M, 2) metres (:meth:`ZoneRows.slack`)."""
        return self.rows.slack(q)


class ZoneHalfPlanes(Block):
    """The zones' rows at q^k (module docstring); build it only for a scenario with zones.

    With ``pieces`` only the rows of the ``pieces`` polygon pieces nearest each slot at q^k
    (or at ``also``, slot points (M, 2) metres: an answer that broke rows left out) are
    imposed (:meth:`~uav_comm_planner.core.zone_rows.ZoneModel.nearest_rows`; a 1000-vertex
    star is 500 pieces, two rows each per slot); :meth:`complete` says whether the answer
    keeps the rows left out, and a step whose answer does not is solved again with twice the
    pieces, those nearest that answer among them
    (:class:`~uav_comm_planner.core.sca.fast.ClarabelTrajectoryStep`), so the step's answer is
    the whole restriction's."""

    def __init__(self, frame: Frame, pieces: int | None = None,
                 also: np.ndarray | None = None):
        super().__init__(frame)
        self.model = zone_model(frame.scenario.zones)
        if self.model is None:
            raise ValueError('ZoneHalfPlanes needs a scenario with zones')
        self.num_slots = frame.scenario.num_slots
        self.pieces = pieces
        self.also = also
        self.per_slot = self.model.pieces_rows_per_slot(pieces)
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

    def at(self, expansion: Expansion) -> ZoneStepRows:
        path = flown_path(expansion.q_k, self.frame.scenario)
        every = self.model.rows(path)
        if self.per_slot == self.model.rows_per_slot:
            return ZoneStepRows(every, every)
        points = [path[1:-1]] + ([] if self.also is None else [self.also])
        return ZoneStepRows(self.model.nearest_rows(every, points, self.pieces), every)

    def complete(self, q: np.ndarray, data: ZoneStepRows) -> bool:
        """Whether q (M, 2) metres keeps every row of the restriction, those left out too."""
        if data.rows is data.every:
            return True
        return bool(data.every.slack(q).min(initial=np.inf) >= -LEFT_OUT_SLACK_M)

    def offsets_km(self, rows: ZoneRows) -> np.ndarray:
        """(o - a . c) / 1000, (M, K): the rows' offsets in the frame."""
        return (rows.offsets - rows.normals @ self.frame.centre_m) / KM

    def update(self, data: ZoneStepRows) -> tuple[np.ndarray, np.ndarray]:
        return -data.rows.normals.ravel(), -self.offsets_km(data.rows).ravel()

    def constraints(self, v: Variables, data: ZoneStepRows) -> list[cp.Constraint]:
        rows = data.rows
        offsets = self.offsets_km(rows)
        return [cp.sum(cp.multiply(rows.normals[:, k, :], v.z), axis=1) >= offsets[:, k]
                for k in range(self.per_slot)]

    def certificate(self, z: np.ndarray, data: ZoneStepRows, duals: Sequence,
                    bound: DualBound) -> DualBound | None:
        rows = data.rows
        if not duals:
            return bound
        slack = np.einsum('mkj,mj->mk', rows.normals, z) - self.offsets_km(rows)
        if slack.size and slack.min() < -LEG_SLACK * max(1.0, float(np.abs(z).max())):
            return None
        eta = np.maximum(np.stack([np.asarray(d, dtype=float).reshape(-1) for d in duals],
                                  axis=1), 0.0)
        return bound.plus(float((eta * slack).sum()),
                          np.einsum('mk,mkj->mj', eta, rows.normals))


__all__ = ['LEFT_OUT_SLACK_M', 'NEAREST_PIECES', 'ZoneHalfPlanes', 'ZoneStepRows']
