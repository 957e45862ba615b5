"""The speed limits: one check and one projection for the package.

Every leg l = q[m] - q[m-1] counts, q0 -> q[1] and q[M] -> qF included: ||l|| <= V delta over
the ground and, in wind or with an airspeed below V, ||l - w delta|| <= V_air delta through
the air (:class:`~uav_comm_planner.core.scenario.Scenario`). An interior-point solver meets a
constraint to its feasibility tolerance, not exactly, so the check allows a leg
:data:`LEG_SLACK` beyond a limit; the projection then removes even that (Algorithm 1
projects every trajectory it keeps).
"""

from __future__ import annotations

import math

import numpy as np

from uav_comm_planner.core import initial
from uav_comm_planner.core.model import legs, vector_lengths
from uav_comm_planner.core.scenario import Scenario

#: The share by which a leg may exceed V delta and still count as within the limit: the
#: conic solvers' feasibility tolerance, well above round-off and far below a metre.
LEG_SLACK = 1e-7


def limit_discs(scenario: Scenario) -> list[tuple[np.ndarray, float]]:
    """The discs every leg must lie in, as (centre (2,) metres, radius metres): the ground
    speed disc, and the airspeed disc centred on the slot's drift when it constrains more."""
    discs = [(np.zeros(2), scenario.max_step_m)]
    if scenario.airspeed_limited:
        discs.append((scenario.drift_m, scenario.max_air_step_m))
    return discs


def within_speed_limit(q: np.ndarray | None, scenario: Scenario, *,
                       slack: float = LEG_SLACK) -> bool:
    """Whether q (M, 2) metres is a finite path of ``scenario``'s M slots whose every leg, with
    q0 and qF, keeps every limit (:func:`limit_discs`) to within the share ``slack``."""
    if q is None:
        return False
    q = np.asarray(q, dtype=float)
    if q.shape != (scenario.num_slots, 2) or not np.all(np.isfinite(q)):
        return False
    steps = legs(q, scenario)
    return all(float(np.linalg.norm(steps - centre, axis=1).max()) <= radius * (1 + slack)
               for centre, radius in limit_discs(scenario))


def project_onto_speed_limit(q: np.ndarray, scenario: Scenario) -> np.ndarray:
    """q (M, 2) metres, moved just enough toward the straight line that every leg keeps every
    limit.

    With s the straight line q0 -> qF at uniform speed (each of its legs feasible, since the
    scenario's goal is reachable) and, for a limit disc of centre c and radius r, L the largest
    ||l - c|| over the legs l of q and S = ||s_leg - c|| <= r, the blend (1 - lam) q + lam s has
    ||l' - c|| <= (1 - lam) L + lam S (triangle inequality), which is r for
    lam = (L - r) / (L - S); the largest lam over the discs serves all. A solver's answer is
    within round-off of the limits, so lam is of that order; at the goal's maximum reach
    (S = r) lam = 1 and the only feasible path, the straight line, is returned. q itself is
    returned when every leg is within the limits.
    """
    q = np.asarray(q, dtype=float).reshape(-1, 2)
    steps = legs(q, scenario)
    lam = 0.0
    for centre, radius in limit_discs(scenario):
        # Without numpy.linalg.norm's checks: this runs on every start and every step.
        longest = float(vector_lengths(steps - centre, axis=1).max())
        if longest <= radius:
            continue
        straight_leg = (np.asarray(scenario.goal_m, float)
                        - np.asarray(scenario.start_m, float)) / (scenario.num_slots + 1)
        straight = float(np.linalg.norm(straight_leg - centre))
        if not math.isfinite(longest) or longest - straight <= 0:
            return initial.straight_line(scenario)
        lam = max(lam, (longest - radius) / (longest - straight))
    if lam == 0.0:
        return q
    # A few ulps more than the exact lam, so that the blend's round-off stays within the limit.
    lam = min(1.0, lam * (1 + 1e-12) + 1e-15)
    return (1.0 - lam) * q + lam * initial.straight_line(scenario)


def retimed(q: np.ndarray, scenario: Scenario) -> np.ndarray | None:
    """q (M, 2) metres flown along its own path q0 -> q[1..M] -> qF at a pace that keeps
    ``scenario``'s speed limits: every slot advances along the path by at most the radius r of
    the largest leg disc about zero inside every limit disc (min over the discs of radius
    minus the distance of its centre from zero), as close to q's own arc length as that allows
    and never later than what still reaches qF at that pace; a chord of the path is no longer
    than the arc it spans, so every leg keeps the limits. The path's stops are shortened to
    pay for its slower legs; q itself when it keeps the limits. None when the path is longer
    than M + 1 legs of r.

    With s_m q's arc length at slot m, S the path's length and L_m = S - (M + 1 - m) r the
    least arc that still reaches qF: s'_0 = 0, s'_m = max(s'_{m-1}, min(s_m, s'_{m-1} + r),
    L_m); each increment is at most r since L_m - L_{m-1} = r and s'_{m-1} >= L_{m-1}.
    """
    if within_speed_limit(q, scenario, slack=0.0):
        return np.asarray(q, dtype=float)
    path = np.vstack([scenario.start_m, np.asarray(q, dtype=float).reshape(-1, 2),
                      scenario.goal_m])
    pieces = np.linalg.norm(np.diff(path, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(pieces)])
    radius = min(r - float(np.linalg.norm(c)) for c, r in limit_discs(scenario)) * (1 - 1e-9)
    total, slots = float(arc[-1]), scenario.num_slots
    if not (math.isfinite(total) and radius > 0.0) or total > (slots + 1) * radius:
        return None
    paced = np.zeros(slots + 1)
    for m in range(1, slots + 1):
        paced[m] = max(paced[m - 1], min(arc[m], paced[m - 1] + radius),
                       total - (slots + 1 - m) * radius)
    kept = np.concatenate([[True], pieces > 0.0])           # np.interp needs increasing arcs
    return np.column_stack([np.interp(paced[1:], arc[kept], path[kept, axis])
                            for axis in range(2)])


__all__ = ['LEG_SLACK', 'limit_discs', 'project_onto_speed_limit', 'retimed',
           'within_speed_limit']
