"""Channels by name: the gains against Al-Hourani's formula written out here, the trajectory
step's bound (below the rate everywhere, equal at the expansion point, concave), plans whose
stated throughput is recomputed independently, the command line and the node's parameter."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from uav_comm_planner import paper_scenario, plan, SolverSettings
from uav_comm_planner.core.channel import channel_names, ENVIRONMENTS, parse_channel
from uav_comm_planner.core.model import snr_per_watt, snr_scale
from uav_comm_planner.core.power import waterfilling_power
from uav_comm_planner.core.sca.channel_bound import channel_coefficients, channel_lower_bound
from uav_comm_planner.core.sca.fast import trajectory_step_clarabel
from uav_comm_planner.core.sca.reference import trajectory_step_cvxpy
from uav_comm_planner.core.sca.surrogate import sca_lower_bound
from uav_comm_planner.errors import InvalidChannelError, InvalidScenarioError
from uav_comm_planner.tools import cli

LOS = [f'los:{env}' for env in ENVIRONMENTS]
#: Al-Hourani's Table (a, b, eta_LoS dB, eta_NLoS dB), typed in again from the paper.
TABLE = {'suburban': (4.88, 0.43, 0.1, 21), 'urban': (9.61, 0.16, 1.0, 20),
         'dense-urban': (12.08, 0.11, 1.6, 23), 'highrise-urban': (27.23, 0.08, 2.3, 34)}


def expected_gain(env: str, beta0: float, x: float, y: float, h: float) -> float:
    """beta0 / d^2 (P_LoS 10^(-eta_LoS/10) + (1 - P_LoS) 10^(-eta_NLoS/10)), one point."""
    a, b, eta_los, eta_nlos = TABLE[env]
    horizontal = math.hypot(x, y)
    theta = math.degrees(math.atan2(h, horizontal))
    p_los = 1.0 / (1.0 + a * math.exp(-b * (theta - a)))
    d2 = horizontal ** 2 + h ** 2
    return beta0 / d2 * (p_los * 10 ** (-eta_los / 10) + (1 - p_los) * 10 ** (-eta_nlos / 10))


def recomputed_min_throughput(env: str, q, p, scenario) -> float:
    """min_n (B/N) mean_m log2(1 + p_n[m] N g_n[m] / (B sigma^2)), loop by loop."""
    n_nodes, sigma2 = scenario.num_nodes, 10 ** ((scenario.noise_psd_dbm_per_hz - 30) / 10)
    rates = []
    for n, (wx, wy) in enumerate(scenario.ground_nodes_m):
        bits = 0.0
        for m, (x, y) in enumerate(q):
            g = expected_gain(env, scenario.reference_gain, x - wx, y - wy, scenario.altitude_m)
            bits += math.log2(1 + p[n][m] * n_nodes * g / (scenario.bandwidth_hz * sigma2))
        rates.append(scenario.bandwidth_hz / n_nodes * bits / len(q))
    return min(rates)


@pytest.mark.parametrize('name, canonical', [
    ('free-space', 'free-space'), (' Free-Space ', 'free-space'),
    ('free-space:alpha=2', 'free-space'), ('free-space:alpha=2.5', 'free-space:alpha=2.5'),
    ('los:urban', 'los:urban'), ('LOS:highrise-urban', 'los:highrise-urban')])
def test_channel_names_parse_to_their_canonical_form(name, canonical):
    assert parse_channel(name).name == canonical
    assert paper_scenario('I', channel=name).channel == canonical


@pytest.mark.parametrize('name, reason', [
    ('los:rural', 'unknown channel'), ('fading', 'unknown channel'), ('', 'unknown channel'),
    ('free-space:alpha=0', r'in \(0, 10\]'), ('free-space:alpha=nan', r'in \(0, 10\]'),
    ('free-space:alpha=x', 'must be a number'), ('free-space:beta=2', "'alpha=A'"),
    (3, 'must be a name')])
def test_bad_channel_names_are_a_typed_error(name, reason):
    with pytest.raises(InvalidChannelError, match=reason):
        parse_channel(name)
    with pytest.raises(InvalidScenarioError, match=reason):
        paper_scenario('I', channel=name)


@pytest.mark.parametrize('env', list(TABLE))
def test_line_of_sight_gain_is_al_hourani_s_expected_gain(env):
    scenario = paper_scenario('I', channel=f'los:{env}', altitude_m=80.0)
    q = np.array([[200.0, 400.0], [230.0, 380.0], [1000.0, 0.0], [-500.0, 900.0]])
    a = snr_per_watt(q, scenario)
    for n, (wx, wy) in enumerate(scenario.ground_nodes_m):
        for m, (x, y) in enumerate(q):
            g = expected_gain(env, 1e-3, x - wx, y - wy, 80.0)
            assert a[n, m] == pytest.approx(snr_scale(scenario) / 1e-3 * g, rel=1e-12)


def test_path_loss_exponent_and_the_letter_s_channel():
    q = np.array([[0.0, 0.0], [1500.0, 300.0]])
    letter = paper_scenario('I')
    alpha = paper_scenario('I', channel='free-space:alpha=3')
    d2 = ((q[None] - letter.nodes[:, None]) ** 2).sum(axis=-1) + 100.0 ** 2
    np.testing.assert_array_equal(snr_per_watt(q, letter), snr_scale(letter) / d2)
    np.testing.assert_allclose(snr_per_watt(q, alpha), snr_scale(alpha) * d2 ** -1.5,
                               rtol=1e-13)


@pytest.mark.parametrize('name', LOS + ['free-space:alpha=3.5'])
def test_rate_slope_is_the_derivative_of_the_rate(name):
    channel = parse_channel(name)
    rho = np.array([0.5, 10.0, 90.0, 400.0, 3000.0])
    for c in (1e3, 1e8, 1e12):
        _, slope = channel.rate_and_slope(rho, 70.0, c)
        step = 1e-4 * rho
        up, _ = channel.rate_and_slope(rho + step, 70.0, c)
        down, _ = channel.rate_and_slope(rho - step, 70.0, c)
        np.testing.assert_allclose(slope, (up - down) / (2 * step), rtol=1e-5)


@pytest.mark.parametrize('name', LOS)
def test_the_rate_is_convex_in_the_squared_horizontal_distance(name):
    """The property that keeps the letter's tangent in s a global bound, and so bounds the
    curvature term from above: checked on a dense grid of altitudes, distances and SNRs."""
    channel = parse_channel(name)
    s = np.linspace(0.0, 3000.0 ** 2, 200001)
    for h in (20.0, 60.0, 150.0, 400.0):
        for snr_above in 10.0 ** np.arange(-3.0, 13.0, 1.0):
            rate, _ = channel.rate_and_slope(np.sqrt(s), h, snr_above * h * h)
            second = rate[2:] - 2 * rate[1:-1] + rate[:-2]
            assert second.min() >= -1e-12 * max(1.0, rate.max()), (h, snr_above)


@pytest.mark.parametrize('name', LOS)
@pytest.mark.parametrize('radio', [
    dict(), dict(bandwidth_hz=1e6, noise_psd_dbm_per_hz=-145.0, altitude_m=60.0)])
def test_bound_is_below_the_rate_everywhere_and_equal_at_the_point(name, radio):
    scenario = paper_scenario('I', channel=name, **radio)
    rng = np.random.default_rng(7)
    q_k = np.vstack([scenario.nodes, scenario.nodes[1] + [0.2, 0.0],
                     rng.uniform(-300.0, 2300.0, (46, 2))])
    p = 10.0 ** rng.uniform(-5.0, 0.7, (3, 50))
    p[0, 3] = 0.0
    coef = channel_coefficients(q_k, p, scenario)
    assert np.all(coef.linear >= 0.0) and np.all(coef.weight >= 0.0)     # concave in q
    true_k = np.log2(1.0 + p * snr_per_watt(q_k, scenario))
    np.testing.assert_allclose(channel_lower_bound(q_k, q_k, p, scenario), true_k,
                               rtol=1e-12, atol=1e-12)
    # Every slot against every horizontal distance out to 100 km (independent gain, not the
    # module's R), far denser than the module's own grid.
    rho = np.concatenate([[0.0], np.geomspace(1e-2, 1e5, 20000)])
    gain = np.array([expected_gain(name[4:], scenario.reference_gain, r, 0.0,
                                   scenario.altitude_m) for r in rho])
    snr = p[..., None] * (snr_scale(scenario) / scenario.reference_gain) * gain
    true = np.log2(1.0 + snr)
    bound = coef.constant[..., None] - coef.linear[..., None] * rho \
        - coef.weight[..., None] * rho ** 2
    assert (bound - true).max() <= 1e-9


def test_bound_s_slope_at_the_point_is_the_rate_s():
    scenario = paper_scenario('I', channel='los:dense-urban')
    q_k = np.array([[300.0, 500.0]] * 50)
    p = np.full((3, 50), 0.1)
    direction = np.array([0.6, 0.8])
    step = 1e-3
    rate = [np.log2(1 + p * snr_per_watt(q_k + t * direction, scenario)) for t in (-step, step)]
    bound = [channel_lower_bound(q_k + t * direction, q_k, p, scenario) for t in (-step, step)]
    np.testing.assert_allclose((bound[1] - bound[0]), (rate[1] - rate[0]), rtol=1e-4)


@pytest.mark.parametrize('name, slots', [('los:urban', 30), ('los:highrise-urban', 30),
                                         ('los:suburban', 100)])
def test_reference_and_fast_steps_agree_on_the_channel_block(name, slots):
    scenario = paper_scenario('I', channel=name, num_slots=slots, horizon_s=float(slots),
                              max_speed_mps=100.0)
    q_k = np.linspace(scenario.start_m, scenario.goal_m, slots + 2)[1:-1]
    q_k[10] = scenario.nodes[1]                         # one slot on a node's corner
    p = waterfilling_power(snr_per_watt(q_k, scenario), scenario.power_budget_w).p
    fast = trajectory_step_clarabel(q_k, p, scenario)
    reference = trajectory_step_cvxpy(q_k, p, scenario)
    assert fast.bound == pytest.approx(reference.bound, abs=1e-6)
    at_k = sca_lower_bound(q_k, q_k, p, scenario).mean(axis=1).min()
    assert fast.bound >= at_k - 1e-9                   # the step never loses on its bound
    true_new = np.log2(1 + p * snr_per_watt(fast.q, scenario)).mean(axis=1).min()
    assert true_new >= fast.bound - 1e-9               # the bound is below the true rate


@pytest.mark.parametrize('name', LOS)
def test_plan_states_the_throughput_its_trajectory_and_power_give(name):
    scenario = paper_scenario('II', channel=name)
    result = plan(scenario)
    q, p = result.trajectory, result.power
    assert result.min_throughput == pytest.approx(
        recomputed_min_throughput(name[4:], q.tolist(), p.tolist(), scenario), rel=1e-6)
    history = [step.min_throughput for step in result.history]
    assert all(b >= a - 1e-9 for a, b in zip(history, history[1:]))
    assert result.min_throughput <= result.upper_bound
    assert result.min_throughput >= result.baselines['straight'] - 1e-9


def test_a_worse_environment_gives_less():
    values = [plan(paper_scenario('I', channel=name),
                   SolverSettings.letter()).min_throughput for name in LOS]
    assert values == sorted(values, reverse=True)
    assert plan(paper_scenario('I'), SolverSettings.letter()).min_throughput > values[0]


def test_command_line_channel_flag_and_json(tmp_path, capsys):
    result_file = tmp_path / 'r.json'
    status = cli.main(['plan', '--case', 'I', '--channel', 'los:urban', '--json',
                       str(result_file)])
    out, _ = capsys.readouterr()
    assert status == 0 and 'channel los:urban' in out
    data = json.loads(result_file.read_text())
    assert data['scenario']['channel'] == 'los:urban'
    scenario = paper_scenario('I', channel='los:urban')
    assert data['min_throughput'] == pytest.approx(
        recomputed_min_throughput('urban', data['trajectory'], data['power'], scenario),
        rel=1e-6)
    # The result file is a scenario file: planned again on its own channel.
    assert cli.main(['plan', '--scenario', str(result_file)]) == 0
    assert 'channel los:urban' in capsys.readouterr()[0]


def test_command_line_refuses_a_bad_channel_in_one_line(capsys):
    status = cli.main(['plan', '--case', 'I', '--channel', 'los:moon'])
    out, err = capsys.readouterr()
    assert status == 2
    assert len(err.strip().splitlines()) == 1 and 'unknown channel' in err


def test_node_parameter_channel(harness):
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    h = harness()
    h.published(1)
    before = h.node.current_plan
    bad = Parameter('channel', value='los:moon').to_parameter_msg()
    answer = h.call('set_parameters', SetParameters.Request(parameters=[bad]))
    assert not answer.results[0].successful
    assert 'unknown channel' in answer.results[0].reason
    assert h.node.get_parameter('channel').value == 'free-space'
    assert h.node.current_plan is before
    good = Parameter('channel', value='los:suburban').to_parameter_msg()
    answer = h.call('set_parameters', SetParameters.Request(parameters=[good]))
    assert answer.results[0].successful, answer.results[0].reason
    h.published(2)
    assert h.node.current_plan.result.scenario.channel == 'los:suburban'


def test_every_name_listed_parses():
    for name in channel_names():
        assert parse_channel(name).name == name


@pytest.mark.parametrize('slots, partial_sums', [(150, True), (150, False), (40, True)])
def test_channel_block_rows_are_the_bound_minus_t(slots, partial_sums):
    """b - A x on the node rows equals mean_m lbr_{n,m}(q) - t for any q when u[m] and
    rho_{n,m} are the squared norm and the distances, and the cones' rows are their slacks."""
    from uav_comm_planner.core.sca.block import Expansion, Frame
    from uav_comm_planner.core.sca.channel_rates import ChannelRates
    from uav_comm_planner.core.sca.program import cone_program, step_blocks

    scenario = paper_scenario('I', channel='los:urban', num_slots=slots,
                              horizon_s=float(slots))
    frame = Frame.of(scenario)
    blocks = step_blocks(frame, partial_sums=partial_sums)
    rates = blocks[0]
    assert isinstance(rates, ChannelRates)
    assert (rates.num_sums > 0) == (partial_sums and slots > 64)
    program = cone_program(blocks)
    rng = np.random.default_rng(2)
    q_k = np.linspace(scenario.start_m, scenario.goal_m, slots + 2)[1:-1]
    q_k[5] = scenario.nodes[0]
    p = waterfilling_power(snr_per_watt(q_k, scenario), scenario.power_budget_w).p
    data = [block.at(Expansion(q_k, p)) for block in blocks]
    entries = np.concatenate([block.update(d)[0] for block, d in zip(blocks, data)])
    right = np.concatenate([block.update(d)[1] for block, d in zip(blocks, data)])
    values = program.values.copy()
    values[program.changing_build] = entries
    b = np.concatenate([block.right_hand_side() for block in blocks])
    b[program.changing_rows] = right
    a = program.matrix(values)
    q = q_k + rng.normal(scale=150.0, size=q_k.shape)
    z = frame.km(q)
    w = frame.nodes
    t = 2.3
    x = np.zeros(program.num_columns)
    x[0], x[1:1 + 2 * slots] = t, z.ravel()
    first = program.first_columns[0]
    x[first:first + slots] = (z ** 2).sum(axis=1)
    rho_first = first + slots + rates.num_sums
    distances = np.sqrt(((z[None] - w[:, None]) ** 2).sum(axis=-1))
    x[rho_first:rho_first + 3 * slots] = distances.ravel()
    block_rows = slice(rates.num_nodes, rates.num_nodes + rates.num_sums)
    x[first + slots:first + slots + rates.num_sums] = -(b - a @ x)[block_rows]
    slack = b - a @ x
    np.testing.assert_allclose(slack[block_rows], 0.0, atol=1e-12)
    expected = sca_lower_bound(q, q_k, p, scenario).mean(axis=1) - t
    np.testing.assert_allclose(slack[:rates.num_nodes], expected, rtol=1e-9, atol=1e-9)
    cones = slack[rates.num_nodes + rates.num_sums + 4 * slots:][:3 * 3 * slots].reshape(-1, 3)
    np.testing.assert_allclose(cones[:, 0], distances.ravel(), atol=1e-12)
    np.testing.assert_allclose(cones[:, 1:], (z[None] - w[:, None]).reshape(-1, 2),
                               atol=1e-12)
