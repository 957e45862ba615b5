"""The speed limit ||q[m] - q[m-1]|| <= V delta: one check and one projection for the package.

Every leg counts, q0 -> q[1] and q[M] -> qF included (:func:`~uav_comm_planner.core.model.
leg_lengths`). An interior-point solver meets a constraint to its feasibility tolerance, not
exactly, so the check allows a leg :data:`LEG_SLACK` longer than V delta; the projection then
removes even that (Algorithm 1 projects every trajectory it keeps).
"""

from __future__ import annotations

import math

import numpy as np

from uav_comm_planner.core import initial
from uav_comm_planner.core.model import leg_lengths
from uav_comm_planner.core.scenario import Scenario

#: The share by which a leg may exceed V delta and still count as within the limit: the
#: conic solvers' feasibility tolerance, well above round-off and far below a metre.
LEG_SLACK = 1e-7


def within_speed_limit(q: np.ndarray | None, scenario: Scenario) -> bool:
    """Whether q (M, 2) metres is a finite path of ``scenario``'s M slots whose every leg, with
    q0 and qF, is at most V delta (1 + :data:`LEG_SLACK`)."""
    if q is None:
        return False
    q = np.asarray(q, dtype=float)
    if q.shape != (scenario.num_slots, 2) or not np.all(np.isfinite(q)):
        return False
    return bool(leg_lengths(q, scenario).max() <= scenario.max_step_m * (1 + LEG_SLACK))


def project_onto_speed_limit(q: np.ndarray, scenario: Scenario) -> np.ndarray:
    """q (M, 2) metres, moved just enough toward the straight line that no leg exceeds V delta.

    With s the straight line q0 -> qF at uniform speed (legs D / (M + 1) <= V delta, D =
    ||qF - q0||) and L the longest leg of q, the blend (1 - lam) q + lam s has legs at most
    (1 - lam) L + lam D / (M + 1) (triangle inequality), which is V delta for
    lam = (L - V delta) / (L - D / (M + 1)). A solver's answer is within round-off of the
    limit, so lam is of that order; at the goal's maximum reach, D = (M + 1) V delta, lam = 1
    and the only feasible path, the straight line, is returned. q itself is returned when
    every leg is within the limit.
    """
    q = np.asarray(q, dtype=float).reshape(-1, 2)
    limit = scenario.max_step_m
    longest = float(leg_lengths(q, scenario).max())
    if longest <= limit:
        return q
    straight = initial.straight_line(scenario)
    straight_leg = math.dist(scenario.start_m, scenario.goal_m) / (scenario.num_slots + 1)
    if not math.isfinite(longest) or longest - straight_leg <= 0:
        return straight
    # A few ulps more than the exact lam, so that the blend's round-off stays within V delta.
    lam = min(1.0, (longest - limit) / (longest - straight_leg) * (1 + 1e-12) + 1e-15)
    return (1.0 - lam) * q + lam * straight


__all__ = ['LEG_SLACK', 'project_onto_speed_limit', 'within_speed_limit']
