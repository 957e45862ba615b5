"""The fleet's power step: the max-min power of K UAVs on fixed trajectories.

Given a (K, N, M), find p (K, N, M) >= 0 with sum_{n,m} p_{k,n}[m] <= P_T for every UAV k (each
its own budget) that maximises min_n sum_k mean_m log2(1 + p_{k,n}[m] a_{k,n}[m]): concave in
p, so a convex problem; two solvers:

* :func:`joint_power` (exact): the exponential-cone program, written as the single UAV's
  :func:`~uav_comm_planner.core.power.conic_power` is (shares of the budget, log(x + b)), and
  accepted only on a Lagrangian duality gap (:func:`fleet_dual_bound`) below
  :data:`~uav_comm_planner.core.power.CERTIFIED_GAP`;
* :func:`coordinate_power` (fast): UAV by UAV, the letter's exact water-filling with the other
  UAVs' efficiencies as each node's offset (:func:`~uav_comm_planner.core.power.
  waterfilling_power`), swept until a sweep gains no more than a tolerance. Every sub-step
  solves its block exactly from a feasible point, so the value never decreases; the max-min
  is not smooth, so a sweep can stop short of the joint optimum (two UAVs could each trade a
  node's power with the other), which :func:`joint_power` reaches.
"""

from __future__ import annotations

import math

import cvxpy as cp
import numpy as np

from uav_comm_planner.core.conic import Certificate, solve_checked
from uav_comm_planner.core.fleet.model import fleet_efficiencies
from uav_comm_planner.core.power import (CERTIFIED_GAP, CLARABEL_RETRY, CLARABEL_TIGHT,
                                         power_dual_bound, PowerAllocation, waterfilling_power)
from uav_comm_planner.errors import SolverError

#: Sweeps of :func:`coordinate_power` at most.
MAX_SWEEPS = 200
_ONE_ULP_BELOW_ONE = float(np.nextafter(1.0, 0.0))


def _checked(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim != 3 or a.size == 0 or not (a.min() > 0.0 and a.max() < math.inf):
        raise SolverError('the fleet power step needs a finite, positive SNR-per-watt array '
                          '(K, N, M)')
    return a


def within_budgets(p: np.ndarray, power_budget_w: float) -> np.ndarray:
    """p (K, N, M) clipped at 0 and, per UAV, scaled down until its total is at most P_T
    exactly (round-off of a solver, or of the scaling itself)."""
    p = np.maximum(np.asarray(p, dtype=float), 0.0)
    for p_k in p:
        total = float(p_k.sum())
        if total > power_budget_w:
            p_k *= power_budget_w / total
            while float(p_k.sum()) > power_budget_w:
                p_k *= _ONE_ULP_BELOW_ONE
    return p


def common_value(a: np.ndarray, p: np.ndarray) -> float:
    """min_n sum_k mean_m log2(1 + p a), bits per use."""
    return float(fleet_efficiencies(a, p).sum(axis=0).min())


def fleet_dual_bound(a: np.ndarray, power_budget_w: float, weights: np.ndarray,
                     prices: np.ndarray) -> float:
    """An upper bound on the max-min value (bits per use) from node weights lambda (N,) >= 0
    and per-UAV prices nu (K,) > 0: by weak duality the optimum is at most
    sum_k [nu_k P_T + sum_{n,m} max_{p >= 0} (lambda_n / M log2(1 + a_{k,n}[m] p) - nu_k p)]
    (lambda normalised to sum to 1), which is the single UAV's bound summed over the UAVs
    (:func:`~uav_comm_planner.core.power.power_dual_bound`)."""
    return float(sum(power_dual_bound(a_k, power_budget_w, weights, float(nu))
                     for a_k, nu in zip(a, prices)))


def joint_power(a: np.ndarray, power_budget_w: float, *,
                solver: str = 'CLARABEL') -> PowerAllocation:
    """The exact max-min power p (K, N, M) for a (K, N, M) and budget P_T per UAV.

    With x_k = p_k / P_T and b = 1 / (P_T a), log2(1 + p a) = log2(P_T a) + log2(x + b), so the
    cones see log(x + b) with x in [0, 1] (module docstring). Raises :class:`SolverError` when
    no answer is certified.
    """
    a = _checked(a)
    k, n, m = a.shape
    b = 1.0 / (power_budget_w * a)
    offset = np.log(power_budget_w * a).mean(axis=2).sum(axis=0)          # (N,)
    x = [cp.Variable((n, m), nonneg=True) for _ in range(k)]
    t = cp.Variable()
    budgets = [cp.sum(x_k) <= 1.0 for x_k in x]
    nodes = (sum(cp.sum(cp.log(x_k + b_k), axis=1) for x_k, b_k in zip(x, b)) / m + offset
             >= LN2 * t)
    problem = cp.Problem(cp.Maximize(t), budgets + [nodes])
    answer: list[PowerAllocation] = []

    def certify() -> Certificate:
        p = within_budgets(power_budget_w * np.stack([x_k.value for x_k in x]), power_budget_w)
        value = common_value(a, p)
        answer[:] = [PowerAllocation(p=p, efficiency=value)]
        weights = LN2 * np.asarray(nodes.dual_value, dtype=float)
        prices = np.array([float(c.dual_value) for c in budgets]) / power_budget_w
        bound = fleet_dual_bound(a, power_budget_w, weights, prices)
        return Certificate((bound - value) / max(1.0, abs(value)), CERTIFIED_GAP)

    bases = [CLARABEL_TIGHT, CLARABEL_RETRY] if solver == 'CLARABEL' else [{}]
    solve_checked(problem, 'fleet power step', solver, bases, certify)
    return answer[0]


def coordinate_power(a: np.ndarray, power_budget_w: float, *, p: np.ndarray | None = None,
                     tolerance: float = 1e-9) -> PowerAllocation:
    """Max-min power by exact water-filling UAV by UAV (module docstring), from p (K, N, M)
    watts (None: no power yet); stops when a sweep gains at most ``tolerance`` times
    max(1, value) bits per use."""
    a = _checked(a)
    p = np.zeros_like(a) if p is None else within_budgets(p, power_budget_w)
    value = common_value(a, p)
    for _ in range(MAX_SWEEPS):
        before = value
        for k in range(a.shape[0]):
            own = fleet_efficiencies(a, p)
            offsets = own.sum(axis=0) - own[k]
            allocation = waterfilling_power(a[k], power_budget_w, offsets=offsets)
            if allocation.efficiency >= value:
                p[k] = allocation.p
                value = allocation.efficiency
        if value - before <= tolerance * max(1.0, abs(value)):
            break
    return PowerAllocation(p=p, efficiency=common_value(a, p))


LN2 = math.log(2.0)

POWER_METHODS = {'joint': joint_power, 'coordinate': coordinate_power}

__all__ = ['common_value', 'coordinate_power', 'fleet_dual_bound', 'joint_power',
           'POWER_METHODS', 'within_budgets']
