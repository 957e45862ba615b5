"""Altitude as a variable: the 3D step's bound (below the rate over the range, tight, concave),
the hover altitude against a one-dimensional search, plans that keep the range and the climb
limit and state what their trajectory, altitudes and power give, and the command line."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from test_channel import expected_gain

from uav_comm_planner import paper_scenario, Scenario, SolverSettings
from uav_comm_planner.core.altitude import (altitude_bound, AltitudeLimits,
                                            plan_with_altitude, snr_per_watt_3d)
from uav_comm_planner.core.model import snr_scale
from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.tools import cli

#: Where altitude matters: B = 1 MHz, -145 dBm/Hz, P_T = 0.1 W.
RADIO = dict(bandwidth_hz=1e6, noise_psd_dbm_per_hz=-145.0, power_budget_w=0.1)


def recomputed(env: str, q, h, p, scenario) -> float:
    """min_n (B/N) mean_m log2(1 + p N g / (B sigma^2)), g Al-Hourani's at (q[m], h[m])."""
    n_nodes, sigma2 = scenario.num_nodes, 10 ** ((scenario.noise_psd_dbm_per_hz - 30) / 10)
    rates = []
    for n, (wx, wy) in enumerate(scenario.ground_nodes_m):
        noise = scenario.bandwidth_hz * sigma2
        bits = sum(math.log2(1 + p[n][m] * n_nodes * expected_gain(
            env, scenario.reference_gain, x - wx, y - wy, h[m]) / noise)
            for m, (x, y) in enumerate(q))
        rates.append(scenario.bandwidth_hz / n_nodes * bits / len(q))
    return min(rates)


@pytest.mark.parametrize('limits, reason', [
    (((300.0, 30.0), 2.0), 'lowest <= highest'), (((0.0, 30.0), 2.0), '0 < lowest'),
    (((30.0, math.inf), 2.0), 'finite'), (((30.0,), 2.0), 'pair'),
    (((30.0, 60.0), 0.0), 'max_climb_mps'), (((30.0, 60.0), 'fast'), 'number')])
def test_bad_altitude_limits_are_a_typed_error(limits, reason):
    with pytest.raises(InvalidScenarioError, match=reason):
        AltitudeLimits(*limits)


@pytest.mark.parametrize('name', ['los:suburban', 'los:urban', 'los:highrise-urban',
                                  'free-space:alpha=2.5'])
def test_altitude_bound_is_below_the_rate_over_the_range_and_tight(name):
    scenario = paper_scenario('I', channel=name, **RADIO)
    limits = AltitudeLimits((30.0, 400.0), 5.0)
    rng = np.random.default_rng(3)
    q_k = np.vstack([scenario.nodes, rng.uniform(-200.0, 2200.0, (7, 2))])
    h_k = rng.uniform(30.0, 400.0, 10)
    h_k[0] = 30.0
    p = 10.0 ** rng.uniform(-4.0, -1.0, (3, 10))
    bound = altitude_bound(q_k, h_k, p, scenario, limits)
    for part in (bound.linear, bound.weight, bound.h_weight):
        assert np.all(part >= 0.0)                                     # concave in (q, h)
    true_k = np.log2(1 + p * snr_per_watt_3d(q_k, h_k, scenario))
    np.testing.assert_allclose(bound.at(q_k, h_k, scenario), true_k, rtol=1e-12, atol=1e-12)
    # Every slot against a grid of horizontal distances and altitudes within the range.
    rho = np.concatenate([[0.0], np.geomspace(0.1, 3e4, 400)])
    heights = np.linspace(30.0, 400.0, 149)
    c = p * snr_scale(scenario)
    gain = scenario.channel_model.gain(rho[:, None] ** 2, heights[None, :])    # (R, H)
    true = np.log2(1 + c[..., None, None] * gain)
    lower = (bound.constant[..., None, None] - bound.linear[..., None, None] * rho[:, None]
             - bound.weight[..., None, None] * rho[:, None] ** 2
             + bound.h_linear[..., None, None] * heights - bound.h_weight[..., None, None]
             * heights ** 2)
    assert (lower - true).max() <= 1e-9


def hover_scenario(name: str, r: float) -> Scenario:
    """One node at horizontal distance r from a UAV held at (0, 0)."""
    return Scenario(ground_nodes_m=((r, 0.0),), start_m=(0.0, 0.0), goal_m=(0.0, 0.0),
                    max_speed_mps=0.01, horizon_s=20.0, num_slots=10, channel=name, **RADIO)


def best_altitude(scenario: Scenario, low: float, high: float) -> float:
    """The altitude of the highest gain at the node's distance: a search every centimetre."""
    (r, _), = scenario.ground_nodes_m
    heights = np.arange(low, high, 0.01)
    env = scenario.channel[4:]
    return float(heights[np.argmax([expected_gain(env, 1.0, r, 0.0, h) for h in heights])])


@pytest.mark.parametrize('name, r', [('los:suburban', 300.0), ('los:urban', 300.0),
                                     ('los:dense-urban', 200.0), ('los:highrise-urban', 300.0)])
def test_hover_altitude_is_the_one_dimensional_search_s(name, r):
    scenario = hover_scenario(name, r)
    result = plan_with_altitude(scenario, AltitudeLimits((20.0, 800.0), 5.0))
    best = best_altitude(scenario, 20.0, 800.0)
    assert 20.0 + 5.0 < best < 800.0 - 5.0                   # a trade-off, not an end
    assert np.abs(result.altitudes - best).max() <= 5.0


@pytest.mark.parametrize('name', ['los:suburban', 'los:urban'])
def test_the_altitude_steps_climb_from_the_lowest_to_the_best(name):
    """Started at the lowest altitude, the SCA itself finds the best hover altitude."""
    scenario = hover_scenario(name, 300.0)
    result = plan_with_altitude(
        scenario, AltitudeLimits((20.0, 800.0), 100.0),
        SolverSettings(relative_tolerance=1e-9, max_inner_iterations=400), start_altitude_m=20.0)
    assert result.fixed_altitude_m == 20.0
    assert np.abs(result.altitudes - best_altitude(scenario, 20.0, 800.0)).max() <= 5.0
    assert all(b >= a for a, b in zip(result.history, result.history[1:]))


def test_a_three_dimensional_plan_keeps_its_limits_and_states_its_throughput():
    scenario = paper_scenario('I', channel='los:urban', **RADIO)
    limits = AltitudeLimits((30.0, 300.0), 5.0)
    result = plan_with_altitude(scenario, limits)
    h = result.altitudes
    assert h.min() >= 30.0 - 1e-9 and h.max() <= 300.0 + 1e-9
    assert np.abs(np.diff(h)).max() <= 5.0 * scenario.slot_s + 1e-6
    assert np.linalg.norm(np.diff(np.vstack([scenario.start_m, result.trajectory,
                                             scenario.goal_m]), axis=0), axis=1).max() \
        <= scenario.max_step_m * (1 + 1e-9)
    assert all(b >= a for a, b in zip(result.history, result.history[1:]))
    assert result.min_throughput >= result.fixed.min_throughput
    assert result.min_throughput > result.fixed.min_throughput * 1.005   # altitude pays here
    assert h.max() - h.min() > 5.0
    assert result.min_throughput == pytest.approx(recomputed(
        'urban', result.trajectory.tolist(), h.tolist(), result.power.tolist(), scenario),
        rel=1e-6)


def test_a_step_that_stalls_clarabel_at_its_defaults_is_solved_with_the_next_settings():
    # At 1 m/s of climb this case's altitude step stalls Clarabel's defaults mid-way through
    # Algorithm 1; the next settings (core.conic.CLARABEL_ATTEMPTS) solve it.
    scenario = paper_scenario('I', channel='los:urban', max_speed_mps=10.0, horizon_s=400.0,
                              num_slots=50, **RADIO)
    result = plan_with_altitude(scenario, AltitudeLimits((30.0, 120.0), 1.0))
    assert result.min_throughput >= result.fixed.min_throughput
    assert np.abs(np.diff(result.altitudes)).max() <= 1.0 * scenario.slot_s + 1e-6
    assert result.min_throughput == pytest.approx(recomputed(
        'urban', result.trajectory.tolist(), result.altitudes.tolist(), result.power.tolist(),
        scenario), rel=1e-6)


def test_free_space_stays_at_the_lowest_altitude():
    scenario = paper_scenario('I', num_slots=20, horizon_s=50.0, **RADIO)
    result = plan_with_altitude(scenario, AltitudeLimits((40.0, 200.0), 5.0))
    np.testing.assert_allclose(result.altitudes, 40.0, atol=1e-6)
    assert result.fixed_altitude_m == 40.0


def test_command_line_altitude_range_and_json(tmp_path, capsys):
    result_file = tmp_path / 'r.json'
    status = cli.main(['plan', '--nodes', '300,0', '--start', '0,0', '--goal', '0,0',
                       '--speed', '0.01', '--horizon', '20', '--slots', '10',
                       '--bandwidth', '1e6', '--noise-dbm', '-145', '--budget', '0.1',
                       '--channel', 'los:urban', '--altitude-range', '20,800',
                       '--climb-rate', '5', '--json', str(result_file)])
    out, _ = capsys.readouterr()
    assert status == 0 and 'best fixed altitude' in out
    data = json.loads(result_file.read_text())
    assert len(data['altitudes_m']) == 10 and data['scenario']['channel'] == 'los:urban'
    scenario = hover_scenario('los:urban', 300.0)
    assert max(abs(h - best_altitude(scenario, 20.0, 800.0)) for h in data['altitudes_m']) <= 5
    assert data['min_throughput'] == pytest.approx(recomputed(
        'urban', data['trajectory'], data['altitudes_m'], data['power'], scenario), rel=1e-6)


@pytest.mark.parametrize('argv, reason', [
    (['--climb-rate', '3'], 'needs --altitude-range'),
    (['--altitude-range', '30,300', '--figure', 'f.png'], 'does not combine'),
    (['--altitude-range', '30,300', '--mission', 'm.waypoints', '--speed', '10',
      '--horizon', '400', '--climb-rate', '2.5'], 'WPNAV_SPEED_DN'),
    (['--altitude-range', '30,300', '--mission', 'm.waypoints', '--speed', '10',
      '--horizon', '400', '--firmware', 'px4', '--climb-rate', '1'], 'ardupilot only'),
    (['--altitude-range', '300,30'], 'lowest <= highest'),
    (['--altitude-range', '30'], 'MIN,MAX')])
def test_command_line_refuses_bad_altitude_options_in_one_line(argv, reason, capsys, tmp_path,
                                                               monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert cli.main(['plan', *argv]) == 2
    err = capsys.readouterr()[1]
    assert len(err.strip().splitlines()) == 1 and reason in err
