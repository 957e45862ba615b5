"""The fleet's SCA trajectory step: every UAV's trajectory at once, t below every node's bound.

Each UAV k's part is the single UAV's, from its blocks (:mod:`uav_comm_planner.core.sca`): the
node-rate block's bound at q_k^k with power p_k (:meth:`~uav_comm_planner.core.sca.rates.
NodeRates.at`), mean_m lbr_{k,n,m}(z_k) = C_{k,n} - (1/M) sum_m W_{k,n,m} ||z_k[m] - w_n||^2,
and the leg block's speed limits (:class:`~uav_comm_planner.core.sca.legs.LegLimits`); node n's
throughput is the sum over the UAVs, so the rate rows are

    t <= sum_k [C_{k,n} - (1/M) sum_m W_{k,n,m} (u_k[m] - 2 w_n . z_k[m] + ||w_n||^2)],

with u_k[m] >= ||z_k[m]||^2 (exact at an optimum, as in the node-rate block), plus the
separation rows (:mod:`.separation`). Each bound is global and tight at q^k, and q^k keeps every
row, so the step never lowers the true minimum throughput. Positions are in kilometres about
one centre for all UAVs (:class:`~uav_comm_planner.core.sca.block.Frame`).

Two solvers of the same step, which must agree: :func:`step_clarabel` (the default) writes the
cone program s = b - A x for Clarabel directly, x = (t, then per UAV z_k (2 M) and u_k (M)),
with each UAV's node-rate coefficients (:meth:`NodeRates.update`) and leg cones
(:meth:`LegLimits.pattern`) placed in its columns; :func:`step_cvxpy` (the reference) states
the same constraints in cvxpy, the legs by :meth:`LegLimits.constraints`.
"""

from __future__ import annotations

from dataclasses import dataclass

import clarabel
import cvxpy as cp
import numpy as np
from scipy import sparse

from uav_comm_planner.core.conic import solve_usable
from uav_comm_planner.core.feasibility import project_onto_speed_limit
from uav_comm_planner.core.fleet.scenario import FleetScenario
from uav_comm_planner.core.fleet.separation import (keeps_separation, separation_rows,
                                                    SeparationRows)
from uav_comm_planner.core.sca.block import Columns, Expansion, Frame, Variables
from uav_comm_planner.core.sca.legs import LegLimits
from uav_comm_planner.core.sca.rates import NodeRates, NodeRows
from uav_comm_planner.core.sca.surrogate import KM
from uav_comm_planner.errors import SolverError

STEP_METHODS = ('clarabel', 'cvxpy')


def fleet_frames(fleet: FleetScenario) -> list[Frame]:
    """One frame per UAV, all about the centre of the box around the nodes and every end."""
    corners = np.vstack([fleet.scenario.nodes, fleet.starts_m, fleet.goals_m])
    centre = (corners.min(axis=0) + corners.max(axis=0)) / 2.0
    return [Frame(vehicle, centre) for vehicle in fleet.vehicles]


@dataclass(frozen=True)
class StepData:
    """A step's data at q^k: each UAV's bound rows and the separation rows (kilometres)."""

    rows: list[NodeRows]
    separation: SeparationRows


def step_cvxpy(fleet: FleetScenario, frames: list[Frame], rates: list[NodeRates],
               data: StepData) -> np.ndarray:
    """The reference step: z (K, M, 2) km, the maximiser, from cvxpy built afresh."""
    m = fleet.scenario.num_slots
    w = frames[0].nodes
    t = cp.Variable()
    z = [cp.Variable((m, 2)) for _ in frames]
    bound = 0
    constraints = []
    for frame, z_k, rows in zip(frames, z, data.rows):
        spread = cp.hstack([rows.weight[n] @ cp.sum(cp.square(z_k - w[n][None, :]), axis=1)
                            for n in range(len(w))])
        bound = bound + rows.constant - spread / m
        path = cp.vstack([frame.start[None, :], z_k, frame.goal[None, :]])
        constraints += LegLimits(frame).constraints(Variables(z_k, t, path[1:] - path[:-1]),
                                                    None)
    constraints.append(bound >= t)
    for (j, k), a, rhs in zip(fleet.pairs, data.separation.direction, data.separation.rhs):
        constraints.append(cp.sum(cp.multiply(a, z[j] - z[k]), axis=1) >= rhs)
    problem = cp.Problem(cp.Maximize(t), constraints)
    solve_usable(problem, 'fleet trajectory step')
    return np.stack([z_k.value for z_k in z])


def _clarabel_settings() -> clarabel.DefaultSettings:
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    return settings


def step_clarabel(fleet: FleetScenario, frames: list[Frame], rates: list[NodeRates],
                  data: StepData) -> np.ndarray:
    """The step as Clarabel's cone program (module docstring): z (K, M, 2) km."""
    n, m, uavs = fleet.scenario.num_nodes, fleet.scenario.num_slots, fleet.num_uavs
    width = 3 * m                                     # z_k (2 M), then u_k (M)
    first = 1 + width * np.arange(uavs)
    pairs = len(fleet.pairs)
    rows, cols, values, b = [], [], [], []
    # Node rows: t + sum_k coefficients_k . (z_k, u_k) <= sum_k b_k.
    rows.append(np.arange(n))
    cols.append(np.zeros(n, dtype=int))
    values.append(np.ones(n))
    right = np.zeros(n)
    slot = np.arange(m)
    for k, (block, node_rows) in enumerate(zip(rates, data.rows)):
        coefficients, b_k = block.update(node_rows)
        right += b_k
        # (M, 3): slot m's z_x, z_y and u columns of UAV k.
        columns = np.column_stack([first[k] + 2 * slot, first[k] + 2 * slot + 1,
                                   first[k] + 2 * m + slot])
        rows.append(np.repeat(np.arange(n), 3 * m))
        cols.append(np.broadcast_to(columns, (n, m, 3)).ravel())
        values.append(coefficients)
    b.append(right)
    # Separation rows: -a . (z_j - z_k) <= -rhs.
    for p, ((j, k), a, rhs) in enumerate(zip(fleet.pairs, data.separation.direction,
                                             data.separation.rhs)):
        row = n + p * m + np.repeat(slot, 2)
        for uav, sign in ((j, -1.0), (k, 1.0)):
            rows.append(row)
            cols.append(first[uav] + np.arange(2 * m))
            values.append(sign * a.ravel())
        b.append(-rhs)
    row = n + pairs * m
    cones = [clarabel.NonnegativeConeT(row)]
    # Epigraph cones ((u + 1) / 2, z_x, z_y, (u - 1) / 2) and the legs' cones, UAV by UAV.
    for k, frame in enumerate(frames):
        u_col = first[k] + 2 * m + slot
        z_col = first[k] + 2 * slot[:, None] + np.arange(2)
        rows.append(row + (4 * slot[:, None] + np.arange(4)).ravel())
        cols.append(np.column_stack([u_col, z_col, u_col]).ravel())
        values.append(np.tile([-0.5, -1.0, -1.0, -0.5], m))
        b.append(np.tile([0.5, 0.0, 0.0, -0.5], m))
        cones += [clarabel.SecondOrderConeT(4)] * m
        row += 4 * m
        legs = LegLimits(frame)
        pattern = legs.pattern(Columns(m, 1 + 2 * m))
        rows.append(row + pattern.rows)
        cols.append(first[k] + pattern.cols - 1)      # z's columns start at 1 in the block
        values.append(pattern.values)
        b.append(legs.right_hand_side())
        cones += list(legs.cones())
        row += legs.num_rows
    a_matrix = sparse.csc_matrix((np.concatenate(values), (np.concatenate(rows),
                                                           np.concatenate(cols))),
                                 shape=(row, 1 + width * uavs))
    objective = np.zeros(1 + width * uavs)
    objective[0] = -1.0
    no_quadratic = sparse.csc_matrix((a_matrix.shape[1], a_matrix.shape[1]))
    solver = clarabel.DefaultSolver(no_quadratic, objective, a_matrix, np.concatenate(b), cones,
                                    _clarabel_settings())
    solution = solver.solve()
    if solution.status not in (clarabel.SolverStatus.Solved,
                               clarabel.SolverStatus.AlmostSolved):
        raise SolverError(f'fleet trajectory step: Clarabel returned status {solution.status}')
    x = np.asarray(solution.x)
    return np.stack([x[first[k]:first[k] + 2 * m].reshape(m, 2) for k in range(uavs)])


class FleetStep:
    """The step for one fleet (module docstring); call it with q (K, M, 2) metres and p
    (K, N, M) watts for the next q (K, M, 2) metres, or None when the solver's answer does not
    keep the separation (the caller keeps q). ``method``: 'clarabel' or 'cvxpy'."""

    def __init__(self, fleet: FleetScenario, *, method: str = 'clarabel'):
        if method not in STEP_METHODS:
            raise SolverError(f'unknown fleet step method {method!r}: one of {STEP_METHODS}')
        self.fleet = fleet
        self.solve = step_clarabel if method == 'clarabel' else step_cvxpy
        self.frames = fleet_frames(fleet)
        self.rates = [NodeRates(frame, partial_sums=False) for frame in self.frames]

    def data(self, q: np.ndarray, p: np.ndarray) -> StepData:
        """The step's data at q (K, M, 2) metres with power p (K, N, M) watts."""
        z = np.stack([frame.km(q_k) for frame, q_k in zip(self.frames, q)])
        return StepData(rows=[rates.at(Expansion(q_k, p_k))
                              for rates, q_k, p_k in zip(self.rates, q, p)],
                        separation=separation_rows(z, self.fleet, scale=KM))

    def __call__(self, q: np.ndarray, p: np.ndarray) -> np.ndarray | None:
        z = self.solve(self.fleet, self.frames, self.rates,
                       self.data(np.asarray(q, dtype=float), np.asarray(p, dtype=float)))
        q_new = np.stack([project_onto_speed_limit(frame.metres(z_k), frame.scenario)
                          for frame, z_k in zip(self.frames, z)])
        return q_new if keeps_separation(q_new, self.fleet) else None


__all__ = ['fleet_frames', 'FleetStep', 'step_clarabel', 'step_cvxpy', 'STEP_METHODS',
           'StepData']
