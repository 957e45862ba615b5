"""Trajectory step (letter, problem (11)): successive convex approximation with power fixed.

Around the current trajectory q^k, with d^k_{n,m} = ||q^k[m] - w_n||^2 + H^2 and the SNR
there, snr^k_{n,m} = p_n[m] a_n[m](q^k) = gamma beta0 / d^k, the convexity of
log2(1 + A / (d + x)) in x gives, for x = ||q[m] - w_n||^2 - ||q^k[m] - w_n||^2,

    r_{n,m}(q) >= lbr_{n,m}(q) = log2(1 + snr^k) - snr^k / ((1 + snr^k) ln 2) * x / d^k,

which is the letter's bound, since
gamma beta0 / (d^k (gamma beta0 + d^k)) = snr^k / ((1 + snr^k) d^k).
The bound is global and tight at q^k, so maximising min_n mean_m lbr_{n,m} subject to the
speed limits never lowers the true minimum rate.

With offsets o_n (N,) bits per use (the data a node already holds, see
:mod:`uav_comm_planner.core.receding`) the step maximises min_n (o_n + mean_m lbr_{n,m}): the
same bound plus a constant per node, still global and tight at q^k.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import functools
import math
from typing import Callable, Sequence

import cvxpy as cp
import numpy as np

from uav_comm_planner.core.conic import Certificate, solve_checked
from uav_comm_planner.core.feasibility import LEG_SLACK, limit_discs
from uav_comm_planner.core.model import (flown_path, leg_lengths, LN2, snr_scale,
                                         squared_distances)
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.core.zone_rows import zone_model, ZoneRows

#: The conic problems see positions in kilometres: coordinates of order 1, not 1000.
KM = 1000.0


@dataclass(frozen=True)
class SurrogateCoefficients:
    """lbr_{n,m}(q) = value - slope * (||q[m] - w_n||^2 - ||q^k[m] - w_n||^2) / d^k.

    value: log2(1 + snr^k), (N, M) bits per use; slope: snr^k / ((1 + snr^k) ln 2), (N, M);
    d: d^k, (N, M) square metres; horizontal: ||q^k[m] - w_n||^2, (N, M) square metres.
    """

    value: np.ndarray
    slope: np.ndarray
    d: np.ndarray
    horizontal: np.ndarray


def surrogate_coefficients(q_k: np.ndarray, p: np.ndarray,
                           scenario: Scenario) -> SurrogateCoefficients:
    """The SCA bound's coefficients at the expansion point q^k (M, 2) for power p (N, M)."""
    d = squared_distances(q_k, scenario)
    snr = np.asarray(p, dtype=float) * (snr_scale(scenario) / d)
    return SurrogateCoefficients(value=np.log1p(snr) / LN2,
                                 slope=snr / ((1.0 + snr) * LN2),
                                 d=d, horizontal=d - scenario.altitude_m ** 2)


def kilometre_rows(coef: SurrogateCoefficients) -> tuple[np.ndarray, np.ndarray]:
    """The bound in kilometres: mean_m lbr_{n,m}(q) = constant_n - (1/M) sum_m weight_{n,m}
    ||z[m] - w_n||^2 with z = q / 1000 and w_n / 1000. Returns weight (N, M), per km^2, and
    constant (N,), bits per use."""
    # x / d^k is dimensionless, so the slope may be divided by d^k in km^2.
    weight = coef.slope / (coef.d / KM ** 2)
    constant = (coef.value + weight * coef.horizontal / KM ** 2).sum(axis=1) / weight.shape[1]
    return weight, constant


def sca_lower_bound(q: np.ndarray, q_k: np.ndarray, p: np.ndarray,
                    scenario: Scenario) -> np.ndarray:
    """lbr_{n,m}(q) expanded at q^k: (N, M) bits per use, a lower bound of log2(1 + p a(q))."""
    coef = surrogate_coefficients(q_k, p, scenario)
    x = squared_distances(q, scenario) - coef.d
    return coef.value - coef.slope * x / coef.d


@dataclass(frozen=True)
class TrajectoryStep:
    """q: (M, 2) metres, the maximiser; bound: min_n mean_m lbr_{n,m}(q), bits per use.

    Algorithm 1 judges a step by the true rates, so the bound is evaluated on first use only
    (``bound_of`` computes it).
    """

    q: np.ndarray
    bound_of: Callable[[], float] = field(repr=False, compare=False)

    @functools.cached_property
    def bound(self) -> float:
        return float(self.bound_of())


def with_offsets(constant: np.ndarray, offsets: np.ndarray | None) -> np.ndarray:
    """constant_n + o_n (N,), or ``constant`` itself without offsets."""
    if offsets is None:
        return constant
    return constant + np.asarray(offsets, dtype=float).reshape(-1)


#: A cvxpy trajectory step is accepted when its duality gap (:func:`sca_duality_gap`) is at
#: most this share of max(1, value); the alternating loop then also keeps it only if the true
#: minimum rate does not drop.
CERTIFIED_GAP = 1e-7
#: Tried when the solver's defaults stop short of optimal: more iterations, tighter
#: tolerances, the answer still judged by its duality gap.
CLARABEL_RETRY = dict(max_iter=400, tol_gap_abs=1e-9, tol_gap_rel=1e-9, tol_feas=1e-9)
#: The last try: the path budget's multiplier is large where the budget binds hard, and the
#: certificate then needs the budget met to about 1e-11 (seen: 1.2e-7 at 1e-9, 3e-9 here).
CLARABEL_LAST_RETRY = dict(max_iter=400, tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)


@dataclass(frozen=True)
class LegDisc:
    """A limit on every leg l of the path (kilometres): ||l - centre|| <= radius, with the
    solver's multipliers ``prices`` (M + 1,), one per leg (see :func:`sca_duality_gap`)."""

    centre: np.ndarray
    radius: float
    prices: np.ndarray


@dataclass(frozen=True)
class PathBudget:
    """A limit on the whole path (kilometres): the sum of its legs' lengths at most
    ``length``, with the solver's multiplier ``price`` (see :func:`sca_duality_gap`)."""

    length: float
    price: float


@dataclass(frozen=True)
class HalfPlanes:
    """Linear rows normals[m, k] . z[m] >= offsets[m, k] on the slot points (kilometres: the
    zones' restriction, :mod:`uav_comm_planner.core.zone_rows`), with the solver's multipliers
    ``prices`` (M, K)."""

    normals: np.ndarray
    offsets: np.ndarray
    prices: np.ndarray


def sca_duality_gap(z: np.ndarray, weights: np.ndarray, discs: Sequence[LegDisc],
                    weight: np.ndarray, constant: np.ndarray, start: np.ndarray,
                    goal: np.ndarray, w: np.ndarray,
                    half_planes: HalfPlanes | None = None,
                    budget: PathBudget | None = None) -> float:
    """An upper bound on how far ``z`` is from the SCA step's optimum, relative to max(1, value).

    The step (kilometres): maximise min_n f_n(z), f_n(z) = constant_n - (1/M) sum_m
    weight_{n,m} ||z[m] - w_n||^2, subject to every leg l of the path start, z[1..M], goal
    keeping ||l - c|| <= r for each disc (c, r) of ``discs``, with ``half_planes`` every
    row a . z[m] >= b, and with ``budget`` sum_l ||l|| <= length. For multipliers lambda (N,)
    >= 0 summing to 1, nu >= 0 per disc and leg, eta >= 0 per row and kappa >= 0 for the
    budget, weak duality bounds the optimum by max_z L(z),
    L = sum_n lambda_n f_n + sum_discs sum_l nu_l (r - ||l - c||) + sum eta (a . z[m] - b)
    + kappa (length - sum_l ||l||).
    L is concave, and strongly
    so in each z[m] with modulus mu_m = (2/M) sum_n lambda_n weight_{n,m}, so
    max_z L <= L(z) + sum_m ||g_m||^2 / (2 mu_m) with g a supergradient of L at z. The gap is
    that bound minus min_n f_n(z); infinite if z breaks a limit (beyond
    :data:`~uav_comm_planner.core.feasibility.LEG_SLACK`).
    """
    m = z.shape[0]
    if not np.all(np.isfinite(z)):
        return math.inf
    legs = np.diff(np.vstack([start, z, goal]), axis=0)
    lam = np.maximum(weights, 0.0)
    if not lam.sum() > 0.0:
        return math.inf
    lam = lam / lam.sum()
    f = constant - (weight * ((z[None] - w[:, None]) ** 2).sum(axis=2)).sum(axis=1) / m
    value = float(f.min())
    lagrangian = float(lam @ f)
    g = -(2.0 / m) * np.einsum('n,nm,nmk->mk', lam, weight, z[None] - w[:, None])
    for disc in discs:
        relative = legs - disc.centre
        length = np.linalg.norm(relative, axis=1)
        if length.max() > disc.radius * (1 + LEG_SLACK):
            return math.inf
        nu = np.maximum(disc.prices, 0.0)
        # Unit vectors of the legs; a leg at the centre has the supergradient 0 of -||.||.
        units = np.divide(relative, length[:, None], out=np.zeros_like(relative),
                          where=length[:, None] > 0.0)
        lagrangian += float(nu @ (disc.radius - length))
        g += -nu[:-1, None] * units[:-1] + nu[1:, None] * units[1:]
    if budget is not None:
        length = np.linalg.norm(legs, axis=1)
        if length.sum() > budget.length * (1 + LEG_SLACK):
            return math.inf
    if half_planes is not None:
        slack = np.einsum('mkj,mj->mk', half_planes.normals, z) - half_planes.offsets
        if slack.size and slack.min() < -LEG_SLACK * max(1.0, float(np.abs(z).max())):
            return math.inf
        eta = np.maximum(half_planes.prices, 0.0)
        lagrangian += float((eta * slack).sum())
        g += np.einsum('mk,mkj->mj', eta, half_planes.normals)
    modulus = (2.0 / m) * (lam @ weight)                                  # (M,)

    def ascent_of(gradient: np.ndarray) -> float:
        squared = (gradient ** 2).sum(axis=1)
        if np.any((modulus <= 0.0) & (squared > 0.0)):
            return math.inf
        return float(np.divide(squared, 2.0 * modulus, out=np.zeros_like(squared),
                               where=modulus > 0.0).sum())

    if budget is None or budget.price <= 0.0:
        return (lagrangian + ascent_of(g) - value) / max(1.0, abs(value))
    # The budget: kappa (length - sum_l ||l||) <= kappa (length - sum_l v_l . l) for any
    # ||v_l|| <= 1, a linear term in z; slot m (between legs m and m + 1) gets
    # kappa (v_{m+1} - v_m) in its supergradient. Choices of v, the best bound kept: the legs'
    # own directions, and the v that zero every slot's supergradient (v_{m+1} = v_m - g_m /
    # kappa, the stationarity the optimum meets, so robust to the round-off in the directions
    # of nearly straight legs) from the first leg's direction, from the last one's, and their
    # mean, each cut to the unit disc.
    kappa = budget.price
    units = np.divide(legs, length[:, None], out=np.zeros_like(legs),
                      where=length[:, None] > 0.0)
    forward = np.vstack([units[:1], units[:1] - np.cumsum(g, axis=0) / kappa])
    backward = forward - forward[-1] + units[-1]
    best = math.inf
    for v in (units, forward, backward, (forward + backward) / 2.0):
        v = v / np.maximum(np.linalg.norm(v, axis=1), 1.0)[:, None]
        bound = (lagrangian + kappa * float(budget.length - (v * legs).sum())
                 + ascent_of(g + kappa * (v[1:] - v[:-1])))
        best = min(best, bound)
    return (best - value) / max(1.0, abs(value))


def path_length_km(q: np.ndarray, scenario: Scenario) -> float:
    """The length of the path q0, q[1..M] (q (M, 2) metres), qF, kilometres."""
    return float(leg_lengths(q, scenario).sum()) / KM


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


def zone_rows_at(q_k: np.ndarray, scenario: Scenario) -> ZoneRows | None:
    """The zones' restriction at the path of q^k (M, 2) metres, None without zones."""
    model = zone_model(scenario.zones)
    if model is None:
        return None
    return model.rows(flown_path(q_k, scenario))


def trajectory_step_cvxpy(q_k: np.ndarray, p: np.ndarray, scenario: Scenario, *,
                          offsets: np.ndarray | None = None, solver: str = 'CLARABEL',
                          keep_path_length: bool = False, **solver_options) -> TrajectoryStep:
    """One SCA step, built afresh as a cvxpy problem (the reference implementation).

    Variables are z = q / 1000 (kilometres) and t (bits per use): maximise t subject to
    o_n + mean_m lbr_{n,m}(z) >= t for every node (o = 0 without ``offsets`` (N,)) and every
    leg within the speed limits (:func:`~uav_comm_planner.core.feasibility.limit_discs`: at
    most V delta, and in wind within V_air delta of the drift), and with zones their
    restriction at q^k (:func:`zone_rows_at`); with ``keep_path_length`` the path start,
    z[1..M], goal no longer than that of q^k (:func:`path_length_km`, held exactly by
    :func:`within_path_budget`). The answer is accepted only
    when its duality gap (:func:`sca_duality_gap`) is at most :data:`CERTIFIED_GAP`; with
    Clarabel, one that is not is solved again with :data:`CLARABEL_RETRY`, then
    :data:`CLARABEL_LAST_RETRY`.
    """
    weight, constant = kilometre_rows(surrogate_coefficients(q_k, p, scenario))
    constant = with_offsets(constant, offsets)
    m = scenario.num_slots
    w = scenario.nodes / KM
    start = np.reshape(scenario.start_m, (1, 2)) / KM
    goal = np.reshape(scenario.goal_m, (1, 2)) / KM
    limits = [(centre / KM, radius / KM) for centre, radius in limit_discs(scenario)]

    z = cp.Variable((m, 2))
    t = cp.Variable()
    path = cp.vstack([start, z, goal])
    legs = path[1:] - path[:-1]
    constraints = [cp.norm(legs - centre[None, :], 2, axis=1) <= radius
                   for centre, radius in limits]
    for n in range(scenario.num_nodes):
        spread = cp.sum(cp.square(z - w[n][None, :]), axis=1)
        constraints.append(constant[n] - weight[n] @ spread / m >= t)
    rows = zone_rows_at(q_k, scenario)
    zone_constraints = [] if rows is None else [
        cp.sum(cp.multiply(rows.normals[:, k, :], z), axis=1) >= rows.offsets[:, k] / KM
        for k in range(rows.offsets.shape[1])]
    budget = path_length_km(q_k, scenario) if keep_path_length else None
    budget_constraints = [] if budget is None else [
        cp.sum(cp.norm(legs, 2, axis=1)) <= budget]
    problem = cp.Problem(cp.Maximize(t), constraints + zone_constraints + budget_constraints)

    def certify() -> Certificate:
        weights = np.array([float(c.dual_value) for c in
                            constraints[len(limits):len(limits) + scenario.num_nodes]])
        discs = [LegDisc(centre, radius, np.asarray(c.dual_value, dtype=float).reshape(-1))
                 for (centre, radius), c in zip(limits, constraints)]
        half_planes = None if rows is None else HalfPlanes(
            rows.normals, rows.offsets / KM,
            np.stack([np.asarray(c.dual_value, dtype=float).reshape(-1)
                      for c in zone_constraints], axis=1))
        path_budget = None if budget is None else PathBudget(
            budget, float(budget_constraints[0].dual_value))
        gap = sca_duality_gap(np.asarray(z.value), weights, discs, weight, constant, start,
                              goal, w, half_planes, path_budget)
        return Certificate(gap, CERTIFIED_GAP)

    bases = [{}, CLARABEL_RETRY, CLARABEL_LAST_RETRY] if solver == 'CLARABEL' else [{}]
    solve_checked(problem, 'trajectory step', solver,
                  [dict(base, **solver_options) for base in bases], certify)
    q = np.asarray(z.value) * KM
    if budget is not None:
        q = within_path_budget(q, q_k, scenario, budget)
    return TrajectoryStep(q=q, bound_of=lambda: with_offsets(
        sca_lower_bound(q, q_k, p, scenario).mean(axis=1), offsets).min())
