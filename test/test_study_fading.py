"""Fading in the Monte Carlo study: every plan of a row judged by Monte Carlo over the fading,
against a simulation written here from the letter's channel, and the option's bad uses."""

from __future__ import annotations

import contextlib
import io
import math

import numpy as np
import pytest

from uav_comm_planner.core.fading import Fading
from uav_comm_planner.core.optimizer import plan
from uav_comm_planner.core.scenario import SolverSettings
from uav_comm_planner.tools import cli
from uav_comm_planner.tools.study.design import scenario_at, StudyDesign
from uav_comm_planner.tools.study.tables import columns, evaluate, open_table, plan_batch

DESIGN = StudyDesign(cases=3, seed=5, draws={'nodes': '3', 'slots': '20', 'side_m': '800'},
                     methods=('default', 'straight', 'bound'), fading=Fading('rayleigh'))


def rayleigh_min_throughputs(q, p, scenario, draws: int, seed: int) -> np.ndarray:
    """min_n R_n of ``draws`` horizons, each link's power gain Exp(1) times the letter's
    beta0 / (||q[m] - w_n||^2 + H^2), written out from the scenario's numbers."""
    nodes = np.asarray(scenario.ground_nodes_m, float)
    n_nodes, slots = p.shape
    sigma2 = 10.0 ** ((scenario.noise_psd_dbm_per_hz - 30.0) / 10.0)
    distance2 = ((q[None, :, :] - nodes[:, None, :]) ** 2).sum(axis=2) + scenario.altitude_m ** 2
    snr = p * n_nodes * scenario.reference_gain / distance2 / (scenario.bandwidth_hz * sigma2)
    rng = np.random.default_rng(seed)
    gains = rng.exponential(1.0, (draws, n_nodes, slots))
    rates = scenario.bandwidth_hz / n_nodes * np.log2(1.0 + snr * gains).mean(axis=2)
    return rates.min(axis=1)


def test_a_row_holds_each_plans_ergodic_min_throughput_and_its_spread():
    row = evaluate(DESIGN, 1)
    assert row['status'] == 'ok'
    assert [name for name, _ in columns(DESIGN)] == list(row)
    assert 'bound_ergodic_bps' not in row           # a bound makes no plan
    scenario = scenario_at(DESIGN, 1)
    result = plan(scenario, SolverSettings(compute_baselines=False))
    assert row['default_bps'] == result.min_throughput
    reference = rayleigh_min_throughputs(result.trajectory, result.power, scenario, 20_000, 99)
    error = math.hypot(row['default_ergodic_std'] / math.sqrt(DESIGN.fading.samples),
                       reference.std(ddof=1) / math.sqrt(len(reference)))
    print(f'\nergodic min {row["default_ergodic_bps"]:.5f} (std '
          f'{row["default_ergodic_std"]:.5f}) against {reference.mean():.5f} (std '
          f'{reference.std(ddof=1):.5f}); planned {row["default_bps"]:.5f}')
    assert abs(row['default_ergodic_bps'] - reference.mean()) <= 5.0 * error
    assert row['default_ergodic_std'] == pytest.approx(reference.std(ddof=1), rel=0.15)
    # Jensen: fading costs the plan made on the expected gain.
    for method in ('default', 'straight'):
        assert row[f'{method}_ergodic_bps'] < row[f'{method}_bps']


def test_each_row_draws_its_own_fading_the_same_on_every_run():
    first, again = evaluate(DESIGN, 0), evaluate(DESIGN, 0)
    assert first['default_ergodic_bps'] == again['default_ergodic_bps']
    assert DESIGN.fading_for(0).seed != DESIGN.fading_for(1).seed


def test_the_design_keeps_its_fading_and_a_table_of_another_fading_is_refused(tmp_path):
    assert StudyDesign.from_dict(DESIGN.to_dict()) == DESIGN
    out = tmp_path / 'study.csv'
    table, _ = open_table(out, DESIGN)
    table.append(plan_batch(DESIGN, [0]))
    other = StudyDesign(cases=3, seed=5, draws=DESIGN.draws, methods=DESIGN.methods,
                        fading=Fading('rician', 3.0))
    with pytest.raises(Exception, match='fading'):
        open_table(out, other)


@pytest.mark.parametrize('argv, match', [
    (['--fading-samples', '10'], 'needs --fading'),
    (['--rician-k-db', '3'], 'needs --fading'),
    (['--fading', 'rician', '--fading-samples', '0'], 'samples'),
    (['--fading', 'rician', '--rician-k-db', '90'], 'Rician factor')])
def test_bad_fading_options_end_with_one_line_and_status_2(tmp_path, monkeypatch, argv, match):
    monkeypatch.chdir(tmp_path)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(['montecarlo', '--quick', '--out', 'study.csv', *argv])
    assert code == 2 and err.getvalue().count('\n') == 1 and match in err.getvalue()
