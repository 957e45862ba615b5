"""Power step (letter, problem (6)): the max-min power allocation on a fixed trajectory.

Given a_n[m] (SNR per watt), find p_n[m] >= 0 with sum p <= P_T that maximises the common
rate. Two exact solvers, which must agree:

* :func:`waterfilling_power`: for a target spectral efficiency c (bits per channel use),
  node n's least power is the water-filling p_n[m] = (mu_n - 1/a_n[m])^+ with mu_n set so
  that mean_m log2(1 + p_n[m] a_n[m]) = c. The total power P(c) is increasing and convex in
  c, with dP/dc = M ln 2 sum_n mu_n, so Newton's method from above finds P(c) = P_T. When
  every slot is active at the optimum (the usual case at high SNR) the levels have a closed
  form, tried first.
* :func:`conic_power`: the same problem as an exponential-cone program (cvxpy + Clarabel).

Both take optional offsets o_n (N,) bits per use, the data a node already holds (the receding
horizon, :mod:`uav_comm_planner.core.receding`): they then maximise the common value
c = min_n (o_n + mean_m log2(1 + p_n[m] a_n[m])), where node n needs only the efficiency
(c - o_n)^+ from this schedule. Without offsets (or with all zero) the problem and the code
path are exactly the letter's.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import cvxpy as cp
import numpy as np

from uav_comm_planner.core.conic import Certificate, solve_checked
from uav_comm_planner.core.model import LN2, spectral_efficiencies
from uav_comm_planner.errors import SolverError

_NEWTON_MAX_STEPS = 200
#: The largest double below 1: multiplying by it lowers a positive number by one ulp or less.
_ONE_ULP_BELOW_ONE = float(np.nextafter(1.0, 0.0))

#: Clarabel's defaults stop at a 1e-8 gap; the tighter ones cost little here and let the
#: conic answers agree with the exact water-filling well below 1e-6.
CLARABEL_TIGHT = dict(tol_gap_abs=1e-10, tol_gap_rel=1e-10, tol_feas=1e-10, tol_ktratio=1e-8)
#: Tried when the tight settings stop short. A 1e-10 gap is at the floor of what Clarabel's
#: exponential cones reach when the optimum leaves a node without power: that node's constraint
#: is slack, its log terms' epigraph variables lie anywhere on a face of the cone, and the gap
#: can stall just above 1e-10 (1.03e-10 on a seeded case with offsets). 1e-9 is reached there.
CLARABEL_RETRY = dict(tol_gap_abs=1e-9, tol_gap_rel=1e-9, tol_feas=1e-9, tol_ktratio=1e-7,
                      max_iter=400)
#: A conic power step is accepted when its Lagrangian duality gap
#: (:func:`power_dual_bound` minus the value reached) is at most this share of max(1, value).
CERTIFIED_GAP = 1e-8


@dataclass(frozen=True)
class PowerAllocation:
    """p: (N, M) watts; efficiency: the common min_n (o_n + mean_m log2(1 + p a)) reached,
    bits per use (o = 0 without offsets)."""

    p: np.ndarray
    efficiency: float


def _within_budget(p: np.ndarray, a: np.ndarray, power_budget_w: float,
                   offsets: np.ndarray | None = None) -> PowerAllocation:
    """p >= 0 (N, M), scaled down in place if round-off put its total above the budget, with
    the efficiency it reaches for SNR per watt a (plus the offsets o (N,), if any).

    The scaling itself rounds, so p is lowered a ulp at a time until sum(p) <= P_T holds
    exactly (once or twice at most).
    """
    total = float(p.sum())
    if total > power_budget_w:
        p *= power_budget_w / total
        for _ in range(64):
            if float(p.sum()) <= power_budget_w:
                break
            p *= _ONE_ULP_BELOW_ONE
    return PowerAllocation(p=p, efficiency=float(spectral_efficiencies(a, p, offsets).min()))


def has_offsets(offsets: np.ndarray | None) -> bool:
    """Whether ``offsets`` change the problem (None and all zero do not)."""
    return offsets is not None and bool(np.any(np.asarray(offsets, dtype=float) != 0.0))


def checked_offsets(offsets: np.ndarray | None, num_nodes: int) -> np.ndarray | None:
    """The offsets as a finite (N,) array, or None when they do not change the problem."""
    if not has_offsets(offsets):
        return None
    offsets = np.asarray(offsets, dtype=float).reshape(-1)
    if offsets.shape != (num_nodes,) or not np.all(np.isfinite(offsets)):
        raise SolverError(f'offsets must be {num_nodes} finite values (bits per use), one per '
                          f'node, got {offsets.shape[0]}')
    return offsets


class _WaterLevels:
    """Per-node minimum power as a function of the common target c, for fixed a (N, M).

    Written for precision at low SNR, where mu_n is within a few ulps of 1/a_n[m]: with the
    slots of node n sorted best first and r_i = log2(a_i / a_1) <= 0 (exact near 0), the
    exponent u_i = log2(mu_n a_i) = M c / k + r_i - (1/k) sum_{j<=k} r_j for k active slots,
    and node n's power is sum_{i<=k} expm1(u_i ln 2) / a_i, free of cancellation.
    """

    def __init__(self, a: np.ndarray):
        self.a = a
        self.num_slots = a.shape[1]
        self._rows = np.arange(a.shape[0])
        best_first = np.sort(a, axis=1)[:, ::-1]
        self.best_first = best_first
        self.worst_best = float(best_first[:, 0].min())          # min_n max_m a_n[m]
        log_a = np.log2(best_first)
        self.log_sum = np.cumsum(log_a, axis=1)                   # S_k
        self.inv_sum = np.cumsum(1.0 / best_first, axis=1)        # sum_{i<=k} 1/a_i
        self.relative = np.log2(best_first / best_first[:, :1])   # r_i
        self.relative_sum = np.cumsum(self.relative, axis=1)      # R_k
        # k slots are active at target c iff M c >= R_k - k r_k (nondecreasing in k, R_1 = 0).
        self.threshold = self.relative_sum - np.arange(1, self.num_slots + 1) * self.relative

    def shifts(self, c: float | np.ndarray) -> np.ndarray:
        """log2(mu_n a_n,best) (N,) at target c (one for all nodes, or (N,) one per node):
        the exponent of each node's best slot."""
        targets = np.reshape(c, (-1, 1)) if np.ndim(c) else c
        active = np.count_nonzero(self.threshold <= self.num_slots * targets, axis=1)
        return (self.num_slots * c - self.relative_sum[self._rows, active - 1]) / active

    def levels(self, c: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Water level mu_n (N,) and node power P_n(c) (N,) for target c >= 0, one for all
        nodes or (N,) one per node."""
        exponents = self.shifts(c)[:, None] + self.relative
        np.maximum(exponents, 0.0, out=exponents)               # inactive slots: no power
        node_power = (np.expm1(LN2 * exponents) / self.best_first).sum(axis=1)
        return np.exp2(exponents[:, 0]) / self.best_first[:, 0], node_power

    def power(self, c: float) -> np.ndarray:
        """p (N, M) watts in the slots' own order at target c: (mu_n - 1/a_n[m])^+."""
        exponents = self.shifts(c)[:, None] + np.log2(self.a / self.best_first[:, :1])
        np.maximum(exponents, 0.0, out=exponents)
        return np.expm1(LN2 * exponents) / self.a

    def start(self, power_budget_w: float) -> float:
        """A target c at or above the root of P(c) = P_T, and at it when every slot is active.

        Two upper bounds, the smaller is kept. Jensen: no node exceeds
        log2(1 + P_T max_m a_n[m] / M) even with the whole budget. All slots active: dropping
        p >= 0 can only lower each node's least power, to M mu_n - sum_m 1/a_n[m] with
        log2 mu_n = c - mean_m log2 a_n[m]; setting their sum to P_T gives
        c = log2(P_T + sum_{n,m} 1/a_n[m]) - log2(M sum_n 2^(-mean_m log2 a_n[m])),
        exact at high SNR, where Newton's method then stops at once.
        """
        m = self.num_slots
        jensen = math.log1p(power_budget_w * self.worst_best / m) / LN2
        mean_log = self.log_sum[:, -1] / m
        lowest = mean_log.min()
        all_active = (math.log2(power_budget_w + self.inv_sum[:, -1].sum()) - math.log2(m)
                      + lowest - math.log2(np.exp2(lowest - mean_log).sum()))
        return min(jensen, all_active)


#: The closed form of the all-active levels subtracts 1/a from mu; it is used only while
#: P_T is at least this share of sum 1/a, so that p keeps all but three of its digits.
_CLOSED_FORM_LEAST_SHARE = 1e-3


def _levels_if_all_active(a: np.ndarray, inv_a: np.ndarray,
                          power_budget_w: float) -> np.ndarray | None:
    """The water levels mu (N,) of the optimum if every slot of every node is active in it.

    With every slot active, node n's power is M mu_n - sum_m 1/a_n[m] and its efficiency
    log2 mu_n + mean_m log2 a_n[m]; equal efficiencies make mu_n proportional to 1/G_n (G_n the
    geometric mean of a_n), and the budget fixes the factor:
    mu_n = (P_T + sum_{n,m} 1/a_n[m]) / M * (1/G_n) / sum_k (1/G_k). That is the optimum exactly
    when every slot is then active, mu_n >= 1/a_n[m]; otherwise None. The usual case at high
    SNR, where it spares the sort and Newton's method.
    """
    mu = _all_active_levels(a, inv_a, power_budget_w)
    return mu if (mu * a.min(axis=1)).min() >= 1.0 else None


def _all_active_levels(a: np.ndarray, inv_a: np.ndarray, power_budget_w: float) -> np.ndarray:
    """The levels mu (..., N) of :func:`_levels_if_all_active` for a (..., N, M) (one
    problem or a stack of them), whether or not every slot is then active."""
    mean_log = np.log2(a).sum(axis=-1) / a.shape[-1]
    inverse_g = np.exp2(mean_log.min(axis=-1, keepdims=True) - mean_log)  # G_min / G_n
    total = power_budget_w + inv_a.sum(axis=(-2, -1))
    return (total / (a.shape[-1] * inverse_g.sum(axis=-1)))[..., None] * inverse_g


def _newton_target(a: np.ndarray, power_budget_w: float) -> tuple[_WaterLevels, float]:
    """The common target c of the optimum, by Newton's method on P(c) = P_T.

    P is convex and increasing, so from a start above the root (:meth:`_WaterLevels.start`)
    the iterates decrease monotonically to it; a start a few ulps below the root (round-off)
    is followed by one step above it. It stops when P(c) is within 1e-13 of P_T or the step
    is below 1e-15 of c, so the whole budget is assigned.
    """
    water = _WaterLevels(a)
    newton_scale = a.shape[1] * LN2
    c = max(water.start(power_budget_w), 0.0)
    for _ in range(_NEWTON_MAX_STEPS):
        mu, node_power = water.levels(c)
        excess = float(node_power.sum()) - power_budget_w
        step = excess / (newton_scale * float(mu.sum()))
        if abs(excess) <= 1e-13 * power_budget_w or abs(step) <= 1e-15 * c:
            return water, c
        c = max(c - step, 0.0)
    raise SolverError('water-filling did not converge; check that a (SNR per watt) is sane')


def _newton_levels(a: np.ndarray, power_budget_w: float) -> np.ndarray:
    """The water levels mu (N,) of the optimum, by Newton's method (:func:`_newton_target`)."""
    water, c = _newton_target(a, power_budget_w)
    return water.levels(c)[0]


def _offset_levels_if_all_active(a: np.ndarray, inv_a: np.ndarray, power_budget_w: float,
                                 offsets: np.ndarray) -> np.ndarray | None:
    """:func:`_levels_if_all_active` with offsets: with every slot of every node active,
    log2 mu_n = c - o_n - mean_m log2 a_n[m] and the budget gives
    c = log2(P_T + sum_{n,m} 1/a_n[m]) - log2(M sum_n 2^(-o_n - mean_m log2 a_n[m])).
    The optimum when then every node needs data (c >= o_n) and every slot is active."""
    exponent = -offsets - np.log2(a).sum(axis=1) / a.shape[1]
    top = exponent.max()
    c = (math.log2(power_budget_w + inv_a.sum()) - math.log2(a.shape[1]) - top
         - math.log2(np.exp2(exponent - top).sum()))
    mu = np.exp2(c + exponent)
    if np.all(c >= offsets) and (mu * a.min(axis=1)).min() >= 1.0:
        return mu
    return None


def _offset_newton_levels(a: np.ndarray, power_budget_w: float,
                          offsets: np.ndarray) -> np.ndarray:
    """The water levels mu (N,) of the optimum with offsets o (N,), by Newton's method.

    Node n's target is (c - o_n)^+, so the total power P(c) = sum_n P_n((c - o_n)^+) is still
    convex and increasing, with slope M ln 2 sum_{n: c > o_n} mu_n, and Newton's method from
    above converges monotonically. The start is above the root: no node gets more than
    log2(1 + P_T max_m a_n[m] / M) from the whole budget (Jensen), so
    c <= min_n (o_n + log2(1 + P_T max_m a_n[m] / M)); and the all-active relaxation (no
    p >= 0, targets c - o_n of any sign) needs less power than P at every c.
    """
    water = _WaterLevels(a)
    m = a.shape[1]
    newton_scale = m * math.log(2.0)
    best = np.exp2(water.log_sum[:, 0])                    # max_m a_n[m]
    jensen = float((offsets + np.log2(1.0 + power_budget_w * best / m)).min())
    exponent = -offsets - water.log_sum[:, -1] / m
    top = exponent.max()
    relaxed = (math.log2(power_budget_w + water.inv_sum[:, -1].sum()) - math.log2(m) - top
               - math.log2(np.exp2(exponent - top).sum()))
    c = max(min(jensen, relaxed), float(offsets.min()))
    for _ in range(_NEWTON_MAX_STEPS):
        needing = c > offsets
        mu, node_power = water.levels(np.maximum(c - offsets, 0.0))
        mu[~needing] = 0.0                 # no power at all, not 1/max_m a_n[m] +- round-off
        excess = float(node_power.sum()) - power_budget_w
        slope = newton_scale * float(mu[needing].sum())
        if excess <= 1e-13 * max(power_budget_w, 1e-300) or slope == 0.0:
            return mu
        step = excess / slope
        if step <= 1e-15 * max(abs(c), 1.0):
            return mu
        c = max(c - step, float(offsets.min()))
    raise SolverError('water-filling did not converge; check that a (SNR per watt) is sane')


def waterfilling_power(a: np.ndarray, power_budget_w: float, *,
                       offsets: np.ndarray | None = None) -> PowerAllocation:
    """Exact max-min power for SNR per watt ``a`` (N, M) and budget P_T, by water-filling:
    in closed form when every slot is active (and P_T is not negligible against sum 1/a),
    else by Newton's method on the target.

    ``offsets`` o (N,), bits per use: maximise min_n (o_n + mean_m log2(1 + p_n[m] a_n[m]));
    a node with o_n above the common value gets no power.
    """
    a = np.asarray(a, dtype=float)
    # min > 0 and max < inf fail for NaN too.
    if a.ndim != 2 or a.size == 0 or not (a.min() > 0.0 and a.max() < math.inf):
        raise SolverError('water-filling needs a finite, positive SNR-per-watt array (N, M)')
    offsets = checked_offsets(offsets, a.shape[0])
    inv_a = 1.0 / a
    if offsets is None:
        mu = None
        if power_budget_w >= _CLOSED_FORM_LEAST_SHARE * inv_a.sum():
            mu = _levels_if_all_active(a, inv_a, power_budget_w)
        if mu is None:
            water, c = _newton_target(a, power_budget_w)
            return _within_budget(water.power(c), a, power_budget_w)
    else:
        mu = _offset_levels_if_all_active(a, inv_a, power_budget_w, offsets)
        if mu is None:
            mu = _offset_newton_levels(a, power_budget_w, offsets)
    p = mu[:, None] - inv_a
    np.maximum(p, 0.0, out=p)
    return _within_budget(p, a, power_budget_w, offsets)


def waterfilling_powers(a: np.ndarray, power_budget_w: float) -> list[PowerAllocation]:
    """:func:`waterfilling_power` (no offsets) for a stack of problems a (K, N, M): the
    closed form worked out for all K at once, the one-at-a-time step only for those where it
    does not apply; for screening many trajectories, where the step's fixed cost per call
    is most of its cost."""
    a = np.asarray(a, dtype=float)
    if a.ndim != 3 or a.size == 0 or not (a.min() > 0.0 and a.max() < math.inf):
        raise SolverError('water-filling needs finite, positive SNR-per-watt arrays (K, N, M)')
    inv_a = 1.0 / a
    mu = _all_active_levels(a, inv_a, power_budget_w)
    closed = (((mu * a.min(axis=-1)).min(axis=-1) >= 1.0)
              & (power_budget_w >= _CLOSED_FORM_LEAST_SHARE * inv_a.sum(axis=(-2, -1))))
    p = mu[..., None] - inv_a
    np.maximum(p, 0.0, out=p)
    within = p.sum(axis=(-2, -1)) <= power_budget_w
    efficiency = spectral_efficiencies(a, p).min(axis=-1)
    return [(PowerAllocation(p=p[k], efficiency=float(efficiency[k])) if within[k] else
             _within_budget(p[k], a[k], power_budget_w)) if closed[k] else
            waterfilling_power(a[k], power_budget_w) for k in range(len(a))]


def power_dual_bound(a: np.ndarray, power_budget_w: float, weights: np.ndarray, nu: float, *,
                     offsets: np.ndarray | None = None) -> float:
    """An upper bound on the max-min value (bits per use) from Lagrange multipliers.

    For node weights lambda (N,) >= 0 summing to 1 and a price nu > 0 per watt, weak duality
    gives max_{p >= 0} min_n (o_n + mean_m log2(1 + p a)) subject to sum p <= P_T at most
    g = sum_n lambda_n o_n + nu P_T + sum_{n,m} max_{p >= 0} [lambda_n / M log2(1 + a p) - nu p],
    where each inner maximum is at p = (lambda_n / (M nu ln 2) - 1/a)^+. Any multipliers give a
    bound; the optimum's give the optimum, so it certifies an answer independently of how
    the answer was found.
    """
    a = np.asarray(a, dtype=float)
    weights = np.maximum(np.asarray(weights, dtype=float).reshape(-1), 0.0)
    if not (nu > 0.0 and weights.sum() > 0.0 and np.all(np.isfinite(weights))):
        return math.inf
    weights = weights / weights.sum()
    m = a.shape[1]
    share = (weights / (m * LN2 * nu))[:, None]
    p = np.maximum(share - 1.0 / a, 0.0)
    inner = weights[:, None] / m * (np.log1p(a * p) / LN2) - nu * p
    value = nu * power_budget_w + float(inner.sum())
    if offsets is not None:
        value += float(weights @ offsets)
    return value


def conic_power(a: np.ndarray, power_budget_w: float, *, offsets: np.ndarray | None = None,
                solver: str = 'CLARABEL', **solver_options) -> PowerAllocation:
    """Exact max-min power for ``a`` (N, M) as an exponential-cone program.

    Written for conditioning: with x = p / P_T (a share of the budget) and b = 1 / (P_T a),
    log2(1 + p a) = log2(P_T a) + log2(x + b), so the cone sees log(x + b) with x in [0, 1]
    instead of log(1 + a p) with a around 1e13. ``offsets`` o (N,) bits per use are added to
    each node's mean: t <= o_n + mean_m log2(1 + p_n[m] a_n[m]).

    The answer is accepted only when its duality gap (:func:`power_dual_bound` at the solver's
    multipliers) is at most :data:`CERTIFIED_GAP`; with Clarabel, an answer that is not is
    solved again with :data:`CLARABEL_RETRY`. Raises :class:`SolverError` otherwise.
    """
    a = np.asarray(a, dtype=float)
    n, m = a.shape
    offsets = checked_offsets(offsets, n)
    b = 1.0 / (power_budget_w * a)
    offset = np.log(power_budget_w * a).mean(axis=1)
    if offsets is not None:
        offset = offset + math.log(2.0) * offsets
    x = cp.Variable((n, m), nonneg=True)
    t = cp.Variable()
    constraints = [cp.sum(x) <= 1.0,
                   cp.sum(cp.log(x + b), axis=1) / m + offset >= math.log(2.0) * t]
    problem = cp.Problem(cp.Maximize(t), constraints)
    bases = [CLARABEL_TIGHT, CLARABEL_RETRY] if solver == 'CLARABEL' else [{}]
    attempts = [dict(base, **solver_options) for base in bases]
    answer: list[PowerAllocation] = []

    def certify() -> Certificate:
        allocation = _within_budget(power_budget_w * np.maximum(x.value, 0.0), a,
                                    power_budget_w, offsets)
        answer[:] = [allocation]
        # The multipliers in bits and watts: the node rows are written in nats, the budget
        # in shares of P_T.
        weights = LN2 * np.asarray(constraints[1].dual_value, dtype=float)
        nu = float(constraints[0].dual_value) / power_budget_w
        bound = power_dual_bound(a, power_budget_w, weights, nu, offsets=offsets)
        scale = max(1.0, abs(allocation.efficiency))
        return Certificate((bound - allocation.efficiency) / scale, CERTIFIED_GAP)

    solve_checked(problem, 'power step', solver, attempts, certify)
    return answer[0]
