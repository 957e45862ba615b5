"""The leg block: every leg of the path within the speed limits.

Leg l of the path q0, z[1..M], qF (l = 0..M) lies in every disc of
:func:`~uav_comm_planner.core.feasibility.limit_discs`: ||leg_l - c|| <= r, the ground speed
(c = 0, r = V delta) and, in wind or with an airspeed below V, the airspeed (c the slot's
drift, r = V_air delta). In the cone program each is M + 1 second-order cones of dimension 3,
s = (r, leg_l - c); b holds r, -c and the ends q0 and qF, all fixed for the scenario. With
``lengths`` (for the path budget, :mod:`~uav_comm_planner.core.sca.path_budget`) the ground
cones bound each leg by a column of its own, its length s_l, instead of V delta:
s = (s_l, leg_l), with M + 1 non-negative rows V delta - s_l after the cones; the lengths are
shared as ``'leg lengths'`` (the same cones, a quarter fewer rows than cones of their own).

Dual certificate: nu_l >= 0 per disc and leg adds nu_l (r - ||leg_l - c||), whose supergradient
in z[m] (between legs m - 1 and m) is -nu_{m-1} u_{m-1} + nu_m u_m, u the legs' unit vectors.
"""

from __future__ import annotations

from typing import Any, Sequence

import clarabel
import cvxpy as cp
import numpy as np

from uav_comm_planner.core.feasibility import LEG_SLACK, limit_discs, within_speed_limit
from uav_comm_planner.core.sca.block import (Block, Columns, DualBound, Entries, Frame,
                                             Variables)
from uav_comm_planner.core.sca.surrogate import KM


def leg_entries(columns: Columns, first_row: int) -> Entries:
    """The z entries of M + 1 cones of dimension 3, s = (., z[l + 1] - z[l]) from
    ``first_row`` (s = b - A x: z[l + 1] enters leg l with -1, z[l] with +1; q0 and qF are
    in b)."""
    num_slots = columns.num_slots
    z_col = columns.z.ravel()
    index = np.arange(2 * num_slots)
    end_of_leg = first_row + 1 + 3 * (index // 2) + index % 2
    return Entries(rows=np.concatenate([end_of_leg, end_of_leg + 3]),
                   cols=np.concatenate([z_col, z_col]),
                   values=np.repeat([-1.0, 1.0], 2 * num_slots))


def leg_right_hand_side(frame: Frame, radius_km: float,
                        centre_km: np.ndarray) -> np.ndarray:
    """b of the M + 1 cones (r, leg_l - c): (3 (M + 1),)."""
    m = frame.scenario.num_slots
    b = np.zeros((m + 1, 3))
    b[:, 0] = radius_km
    b[:, 1:] = -centre_km
    b[0, 1:] -= frame.start
    b[m, 1:] += frame.goal
    return b.ravel()


def leg_units(legs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The legs' lengths (L,) and unit vectors (L, 2); a leg of length 0 gets 0, a
    supergradient of -||.|| there."""
    length = np.linalg.norm(legs, axis=1)
    units = np.divide(legs, length[:, None], out=np.zeros_like(legs),
                      where=length[:, None] > 0.0)
    return length, units


class LegLimits(Block):
    """Every leg in every limit disc (module docstring); with ``lengths``, the legs' lengths
    as columns of their own."""

    def __init__(self, frame: Frame, *, lengths: bool = False):
        super().__init__(frame)
        # The ground speed's disc comes first (centre 0), the one the lengths bound.
        self.discs = [(centre / KM, radius / KM) for centre, radius in
                      limit_discs(frame.scenario)]
        self.num_slots = frame.scenario.num_slots
        self.lengths = bool(lengths)
        if self.lengths:
            self.num_columns = self.num_slots + 1
            self.shares = {'leg lengths': 0}

    @property
    def form(self) -> tuple:
        return ('legs', self.num_slots, len(self.discs), self.lengths)

    def cones(self) -> tuple:
        legs = self.num_slots + 1
        return ((clarabel.SecondOrderConeT(3),) * (legs * len(self.discs))
                + ((clarabel.NonnegativeConeT(legs),) if self.lengths else ()))

    def pattern(self, columns: Columns) -> Entries:
        legs = self.num_slots + 1
        parts = [leg_entries(columns, 3 * legs * k) for k in range(len(self.discs))]
        if self.lengths:
            # s_l as the first entry of ground cone l (b 0 there), and in row l after the
            # cones, V delta - s_l.
            s_col = columns.first + np.arange(legs)
            parts.append(Entries(
                rows=np.concatenate([3 * np.arange(legs), 3 * legs * len(self.discs)
                                     + np.arange(legs)]),
                cols=np.concatenate([s_col, s_col]),
                values=np.concatenate([-np.ones(legs), np.ones(legs)])))
        return Entries.join(*parts)

    def right_hand_side(self) -> np.ndarray:
        b = [leg_right_hand_side(self.frame, radius, centre) for centre, radius in self.discs]
        if self.lengths:
            b.append(np.full(self.num_slots + 1, b[0][0]))
            b[0] = b[0].copy()
            b[0][::3] = 0.0
        return np.concatenate(b)

    def constraints(self, v: Variables, data: Any) -> list[cp.Constraint]:
        return [cp.norm(v.legs - centre[None, :], 2, axis=1) <= radius
                for centre, radius in self.discs]

    def certificate(self, z: np.ndarray, data: Any, duals: Sequence,
                    bound: DualBound) -> DualBound | None:
        legs = self.frame.legs(z)
        for (centre, radius), dual in zip(self.discs, duals):
            length, units = leg_units(legs - centre)
            if length.max() > radius * (1 + LEG_SLACK):
                return None
            nu = np.maximum(np.asarray(dual, dtype=float).reshape(-1), 0.0)
            gradient = -nu[:-1, None] * units[:-1] + nu[1:, None] * units[1:]
            bound = bound.plus(float(nu @ (radius - length)), gradient)
        return bound

    def holds(self, q: np.ndarray, data: Any, slack: float) -> bool:
        return within_speed_limit(q, self.frame.scenario, slack=slack)


__all__ = ['leg_entries', 'leg_right_hand_side', 'leg_units', 'LegLimits']
