"""The exact water-filling power step against the conic (cvxpy + Clarabel) power step."""

import cvxpy as cp
from helpers import waterfilling_multipliers
import numpy as np
import pytest

from uav_comm_planner import paper_scenario
from uav_comm_planner.core.conic import Certificate, solve_checked
from uav_comm_planner.core.initial import static_point, straight_line
from uav_comm_planner.core.model import snr_per_watt
from uav_comm_planner.core.power import conic_power, power_dual_bound, waterfilling_power
from uav_comm_planner.errors import SolverError


def letter_cases():
    for case in ('I', 'II'):
        scenario = paper_scenario(case)
        for q in (straight_line(scenario), static_point(scenario)):
            yield snr_per_watt(q, scenario), scenario.power_budget_w


def random_cases():
    rng = np.random.default_rng(2024)
    for _ in range(6):
        n, m = rng.integers(2, 7), rng.integers(5, 60)
        # Spread over 4 decades so that at a low budget many slots get no power at all.
        a = 10.0 ** rng.uniform(-1.0, 3.0, size=(n, m))
        for budget in (0.05, 1.0, 30.0):
            yield a, budget


def both(a, budget):
    return waterfilling_power(a, budget), conic_power(a, budget)


@pytest.mark.parametrize('a, budget', list(letter_cases()) + list(random_cases()))
def test_waterfilling_equals_conic_form(a, budget):
    exact, conic = both(a, budget)
    assert exact.efficiency == pytest.approx(conic.efficiency, rel=1e-6)
    # Same allocation, up to the conic solver's accuracy relative to the budget.
    np.testing.assert_allclose(exact.p, conic.p, atol=1e-5 * budget)


@pytest.mark.parametrize('a, budget', list(random_cases()))
def test_waterfilling_is_a_water_level_per_node_with_equal_rates(a, budget):
    result = waterfilling_power(a, budget)
    p = result.p
    assert np.all(p >= 0.0)
    assert p.sum() == pytest.approx(budget, rel=1e-9)
    efficiencies = np.log2(1.0 + p * a).mean(axis=1)
    np.testing.assert_allclose(efficiencies, result.efficiency, rtol=1e-8)
    for p_n, a_n in zip(p, a):
        active = p_n > 0
        level = p_n[active] + 1.0 / a_n[active]
        np.testing.assert_allclose(level, level.mean(), rtol=1e-9)
        # Inactive slots are those whose 1/a lies above the water level.
        assert np.all(1.0 / a_n[~active] >= level.mean() * (1 - 1e-9))


def test_low_snr_cases_leave_some_slots_without_power():
    rng = np.random.default_rng(5)
    a = 10.0 ** rng.uniform(-1.0, 3.0, size=(4, 40))
    exact, conic = both(a, 0.05)
    silent = exact.p == 0.0
    assert silent.sum() > 20
    assert np.all(conic.p[silent] <= 1e-6 * 0.05)


def test_the_letters_high_snr_power_is_nearly_constant_along_the_flight():
    # At a ~ 1e13 per watt, 1/a ~ 1e-13 W: water-filling is flat to within 1e-11 W.
    scenario = paper_scenario('I')
    a = snr_per_watt(straight_line(scenario), scenario)
    p = waterfilling_power(a, scenario.power_budget_w).p
    assert np.all(p > 0)
    assert np.ptp(p, axis=1).max() < 1e-10


def test_bad_snr_array_is_refused():
    with pytest.raises(SolverError, match='finite, positive'):
        waterfilling_power(np.array([[1.0, np.nan]]), 1.0)
    with pytest.raises(SolverError, match='finite, positive'):
        waterfilling_power(np.array([[1.0, 0.0]]), 1.0)


def test_conic_failure_is_reported(monkeypatch):
    import cvxpy as cp

    def fail(self, *args, **kwargs):
        raise cp.error.SolverError('numerical trouble')

    monkeypatch.setattr(cp.Problem, 'solve', fail)
    with pytest.raises(SolverError, match='power step: CLARABEL failed'):
        conic_power(np.ones((2, 3)), 1.0)


def test_newton_starts_at_or_above_the_root_and_at_it_when_every_slot_is_active():
    from uav_comm_planner.core.power import _WaterLevels
    rng = np.random.default_rng(9)
    for _ in range(300):
        n, m = rng.integers(1, 8), rng.integers(1, 80)
        a = 10.0 ** rng.uniform(rng.uniform(-3.0, 10.0), 14.0, size=(n, m))
        budget = 10.0 ** rng.uniform(-3.0, 2.0)
        water = _WaterLevels(a)
        _, node_power = water.levels(max(water.start(budget), 0.0))
        assert node_power.sum() >= budget * (1 - 1e-9)
    scenario = paper_scenario('I')
    water = _WaterLevels(snr_per_watt(straight_line(scenario), scenario))
    _, node_power = water.levels(water.start(scenario.power_budget_w))
    assert node_power.sum() == pytest.approx(scenario.power_budget_w, rel=1e-12)


def test_closed_form_levels_are_newtons_when_every_slot_is_active_and_absent_otherwise():
    from uav_comm_planner.core.power import _levels_if_all_active, _newton_levels
    rng = np.random.default_rng(21)
    seen = {True: 0, False: 0}
    for _ in range(300):
        n, m = rng.integers(1, 8), rng.integers(1, 80)
        a = 10.0 ** rng.uniform(rng.uniform(-3.0, 12.0), 14.0, size=(n, m))
        budget = 10.0 ** rng.uniform(-3.0, 2.0)
        newton = _newton_levels(a, budget)
        all_active = bool(np.all(newton[:, None] >= 1.0 / a * (1 + 1e-9)))
        closed = _levels_if_all_active(a, 1.0 / a, budget)
        if all_active:
            assert closed is not None
            np.testing.assert_allclose(closed, newton, rtol=1e-9)
        if closed is None:
            assert np.any(newton[:, None] <= 1.0 / a * (1 + 1e-9))
        seen[closed is None] += 1
    assert seen[True] > 30 and seen[False] > 30


@pytest.mark.parametrize('a, budget', list(letter_cases()) + list(random_cases()))
def test_waterfilling_is_certified_optimal_by_weak_duality(a, budget):
    """The dual bound at the water-filling's own multipliers equals its value (so it is the
    optimum), and any other multipliers give a bound above it (so the bound is one)."""
    exact = waterfilling_power(a, budget)
    weights, nu = waterfilling_multipliers(exact, a)
    bound = power_dual_bound(a, budget, weights, nu)
    assert bound >= exact.efficiency - 1e-9 * max(1.0, exact.efficiency)
    assert bound == pytest.approx(exact.efficiency, rel=1e-9, abs=1e-9)
    rng = np.random.default_rng(0)
    for _ in range(5):
        other = rng.dirichlet(np.ones(a.shape[0]))
        assert power_dual_bound(a, budget, other, nu * rng.uniform(0.2, 5.0)) \
            > exact.efficiency - 1e-12


def test_an_answer_the_certificate_refuses_is_solved_again_then_an_error():
    a = np.array([[4.0, 0.5], [1.0, 2.0]])
    problem_seen = []

    def refuse():
        problem_seen.append(1)
        return Certificate(gap=1e-3, tolerance=1e-8)

    x = cp.Variable(nonneg=True)
    problem = cp.Problem(cp.Maximize(cp.log(1 + a[0, 0] * x)), [x <= 1.0])
    with pytest.raises(SolverError, match=r"power step: CLARABEL returned status 'optimal' "
                                          r'with an optimality gap of 0\.001 .*; then '):
        solve_checked(problem, 'power step', 'CLARABEL', [{}, {'max_iter': 50}], refuse)
    assert len(problem_seen) == 2
    # A NaN gap never holds.
    assert not Certificate(gap=float('nan'), tolerance=1.0).holds


def test_the_power_never_sums_above_the_budget_not_even_by_an_ulp():
    """Over seeded plans and allocations the sum of p is at most P_T exactly (a scaling that
    rounds up is lowered a ulp at a time)."""
    from uav_comm_planner import plan, SolverSettings

    from helpers import random_scenario

    rng = np.random.default_rng(25)
    for _ in range(300):
        a = 10.0 ** rng.uniform(-1.0, 14.0, size=(int(rng.integers(1, 6)),
                                                  int(rng.integers(2, 60))))
        budget = float(10.0 ** rng.uniform(-3.0, 2.0))
        assert waterfilling_power(a, budget).p.sum() <= budget
    for seed in range(20):
        result = plan(random_scenario(seed, nodes=4, slots=30),
                      SolverSettings(compute_baselines=False))
        assert result.power.sum() <= result.scenario.power_budget_w


def test_a_stack_of_power_steps_is_each_step_alone_and_its_shape_is_checked():
    # Stacks of one shape, from problems where the closed form applies (high SNR, large
    # budget) and where it does not (many slots without power), mixed in one stack.
    from uav_comm_planner.core.power import waterfilling_powers

    rng = np.random.default_rng(7)
    for budget in (0.05, 1.0, 30.0):
        stack = np.stack([10.0 ** rng.uniform(low, low + 1.0, size=(4, 25))
                          for low in (-1.0, 2.0, 4.0, 0.0, 5.0)])
        together = waterfilling_powers(stack, budget)
        assert len(together) == len(stack)
        for a, allocation in zip(stack, together):
            alone = waterfilling_power(a, budget)
            np.testing.assert_allclose(allocation.p, alone.p, rtol=1e-9, atol=1e-15 * budget)
            assert allocation.efficiency == pytest.approx(alone.efficiency, rel=1e-12)
            assert allocation.p.sum() <= budget
    with pytest.raises(SolverError):
        waterfilling_powers(np.ones((3, 4)), 1.0)
    with pytest.raises(SolverError):
        waterfilling_powers(-np.ones((2, 3, 4)), 1.0)
