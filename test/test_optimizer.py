"""Algorithm 1: constraints on every output, a never-decreasing objective, typed failures."""

from helpers import random_scenario
import numpy as np
import pytest

from uav_comm_planner import paper_scenario, plan, SolverError, SolverSettings
from uav_comm_planner.core.initial import straight_line
from uav_comm_planner.core.model import average_rates, leg_lengths, snr_per_watt
from uav_comm_planner.core.optimizer import alternate, baseline_rates
from uav_comm_planner.core.power import waterfilling_power
from uav_comm_planner.core.sca.reference import trajectory_step_cvxpy


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
        return plan(random_scenario(int(request.param[-1]), nodes=5, slots=40, side_m=1500.0,
                                    max_speed_mps=80.0, power_budget_w=2.0))
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


def min_rate_by_hand(q, p, scenario):
    """min_n (B/N) mean_m log2(1 + p g / (B/N sigma2)), written out from the model alone."""
    sigma2 = 10 ** ((scenario.noise_psd_dbm_per_hz - 30) / 10)
    w = np.asarray(scenario.ground_nodes_m, dtype=float)
    d2 = ((q[None, :, :] - w[:, None, :]) ** 2).sum(axis=2) + scenario.altitude_m ** 2
    share = scenario.bandwidth_hz / scenario.num_nodes
    snr = p * scenario.reference_gain / d2 / (share * sigma2)
    return float((share * np.log2(1 + snr).mean(axis=1)).min())


@pytest.mark.parametrize('case', ['I', 'II'])
def test_every_step_of_the_letters_loop_is_monotone_without_a_guard(case):
    """Algorithm 1 run by hand from the straight line, every trajectory step kept whatever it
    gives (no acceptance test, no projection): each power step and each SCA step, judged by
    the true min rate recomputed from the model, never lowers the objective."""
    scenario = paper_scenario(case)
    q = straight_line(scenario)
    values = []
    for _ in range(4):
        p = waterfilling_power(snr_per_watt(q, scenario), scenario.power_budget_w).p
        values.append(('power', min_rate_by_hand(q, p, scenario)))
        for _ in range(3):
            q = trajectory_step_cvxpy(q, p, scenario).q
            values.append(('trajectory', min_rate_by_hand(q, p, scenario)))
    rates = [value for _, value in values]
    assert all(b >= a * (1 - 1e-9) for a, b in zip(rates, rates[1:])), values
    # Not flat: the trajectory steps do the work (cases I and II gain 2.7 % and 1.5 %).
    assert rates[-1] > rates[0] * 1.01
    # And the package's loop, which keeps the guard, records the same climb.
    run = alternate(scenario, straight_line(scenario), SolverSettings.letter())
    history = run.history
    assert run.converged and run.trajectory_steps >= 2
    assert history[0].min_throughput == pytest.approx(rates[0], rel=1e-12)
    assert history[0].min_throughput == pytest.approx(
        baseline_rates(scenario)['straight'], rel=1e-12)
    recorded = [step.min_throughput for step in history]
    assert all(b >= a for a, b in zip(recorded, recorded[1:]))


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
