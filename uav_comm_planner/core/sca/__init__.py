"""The SCA trajectory step (letter, problem (11)), written once as blocks.

Each family of constraints is one :class:`~uav_comm_planner.core.sca.block.Block` in one
module: the node rates (:mod:`.rates`), the legs' speed limits (:mod:`.legs`), the zones
(:mod:`.zones`), a replan's path budget (:mod:`.path_budget`). The reference step
(:mod:`.reference`, cvxpy rebuilt at every step) and the fast step (:mod:`.fast`, Clarabel
updated in place on the cone program of :mod:`.program`) are both built from them; the SCA
bound itself is in :mod:`.surrogate`.
"""

from uav_comm_planner.core.sca.block import (Block, BlockFactory, Columns, DualBound, Entries,
                                             Expansion, Frame, Variables)
from uav_comm_planner.core.sca.fast import (ClarabelTrajectoryStep, LOOSE_TOLERANCE, SOLVERS,
                                            trajectory_step_clarabel)
from uav_comm_planner.core.sca.reference import trajectory_step_cvxpy
from uav_comm_planner.core.sca.surrogate import KM, path_length_km, TrajectoryStep

__all__ = ['Block', 'BlockFactory', 'ClarabelTrajectoryStep', 'Columns', 'DualBound', 'Entries',
           'Expansion', 'Frame', 'KM', 'LOOSE_TOLERANCE', 'path_length_km', 'SOLVERS',
           'trajectory_step_clarabel', 'trajectory_step_cvxpy', 'TrajectoryStep', 'Variables']
