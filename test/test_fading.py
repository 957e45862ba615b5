"""Fading in the evaluation: draws with the planner's expected gain as their mean, the Rayleigh
ergodic rate against its closed form, Jensen's inequality, seeds, and the command line."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.special import exp1

from uav_comm_planner import paper_scenario, plan
from uav_comm_planner.core.fading import evaluate_fading, Fading, power_gains
from uav_comm_planner.core.model import snr_per_watt
from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.tools import cli


@pytest.fixture(scope='module')
def urban_plan():
    scenario = paper_scenario('I', channel='los:urban')
    return scenario, plan(scenario)


@pytest.mark.parametrize('fields, reason', [
    (('weibull',), 'one of rician, rayleigh'), (('rician', math.nan), 'in \\[-30, 40\\] dB'),
    (('rician', 50.0), 'in \\[-30, 40\\] dB'), (('rician', 10.0, 0), 'samples'),
    (('rician', 10.0, 10, -1), 'seed'), (('rician', 10.0, 2.5), 'samples')])
def test_bad_fading_is_a_typed_error(fields, reason):
    with pytest.raises(InvalidScenarioError, match=reason):
        Fading(*fields)


@pytest.mark.parametrize('k_db', [-10.0, 0.0, 10.0, 30.0])
def testpower_gains_have_mean_one_and_the_rician_spread(k_db):
    fading = Fading('rician', k_db)
    rng = np.random.default_rng(5)
    draws = power_gains(rng, fading, (400_000,), np.ones(400_000, dtype=bool))
    k = 10 ** (k_db / 10)
    assert draws.mean() == pytest.approx(1.0, abs=5 * draws.std() / math.sqrt(len(draws)))
    # Var |h|^2 = (2 K + 1) / (K + 1)^2 for a Rician power gain of mean 1.
    assert draws.var() == pytest.approx((2 * k + 1) / (k + 1) ** 2, rel=0.02)
    scattered = power_gains(rng, fading, (400_000,), np.zeros(400_000, dtype=bool))
    assert scattered.var() == pytest.approx(1.0, rel=0.02)           # Exp(1)


def test_rayleigh_ergodic_rates_match_the_closed_form(urban_plan):
    """E log2(1 + x E), E ~ Exp(1), is exp(1/x) E1(1/x) / ln 2."""
    scenario, result = urban_plan
    fading = Fading('rayleigh', samples=4000, seed=11)
    evaluation = evaluate_fading(result.trajectory, result.power, scenario, fading)
    x = result.power * snr_per_watt(result.trajectory, scenario)
    with np.errstate(over='ignore', divide='ignore', invalid='ignore'):
        bits = np.where(x > 0, np.exp(1 / x) * exp1(1 / np.where(x > 0, x, 1.0)) / math.log(2),
                        0.0)
    expected = scenario.bandwidth_hz / scenario.num_nodes * bits.mean(axis=1)
    spread = evaluation.std / math.sqrt(fading.samples)
    np.testing.assert_allclose(evaluation.node_ergodic, expected, atol=6 * spread + 1e-9)


def test_los_lottery_draws_line_of_sight_at_p_los(urban_plan):
    scenario, result = urban_plan
    # Rician with a huge K is the LoS lottery alone: E[min_n R_n] then reflects P_LoS only,
    # and a channel that is always in line of sight (free space) loses nearly nothing.
    free = paper_scenario('I')
    free_plan = plan(free)
    quiet = evaluate_fading(free_plan.trajectory, free_plan.power, free,
                            Fading('rician', 40.0, 500))
    assert quiet.mean == pytest.approx(free_plan.min_throughput, rel=1e-3)
    lottery = evaluate_fading(result.trajectory, result.power, scenario,
                              Fading('rician', 40.0, 500))
    assert lottery.mean < result.min_throughput * 0.97


@pytest.mark.parametrize('model, k_db', [('rician', 0.0), ('rician', 10.0), ('rayleigh', 10.0)])
def test_fading_never_beats_the_expected_gain_on_average(urban_plan, model, k_db):
    scenario, result = urban_plan
    evaluation = evaluate_fading(result.trajectory, result.power, scenario,
                                 Fading(model, k_db, 500))
    assert evaluation.planned == pytest.approx(result.min_throughput, rel=1e-12)
    assert evaluation.mean <= evaluation.min_node_ergodic <= evaluation.planned
    assert evaluation.fifth_percentile <= evaluation.mean
    assert evaluation.std > 0.0


def test_the_same_seed_gives_the_same_draws(urban_plan):
    scenario, result = urban_plan
    first, again, other = (evaluate_fading(result.trajectory, result.power, scenario,
                                           Fading('rician', samples=200, seed=seed))
                           for seed in (1, 1, 2))
    np.testing.assert_array_equal(first.min_throughputs, again.min_throughputs)
    assert not np.array_equal(first.min_throughputs, other.min_throughputs)


def test_command_line_fading(tmp_path, capsys):
    result_file = tmp_path / 'r.json'
    status = cli.main(['plan', '--case', 'I', '--channel', 'los:dense-urban', '--fading',
                       'rician', '--fading-samples', '300', '--seed', '4', '--json',
                       str(result_file)])
    out, _ = capsys.readouterr()
    assert status == 0 and 'ergodic min throughput' in out
    record = json.loads(result_file.read_text())
    fading = record['fading']
    assert (fading['model'], fading['samples'], fading['seed']) == ('rician', 300, 4)
    assert fading['ergodic_min_throughput'] < record['min_throughput']
    scenario = paper_scenario('I', channel='los:dense-urban')
    again = evaluate_fading(np.array(record['trajectory']), np.array(record['power']),
                            scenario, Fading('rician', 10.0, 300, 4))
    assert fading['ergodic_min_throughput'] == pytest.approx(again.mean, rel=1e-12)


@pytest.mark.parametrize('argv, reason', [
    (['--seed', '3'], 'needs --fading'),
    (['--fading', 'rician', '--fading-samples', '0'], 'samples'),
    (['--fading', 'rayleigh', '--rician-k-db', '99'], '40'),
    (['--fading', 'nakagami'], 'invalid choice')])
def test_command_line_refuses_bad_fading_options_in_one_line(argv, reason, capsys):
    assert cli.main(['plan', '--case', 'I', *argv]) == 2
    err = capsys.readouterr()[1]
    assert len(err.strip().splitlines()) == 1 and reason in err
