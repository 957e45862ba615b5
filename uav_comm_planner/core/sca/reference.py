"""The reference SCA trajectory step: the blocks' cvxpy constraints, built afresh each step.

Variables z (M, 2) kilometres about the frame's centre and t (bits per use): maximise t
subject to every block of :func:`~uav_comm_planner.core.sca.program.step_blocks` (the node
rates, the legs, the zones, the extra blocks, the path budget). The answer is accepted only
when its duality gap, from every block's part of the certificate
(:class:`~uav_comm_planner.core.sca.block.DualBound`), is at most :data:`CERTIFIED_GAP`; with
Clarabel, one that is not is solved again with :data:`CLARABEL_RETRY`, then
:data:`CLARABEL_LAST_RETRY`.
"""

from __future__ import annotations

import functools
import math
from typing import Sequence

import cvxpy as cp
import numpy as np

from uav_comm_planner.core.conic import Certificate, solve_checked
from uav_comm_planner.core.sca.block import (Block, BlockFactory, DualBound, Expansion, Frame,
                                             Variables)
from uav_comm_planner.core.sca.program import step_blocks
from uav_comm_planner.core.sca.surrogate import TrajectoryStep
from uav_comm_planner.core.scenario import Scenario

#: A cvxpy trajectory step is accepted when its duality gap is at most this share of
#: max(1, value); the alternating loop then also keeps it only if the true minimum rate does
#: not drop.
CERTIFIED_GAP = 1e-7
#: Tried when the solver's defaults stop short of optimal: more iterations, tighter
#: tolerances, the answer still judged by its duality gap.
CLARABEL_RETRY = dict(max_iter=400, tol_gap_abs=1e-9, tol_gap_rel=1e-9, tol_feas=1e-9)
#: The last try: the path budget's multiplier is large where the budget binds hard, and the
#: certificate then needs the budget met to about 1e-11 (seen: 1.2e-7 at 1e-9, 3e-9 here).
CLARABEL_LAST_RETRY = dict(max_iter=400, tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)


def certify(blocks: Sequence[Block], z: np.ndarray, data: Sequence,
            duals: Sequence[Sequence]) -> DualBound | None:
    """The dual bound at z (M, 2) km from every block's part, with the duals of each block's
    constraints; None when z breaks a block. The first block (the node rates) starts it."""
    bound = None
    for block, block_data, block_duals in zip(blocks, data, duals):
        bound = block.certificate(z, block_data, block_duals, bound)
        if bound is None:
            return None
    return bound


def trajectory_step_cvxpy(q_k: np.ndarray, p: np.ndarray, scenario: Scenario, *,
                          offsets: np.ndarray | None = None, solver: str = 'CLARABEL',
                          keep_path_length: bool = False, blocks: Sequence[BlockFactory] = (),
                          **solver_options) -> TrajectoryStep:
    """One SCA step, built afresh as a cvxpy problem (module docstring), expanded at q_k
    (M, 2) metres with power p (N, M) watts; offsets o (N,) bits per use; ``blocks`` more
    constraints (:class:`~uav_comm_planner.core.sca.block.Block` factories)."""
    frame = Frame.of(scenario)
    parts = step_blocks(frame, keep_path_length=keep_path_length, extra=blocks)
    expansion = Expansion(np.asarray(q_k, dtype=float), p, offsets)
    data = [block.at(expansion) for block in parts]
    v = Variables.of(frame)
    groups = [block.constraints(v, block_data) for block, block_data in zip(parts, data)]
    problem = cp.Problem(cp.Maximize(v.t), [c for group in groups for c in group])

    def certificate() -> Certificate:
        bound = certify(parts, np.asarray(v.z.value), data,
                        [[c.dual_value for c in group] for group in groups])
        return Certificate(math.inf if bound is None else bound.gap, CERTIFIED_GAP)

    bases = [{}, CLARABEL_RETRY, CLARABEL_LAST_RETRY] if solver == 'CLARABEL' else [{}]
    solve_checked(problem, 'trajectory step', solver,
                  [dict(base, **solver_options) for base in bases], certificate)
    q = frame.metres(np.asarray(v.z.value))
    for block, block_data in zip(parts, data):
        q = block.repair(q, block_data)
    return TrajectoryStep(q=q, bound_of=functools.partial(data[0].bound, frame.km(q),
                                                          frame.nodes))


__all__ = ['CERTIFIED_GAP', 'certify', 'CLARABEL_LAST_RETRY', 'CLARABEL_RETRY',
           'trajectory_step_cvxpy']
