"""The path budget block: a warm replan's path no longer than at q^k.

With ``keep_path_length`` (:class:`~uav_comm_planner.core.scenario.SolverSettings`) the path
q0, z[1..M], qF is at most L^k long, the length of the path at q^k: sum_l ||leg_l|| <= L^k.
In the cone program: one non-negative row L^k - sum_l s_l, whose b changes at every step, on
the legs' lengths s_l that the leg block shares
(:class:`~uav_comm_planner.core.sca.legs.LegLimits` with ``lengths``, which
:func:`~uav_comm_planner.core.sca.program.step_blocks` sets with the budget). A solver meets
the budget only to its tolerance: :meth:`PathBudget.repair` blends the answer back within it
(:func:`within_path_budget`).

Dual certificate: kappa >= 0 adds kappa (L - sum_l ||leg_l||) <= kappa (L - sum_l v_l . leg_l)
for any ||v_l|| <= 1, a linear term in z; slot m (between legs m - 1 and m) gets
kappa (v_m - v_{m-1}) in its supergradient. Of several v (the legs' own directions, and the v
that zero every slot's supergradient, v_m = v_{m-1} - g_m / kappa, the stationarity the optimum
meets, from the first leg's direction, from the last one's, and their mean, each cut to the
unit disc) the best bound is kept.
"""

from __future__ import annotations

from typing import Sequence

import clarabel
import cvxpy as cp
import numpy as np

from uav_comm_planner.core.feasibility import LEG_SLACK
from uav_comm_planner.core.sca.block import (Block, Columns, DualBound, Entries, Expansion,
                                             Frame, Variables)
from uav_comm_planner.core.sca.legs import leg_units
from uav_comm_planner.core.sca.surrogate import path_length_km
from uav_comm_planner.core.scenario import Scenario

#: Bisections of :func:`within_path_budget`: lam to 1e-12, a fraction of a millimetre on any path.
BUDGET_BISECTIONS = 40


def within_path_budget(q: np.ndarray, q_k: np.ndarray, scenario: Scenario,
                       budget_km: float) -> np.ndarray:
    """A step's answer q (M, 2) metres with its path no longer than ``budget_km``, the length
    of q^k's: q itself when it keeps it, else the blend (1 - lam) q^k + lam q with the largest
    lam that does (bisection; the length is convex along the blend and q^k keeps it). A solver
    meets the budget only to its tolerance, and at the loose one each step would otherwise
    add a few 1e-4 of the length to the next step's budget. The blend keeps the speed limits
    (convex) and, the step's bound being concave, a bound at least q^k's."""
    if path_length_km(q, scenario) <= budget_km:
        return q
    low, high = 0.0, 1.0
    for _ in range(BUDGET_BISECTIONS):
        middle = 0.5 * (low + high)
        if path_length_km((1.0 - middle) * q_k + middle * q, scenario) <= budget_km:
            low = middle
        else:
            high = middle
    return (1.0 - low) * q_k + low * q


class PathBudget(Block):
    """sum_l ||leg_l|| <= L^k (module docstring); its per-step data is (q^k, L^k km)."""

    def __init__(self, frame: Frame):
        super().__init__(frame)
        self.num_slots = frame.scenario.num_slots
        self.changing_rows = np.array([0])

    @property
    def form(self) -> tuple:
        return ('path budget', self.num_slots)

    def cones(self) -> tuple:
        return (clarabel.NonnegativeConeT(1),)

    def pattern(self, columns: Columns) -> Entries:
        if 'leg lengths' not in columns.shared:
            raise ValueError('the path budget needs the legs block with lengths before it')
        legs = self.num_slots + 1
        return Entries(rows=np.zeros(legs, dtype=int),
                       cols=columns.shared['leg lengths'] + np.arange(legs),
                       values=np.ones(legs))

    def right_hand_side(self) -> np.ndarray:
        return np.zeros(1)

    def at(self, expansion: Expansion) -> tuple[np.ndarray, float]:
        return expansion.q_k, path_length_km(expansion.q_k, self.frame.scenario)

    def update(self, data: tuple[np.ndarray, float]) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(0), np.array([data[1]])

    def constraints(self, v: Variables, data: tuple[np.ndarray, float]) -> list[cp.Constraint]:
        return [cp.sum(cp.norm(v.legs, 2, axis=1)) <= data[1]]

    def certificate(self, z: np.ndarray, data: tuple[np.ndarray, float], duals: Sequence,
                    bound: DualBound) -> DualBound | None:
        budget = data[1]
        legs = self.frame.legs(z)
        length, units = leg_units(legs)
        if length.sum() > budget * (1 + LEG_SLACK):
            return None
        kappa = float(duals[0])
        if not kappa > 0.0:
            return bound
        g = bound.gradient
        forward = np.vstack([units[:1], units[:1] - np.cumsum(g, axis=0) / kappa])
        backward = forward - forward[-1] + units[-1]
        best = None
        for v in (units, forward, backward, (forward + backward) / 2.0):
            v = v / np.maximum(np.linalg.norm(v, axis=1), 1.0)[:, None]
            candidate = bound.plus(kappa * float(budget - (v * legs).sum()),
                                   kappa * (v[1:] - v[:-1]))
            if best is None or candidate.total < best.total:
                best = candidate
        return best

    def holds(self, q: np.ndarray, data: tuple[np.ndarray, float], slack: float) -> bool:
        return path_length_km(q, self.frame.scenario) <= data[1] * (1 + slack)

    def repair(self, q: np.ndarray, data: tuple[np.ndarray, float]) -> np.ndarray:
        return within_path_budget(q, data[0], self.frame.scenario, data[1])


__all__ = ['BUDGET_BISECTIONS', 'PathBudget', 'within_path_budget']
