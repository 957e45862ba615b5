"""The steps of Algorithm 1 by name: the power step and the SCA trajectory step.

``power_method`` and ``trajectory_method`` (:func:`~uav_comm_planner.core.optimizer.plan`)
name them: the exact water-filling (default) or its conic reference, and the SCA step on a
Clarabel solver updated in place (default) or the cvxpy reference rebuilt at every step.
"""

from __future__ import annotations

from typing import Callable, Protocol, Sequence

import numpy as np

from uav_comm_planner.core.power import conic_power, PowerAllocation, waterfilling_power
from uav_comm_planner.core.sca.block import BlockFactory
from uav_comm_planner.core.sca.fast import ClarabelTrajectoryStep, trajectory_step_clarabel
from uav_comm_planner.core.sca.reference import trajectory_step_cvxpy
from uav_comm_planner.core.sca.surrogate import TrajectoryStep
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.errors import InvalidScenarioError

PowerSolver = Callable[[np.ndarray, float], PowerAllocation]


class TrajectorySolver(Protocol):
    """A plan's trajectory step: ``solver(q_k, p, scenario, offsets=...)`` gives the step from
    q_k (M, 2) metres and p (N, M) watts; ``set_tolerance`` loosens (a share, or None to
    restore) the interior-point tolerance where the solver has one to loosen."""

    def __call__(self, q_k: np.ndarray, p: np.ndarray, scenario: Scenario,
                 **keywords) -> TrajectoryStep: ...

    def set_tolerance(self, tolerance: float | None) -> None: ...


class RebuiltStep:
    """A step function (the cvxpy reference) as a :class:`TrajectorySolver`: its problem is
    built afresh at every call with ``keywords`` and solved at the solver's own tolerance,
    which :meth:`set_tolerance` leaves as it is."""

    def __init__(self, step: Callable[..., TrajectoryStep], **keywords) -> None:
        self._step, self._keywords = step, keywords

    def __call__(self, q_k: np.ndarray, p: np.ndarray, scenario: Scenario,
                 **keywords) -> TrajectoryStep:
        return self._step(q_k, p, scenario, **self._keywords, **keywords)

    def set_tolerance(self, tolerance: float | None) -> None:
        """Nothing to loosen: the reference always solves at its own tolerance."""


POWER_SOLVERS: dict[str, PowerSolver] = {
    'waterfilling': waterfilling_power,
    'conic': conic_power,
}
TRAJECTORY_SOLVERS: dict[str, Callable[..., TrajectoryStep]] = {
    'cvxpy': trajectory_step_cvxpy,
    'clarabel': trajectory_step_clarabel,
}
#: Methods whose steps share one solver per plan, built for the scenario and updated in place.
TRAJECTORY_STEPPERS: dict[str, Callable[..., TrajectorySolver]] = {
    'clarabel': ClarabelTrajectoryStep,
}


def step_solvers(scenario: Scenario, power_method: str, trajectory_method: str, *,
                 keep_path_length: bool = False,
                 blocks: Sequence[BlockFactory] = ()) -> tuple[PowerSolver, TrajectorySolver]:
    """The power and trajectory steps for these method names (:data:`POWER_SOLVERS`,
    :data:`TRAJECTORY_SOLVERS`), a stepper built for ``scenario`` where there is one; with
    ``keep_path_length`` every trajectory step keeps the path no longer than its expansion
    point's (:class:`~uav_comm_planner.core.scenario.SolverSettings`); ``blocks`` adds
    constraints to every trajectory step (:class:`~uav_comm_planner.core.sca.block.Block`
    factories)."""
    try:
        power_solver = POWER_SOLVERS[power_method]
        trajectory_solver = TRAJECTORY_SOLVERS[trajectory_method]
    except KeyError as exc:
        raise InvalidScenarioError(
            f'unknown method {exc.args[0]!r}; power: {sorted(POWER_SOLVERS)}, '
            f'trajectory: {sorted(TRAJECTORY_SOLVERS)}') from None
    except TypeError:
        raise InvalidScenarioError(
            f'methods are names: power_method one of {sorted(POWER_SOLVERS)}, '
            f'trajectory_method one of {sorted(TRAJECTORY_SOLVERS)}') from None
    if trajectory_method in TRAJECTORY_STEPPERS:
        trajectory_solver = TRAJECTORY_STEPPERS[trajectory_method](
            scenario, keep_path_length=keep_path_length, blocks=tuple(blocks))
    else:
        keywords = {'keep_path_length': True} if keep_path_length else {}
        trajectory_solver = RebuiltStep(trajectory_solver, **keywords,
                                        **({'blocks': tuple(blocks)} if blocks else {}))
    return power_solver, trajectory_solver


__all__ = ['POWER_SOLVERS', 'PowerSolver', 'RebuiltStep', 'TRAJECTORY_SOLVERS',
           'TRAJECTORY_STEPPERS', 'TrajectorySolver', 'step_solvers']
