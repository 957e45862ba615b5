"""core/conic.py: one solve with its status checked, and the certified solve's retries."""

import cvxpy as cp
import pytest

from uav_comm_planner.core.conic import Certificate, solve_checked, solve_usable
from uav_comm_planner.errors import SolverError


def test_a_usable_solve_leaves_the_answer_in_the_variables():
    x = cp.Variable()
    problem = cp.Problem(cp.Maximize(x), [x <= 2.5, x >= -1.0])
    solve_usable(problem, 'toy step')
    assert x.value == pytest.approx(2.5, abs=1e-7)


def test_an_infeasible_problem_is_a_typed_error_naming_the_step_and_the_status():
    x = cp.Variable()
    problem = cp.Problem(cp.Maximize(x), [x <= -1.0, x >= 1.0])
    with pytest.raises(SolverError, match=r"toy step: CLARABEL returned status 'infeasible'"):
        solve_usable(problem, 'toy step')


def test_the_certified_solve_tries_the_next_settings_until_the_check_holds():
    x = cp.Variable()
    problem = cp.Problem(cp.Minimize(cp.square(x - 1.0)))
    tried = []

    def check() -> Certificate:
        # Fails the first answer on purpose: the second attempt's settings must be used.
        tried.append(x.value)
        return Certificate(gap=1.0 if len(tried) == 1 else 0.0, tolerance=0.5)

    certificate = solve_checked(problem, 'toy step', 'CLARABEL', [{}, {'max_iter': 50}], check)
    assert certificate.holds and len(tried) == 2
    with pytest.raises(SolverError, match='optimality gap of 1 .at most 0.5 accepted.'):
        solve_checked(problem, 'toy step', 'CLARABEL', [{}],
                      lambda: Certificate(gap=1.0, tolerance=0.5))
