"""The fleet's SCA trajectory step: every UAV's trajectory at once, t below every node's bound.

Each UAV k's part is the single UAV's, from its blocks (:mod:`uav_comm_planner.core.sca`): the
node-rate block's bound at q_k^k with power p_k (:meth:`~uav_comm_planner.core.sca.rates.
NodeRates.at`), mean_m lbr_{k,n,m}(z_k) = C_{k,n} - (1/M) sum_m W_{k,n,m} ||z_k[m] - w_n||^2,
and the single UAV's other blocks (:func:`~uav_comm_planner.core.sca.program.step_blocks`: the
legs' speed limits, the zones' restriction at q_k^k and the energy budget, each UAV's own);
node n's throughput is the sum over the UAVs, so the rate rows are

    t <= sum_k [C_{k,n} - (1/M) sum_m W_{k,n,m} (u_k[m] - 2 w_n . z_k[m] + ||w_n||^2)],

with u_k[m] >= ||z_k[m]||^2 (exact at an optimum, as in the node-rate block), plus the
separation rows (:mod:`.separation`). Each bound is global and tight at q^k, and q^k keeps every
row, so the step never lowers the true minimum throughput. Positions are in kilometres about
one centre for all UAVs (:class:`~uav_comm_planner.core.sca.block.Frame`).

Two solvers of the same step, which must agree: :func:`step_clarabel` (the default) writes the
cone program s = b - A x for Clarabel directly, x = (t, then per UAV z_k (2 M) and u_k (M),
then each UAV's blocks' own columns), with each UAV's node-rate coefficients
(:meth:`NodeRates.update`) and its blocks' rows (:meth:`~uav_comm_planner.core.sca.block.Block.
pattern`, :meth:`~uav_comm_planner.core.sca.block.Block.update`) placed in its columns;
:func:`step_cvxpy` (the reference) states the same constraints in cvxpy, each UAV's blocks by
their :meth:`~uav_comm_planner.core.sca.block.Block.constraints`. After the solve, each UAV's
answer is repaired as the single UAV's is (the energy block's blend towards q_k^k, the speed
limits' projection, the zones' keeper), and the step is refused (the caller keeps q) unless
every UAV then keeps its blocks and the fleet keeps d_min.
"""

from __future__ import annotations

from dataclasses import dataclass

import clarabel
import cvxpy as cp
import numpy as np
from scipy import sparse

from uav_comm_planner.core.conic import CLARABEL_ATTEMPTS, solve_usable
from uav_comm_planner.core.feasibility import project_onto_speed_limit
from uav_comm_planner.core.fleet.scenario import FleetScenario
from uav_comm_planner.core.fleet.separation import (keeps_separation, separation_rows,
                                                    SeparationRows)
from uav_comm_planner.core.optimizer import ZoneKeeper
from uav_comm_planner.core.sca.block import Block, Columns, Expansion, Frame, Variables
from uav_comm_planner.core.sca.program import step_blocks
from uav_comm_planner.core.sca.rates import NodeRates, NodeRows
from uav_comm_planner.core.sca.surrogate import KM
from uav_comm_planner.errors import SolverError

STEP_METHODS = ('clarabel', 'cvxpy')


def fleet_frames(fleet: FleetScenario) -> list[Frame]:
    """One frame per UAV, all about the centre of the box around the nodes and every end."""
    corners = np.vstack([fleet.scenario.nodes, fleet.starts_m, fleet.goals_m])
    centre = (corners.min(axis=0) + corners.max(axis=0)) / 2.0
    return [Frame(vehicle, centre) for vehicle in fleet.vehicles]


def vehicle_blocks(frame: Frame) -> list[Block]:
    """A UAV's blocks besides its node rates: the single UAV's step's (the legs, the zones
    where there are some, the energy budget where there is one), in the same order."""
    return step_blocks(frame, partial_sums=False)[1:]


def vehicle_paths(frames: list[Frame], z: list[cp.Variable], t: cp.Variable) -> list[Variables]:
    """Each UAV's cvxpy variables as its blocks read them: z_k, t and its path's legs."""
    paths = []
    for frame, z_k in zip(frames, z):
        path = cp.vstack([frame.start[None, :], z_k, frame.goal[None, :]])
        paths.append(Variables(z_k, t, path[1:] - path[:-1]))
    return paths


@dataclass(frozen=True)
class StepData:
    """A step's data at q^k: each UAV's bound rows and the separation rows (kilometres), each
    UAV's other blocks (:func:`vehicle_blocks`) and what they need at q_k^k
    (:meth:`~uav_comm_planner.core.sca.block.Block.at`)."""

    rows: list[NodeRows]
    separation: SeparationRows
    blocks: list[list[Block]]
    block_data: list[list]


def step_cvxpy(fleet: FleetScenario, frames: list[Frame], rates: list[NodeRates],
               data: StepData) -> np.ndarray:
    """The reference step: z (K, M, 2) km, the maximiser, from cvxpy built afresh."""
    m = fleet.scenario.num_slots
    w = frames[0].nodes
    t = cp.Variable()
    z = [cp.Variable((m, 2)) for _ in frames]
    bound = 0
    constraints = []
    for z_k, rows, v, blocks, block_data in zip(z, data.rows, vehicle_paths(frames, z, t),
                                                data.blocks, data.block_data):
        spread = cp.hstack([rows.weight[n] @ cp.sum(cp.square(z_k - w[n][None, :]), axis=1)
                            for n in range(len(w))])
        bound = bound + rows.constant - spread / m
        for block, at_k in zip(blocks, block_data):
            constraints += block.constraints(v, at_k)
    constraints.append(bound >= t)
    for (j, k), a, rhs in zip(fleet.pairs, data.separation.direction, data.separation.rhs):
        constraints.append(cp.sum(cp.multiply(a, z[j] - z[k]), axis=1) >= rhs)
    problem = cp.Problem(cp.Maximize(t), constraints)
    solve_usable(problem, 'fleet trajectory step', attempts=CLARABEL_ATTEMPTS)
    return np.stack([z_k.value for z_k in z])


def _clarabel_settings() -> clarabel.DefaultSettings:
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    return settings


def placed_block(block: Block, block_data: object, z_first: int,
                 own_first: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A block's rows (within the block), columns, values and b at this step, its z columns
    moved to a UAV's z from ``z_first`` and its own columns to ``own_first`` (the block's
    pattern numbers z from column 1 and its own columns after z, :class:`Columns`)."""
    m = block.frame.scenario.num_slots
    pattern = block.pattern(Columns(m, 1 + 2 * m))
    if np.any(pattern.cols == 0):
        raise SolverError(f'a fleet step places no block on t ({type(block).__name__})')
    cols = np.where(pattern.cols <= 2 * m, z_first + pattern.cols - 1,
                    own_first + pattern.cols - (1 + 2 * m))
    values = pattern.values.astype(float)
    b = np.array(block.right_hand_side(), dtype=float)
    entries, rhs = block.update(block_data)
    values[np.asarray(block.changing_entries, dtype=int)] = entries
    b[np.asarray(block.changing_rows, dtype=int)] = rhs
    return pattern.rows, cols, values, b


def step_clarabel(fleet: FleetScenario, frames: list[Frame], rates: list[NodeRates],
                  data: StepData) -> np.ndarray:
    """The step as Clarabel's cone program (module docstring): z (K, M, 2) km."""
    n, m, uavs = fleet.scenario.num_nodes, fleet.scenario.num_slots, fleet.num_uavs
    width = 3 * m                                     # z_k (2 M), then u_k (M)
    first = 1 + width * np.arange(uavs)
    own = 1 + width * uavs                            # the blocks' own columns, UAV by UAV
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
    # Epigraph cones ((u + 1) / 2, z_x, z_y, (u - 1) / 2) and the blocks' rows, UAV by UAV.
    for k in range(uavs):
        u_col = first[k] + 2 * m + slot
        z_col = first[k] + 2 * slot[:, None] + np.arange(2)
        rows.append(row + (4 * slot[:, None] + np.arange(4)).ravel())
        cols.append(np.column_stack([u_col, z_col, u_col]).ravel())
        values.append(np.tile([-0.5, -1.0, -1.0, -0.5], m))
        b.append(np.tile([0.5, 0.0, 0.0, -0.5], m))
        cones += [clarabel.SecondOrderConeT(4)] * m
        row += 4 * m
        for block, at_k in zip(data.blocks[k], data.block_data[k]):
            block_rows, block_cols, block_values, block_b = placed_block(block, at_k,
                                                                         first[k], own)
            rows.append(row + block_rows)
            cols.append(block_cols)
            values.append(block_values)
            b.append(block_b)
            cones += list(block.cones())
            row += block.num_rows
            own += block.num_columns
    a_matrix = sparse.csc_matrix((np.concatenate(values), (np.concatenate(rows),
                                                           np.concatenate(cols))),
                                 shape=(row, own))
    objective = np.zeros(own)
    objective[0] = -1.0
    no_quadratic = sparse.csc_matrix((own, own))
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
    (K, N, M) watts for the next q (K, M, 2) metres, or None when the solver's answer, repaired,
    does not keep every UAV's blocks and the separation (the caller keeps q). ``method``:
    'clarabel' or 'cvxpy'."""

    def __init__(self, fleet: FleetScenario, *, method: str = 'clarabel'):
        if method not in STEP_METHODS:
            raise SolverError(f'unknown fleet step method {method!r}: one of {STEP_METHODS}')
        self.fleet = fleet
        self.solve = step_clarabel if method == 'clarabel' else step_cvxpy
        self.frames = fleet_frames(fleet)
        self.rates = [NodeRates(frame, partial_sums=False) for frame in self.frames]
        self.blocks = [vehicle_blocks(frame) for frame in self.frames]
        self.keepers = [None if vehicle.zones is None or vehicle.zones.empty
                        else ZoneKeeper(vehicle) for vehicle in fleet.vehicles]

    def data(self, q: np.ndarray, p: np.ndarray) -> StepData:
        """The step's data at q (K, M, 2) metres with power p (K, N, M) watts."""
        z = np.stack([frame.km(q_k) for frame, q_k in zip(self.frames, q)])
        expansions = [Expansion(q_k, p_k) for q_k, p_k in zip(q, p)]
        return StepData(rows=[rates.at(expansion)
                              for rates, expansion in zip(self.rates, expansions)],
                        separation=separation_rows(z, self.fleet, scale=KM),
                        blocks=self.blocks,
                        block_data=[[block.at(expansion) for block in blocks]
                                    for blocks, expansion in zip(self.blocks, expansions)])

    def repaired(self, k: int, z_k: np.ndarray, q_k: np.ndarray, block_data: list
                 ) -> np.ndarray | None:
        """UAV k's answer z_k (M, 2) km in metres, repaired as the single UAV's step does
        (each block's repair, the speed limits' projection, the zones' keeper from q_k); None
        when it then breaks one of its blocks."""
        frame = self.frames[k]
        q = frame.metres(z_k)
        for block, at_k in zip(self.blocks[k], block_data):
            q = block.repair(q, at_k)
        q = project_onto_speed_limit(q, frame.scenario)
        keeper = self.keepers[k]
        if keeper is not None:
            q = keeper(q, q_k)
            if not keeper.keeps(q):
                return None
        return q if all(block.admits(q) for block in self.blocks[k]) else None

    def __call__(self, q: np.ndarray, p: np.ndarray) -> np.ndarray | None:
        q = np.asarray(q, dtype=float)
        data = self.data(q, np.asarray(p, dtype=float))
        z = self.solve(self.fleet, self.frames, self.rates, data)
        answers = [self.repaired(k, z_k, q[k], data.block_data[k]) for k, z_k in enumerate(z)]
        if any(answer is None for answer in answers):
            return None
        q_new = np.stack(answers)
        return q_new if keeps_separation(q_new, self.fleet) else None


__all__ = ['fleet_frames', 'FleetStep', 'placed_block', 'step_clarabel',
           'step_cvxpy', 'STEP_METHODS', 'StepData', 'vehicle_blocks', 'vehicle_paths']
