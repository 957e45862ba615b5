"""Solving a cvxpy problem with its status and its answer checked: a failure is a typed error,
never None, and an answer is accepted only when an independent optimality check holds.

An interior-point solver can stop short of its tolerances (cvxpy's ``optimal_inaccurate``,
Clarabel's ``AlmostSolved``) on problems that are perfectly well posed: for example when its
gap stalls a few per cent above a tolerance near the floor of double precision. Such an
answer may still be exact to far more digits than a caller needs, or it may not; the status
does not say which. :func:`solve_checked` therefore asks the caller's own certificate (a
duality gap or a KKT residual computed from the answer with numpy alone) and retries with the
next settings when it fails.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence
import warnings

import cvxpy as cp

from uav_comm_planner.errors import SolverError

#: Statuses whose answer is worth checking; any other is a failure of that attempt.
_USABLE = (cp.OPTIMAL, cp.OPTIMAL_INACCURATE)
#: Clarabel's settings tried in turn by the steps cvxpy states (:func:`solve_usable`): its
#: defaults, more iterations, then a smaller static regularisation, which solves steps whose
#: cones stall at the defaults (seen in the fleet's energy rows and the altitude step).
CLARABEL_ATTEMPTS = ({}, {'max_iter': 400},
                     {'max_iter': 400, 'static_regularization_constant': 1e-7})


@dataclass(frozen=True)
class Certificate:
    """The outcome of an optimality check: ``gap`` (the check's own measure, such as a relative
    duality gap or KKT residual) against the ``tolerance`` it must not exceed."""

    gap: float
    tolerance: float

    @property
    def holds(self) -> bool:
        # Written so that a NaN gap does not hold.
        return self.gap <= self.tolerance


def _attempt(problem: cp.Problem, solver: str, options: dict) -> str:
    """Solve ``problem`` once; '' when its status is usable, else what went wrong."""
    try:
        with warnings.catch_warnings():
            # cvxpy warns of every inaccurate answer; the caller's check decides instead.
            warnings.filterwarnings('ignore', message='Solution may be inaccurate')
            problem.solve(solver=solver, **options)
    except cp.error.SolverError as exc:
        return f'failed ({exc})'
    return '' if problem.status in _USABLE else f'returned status {problem.status!r}'


def solve_usable(problem: cp.Problem, step: str, solver: str = 'CLARABEL',
                 attempts: Sequence[dict] = ({},)) -> None:
    """Solve ``problem`` under each option set of ``attempts`` in turn until its status is
    optimal or nearly so (the caller, an SCA step judged by the iteration around it, accepts
    either). Raises :class:`SolverError` naming ``step`` and every attempt's failure
    otherwise."""
    failures = []
    for options in attempts:
        failure = _attempt(problem, solver, options)
        if not failure:
            return
        failures.append(failure)
    raise SolverError(f'{step}: {solver} ' + '; then '.join(failures))


def solve_checked(problem: cp.Problem, step: str, solver: str,
                  attempts: Sequence[dict], check: Callable[[], Certificate]) -> Certificate:
    """Solve ``problem`` with ``solver`` under each option set of ``attempts`` in turn, until an
    answer is optimal (or nearly so) and ``check()`` certifies it; return that certificate.

    ``check`` reads the problem's variables and dual values after a solve. Raises
    :class:`SolverError` naming ``step`` when no attempt gives a certified answer.
    """
    failures = []
    for options in attempts:
        failure = _attempt(problem, solver, options)
        if failure:
            failures.append(failure)
            continue
        certificate = check()
        if certificate.holds:
            return certificate
        failures.append(f'returned status {problem.status!r} with an optimality gap of '
                        f'{certificate.gap:.3g} (at most {certificate.tolerance:.3g} accepted)')
    raise SolverError(f'{step}: {solver} ' + '; then '.join(failures))
