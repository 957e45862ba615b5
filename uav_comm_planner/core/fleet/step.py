"""The fleet's SCA trajectory step: every UAV's trajectory at once, t below every node's bound.

Each UAV k's part is the single UAV's, from its blocks (:mod:`uav_comm_planner.core.sca`): the
node-rate block's bound at q_k^k with power p_k (:meth:`~uav_comm_planner.core.sca.rates.
NodeRates.at`), mean_m lbr_{k,n,m}(z_k) = C_{k,n} - (1/M) sum_m W_{k,n,m} ||z_k[m] - w_n||^2,
and the leg block's speed limits (:class:`~uav_comm_planner.core.sca.legs.LegLimits`); node n's
throughput is the sum over the UAVs, so the rate rows are

    t <= sum_k [C_{k,n} - (1/M) sum_m W_{k,n,m} (u_k[m] - 2 w_n . z_k[m] + ||w_n||^2)],

with u_k[m] >= ||z_k[m]||^2 (exact at an optimum, as in the node-rate block), plus the
separation rows (:mod:`.separation`). Each bound is global and tight at q^k, and q^k keeps every
row, so the step never lowers the true minimum throughput. The problem is built once per fleet
with cvxpy parameters (W, C, the separation's directions) and solved again at every step.
Positions are in kilometres about one centre for all UAVs (:class:`~uav_comm_planner.core.sca.
block.Frame`).
"""

from __future__ import annotations

import warnings

import cvxpy as cp
import numpy as np

from uav_comm_planner.core.feasibility import project_onto_speed_limit
from uav_comm_planner.core.fleet.scenario import FleetScenario
from uav_comm_planner.core.fleet.separation import (keeps_separation, SEPARATION_CUSHION_M,
                                                    separation_rows)
from uav_comm_planner.core.sca.block import Expansion, Frame, Variables
from uav_comm_planner.core.sca.legs import LegLimits
from uav_comm_planner.core.sca.rates import NodeRates
from uav_comm_planner.core.sca.surrogate import KM
from uav_comm_planner.errors import SolverError

_USABLE = (cp.OPTIMAL, cp.OPTIMAL_INACCURATE)


def fleet_frames(fleet: FleetScenario) -> list[Frame]:
    """One frame per UAV, all about the centre of the box around the nodes and every end."""
    corners = np.vstack([fleet.scenario.nodes, fleet.starts_m, fleet.goals_m])
    centre = (corners.min(axis=0) + corners.max(axis=0)) / 2.0
    return [Frame(vehicle, centre) for vehicle in fleet.vehicles]


class FleetStep:
    """The step for one fleet (module docstring); call it with q (K, M, 2) metres and p
    (K, N, M) watts for the next q (K, M, 2) metres, or None when the solver's answer does not
    keep the separation or does not beat the solver's round-off (the caller keeps q)."""

    def __init__(self, fleet: FleetScenario, *, solver: str = 'CLARABEL'):
        self.fleet, self.solver = fleet, solver
        self.frames = fleet_frames(fleet)
        self.rates = [NodeRates(frame, partial_sums=False) for frame in self.frames]
        n, m = fleet.scenario.num_nodes, fleet.scenario.num_slots
        w = self.frames[0].nodes
        self._w_squared = (w ** 2).sum(axis=1)
        self.t = cp.Variable()
        self.z = [cp.Variable((m, 2)) for _ in self.frames]
        u = [cp.Variable(m) for _ in self.frames]
        self.weight = [cp.Parameter((n, m), nonneg=True) for _ in self.frames]
        self.constant = [cp.Parameter(n) for _ in self.frames]
        bound = sum(c - (W @ u_k - 2.0 * cp.multiply(W @ z_k[:, 0], w[:, 0])
                         - 2.0 * cp.multiply(W @ z_k[:, 1], w[:, 1])) / m
                    for c, W, z_k, u_k in zip(self.constant, self.weight, self.z, u))
        constraints = [bound >= self.t]
        for frame, z_k, u_k in zip(self.frames, self.z, u):
            constraints.append(cp.sum(cp.square(z_k), axis=1) <= u_k)
            path = cp.vstack([frame.start[None, :], z_k, frame.goal[None, :]])
            legs = LegLimits(frame)
            constraints += legs.constraints(Variables(z_k, self.t, path[1:] - path[:-1]), None)
        self.direction = [cp.Parameter((m, 2)) for _ in fleet.pairs]
        for (j, k), a in zip(fleet.pairs, self.direction):
            constraints.append(cp.sum(cp.multiply(a, self.z[j] - self.z[k]), axis=1)
                               >= (fleet.min_separation_m + SEPARATION_CUSHION_M) / KM)
        self.problem = cp.Problem(cp.Maximize(self.t), constraints)

    def _set(self, q: np.ndarray, p: np.ndarray) -> None:
        m = self.fleet.scenario.num_slots
        for rates, q_k, p_k, weight, constant in zip(self.rates, q, p, self.weight,
                                                     self.constant):
            rows = rates.at(Expansion(q_k, p_k))
            weight.value = rows.weight
            constant.value = rows.constant - self._w_squared * rows.weight.sum(axis=1) / m
        z = np.stack([frame.km(q_k) for frame, q_k in zip(self.frames, q)])
        rows = separation_rows(z, self.fleet, scale=KM)
        for a, direction in zip(self.direction, rows.direction):
            a.value = direction

    def __call__(self, q: np.ndarray, p: np.ndarray) -> np.ndarray | None:
        self._set(np.asarray(q, dtype=float), np.asarray(p, dtype=float))
        try:
            with warnings.catch_warnings():
                warnings.filterwarnings('ignore', message='Solution may be inaccurate')
                self.problem.solve(solver=self.solver)
        except cp.error.SolverError as exc:
            raise SolverError(f'fleet trajectory step: {self.solver} failed ({exc})') from exc
        if self.problem.status not in _USABLE:
            raise SolverError(f'fleet trajectory step: {self.solver} returned status '
                              f'{self.problem.status!r}')
        q_new = np.stack([project_onto_speed_limit(frame.metres(z_k.value), frame.scenario)
                          for frame, z_k in zip(self.frames, self.z)])
        return q_new if keeps_separation(q_new, self.fleet) else None


__all__ = ['fleet_frames', 'FleetStep']
