"""Solving a cvxpy problem with its status checked: a failure is a typed error, never None."""

from __future__ import annotations

import cvxpy as cp

from uav_comm_planner.errors import SolverError


def solve_to_optimality(problem: cp.Problem, step: str, solver: str, **options) -> None:
    """Solve ``problem`` with ``solver``; raise :class:`SolverError` unless it is optimal.

    ``step`` names the sub-problem in the message ('power step', 'trajectory step').
    """
    try:
        problem.solve(solver=solver, **options)
    except cp.error.SolverError as exc:
        raise SolverError(f'{step}: {solver} failed ({exc})') from exc
    if problem.status != cp.OPTIMAL:
        raise SolverError(f'{step}: {solver} returned status {problem.status!r}')
