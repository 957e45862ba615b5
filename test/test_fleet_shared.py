"""Wu 2018's shared band: the rates against the definition written out, the schedule against
scipy's linear programming, every constraint on a plan, and the block ascent's monotony."""

import itertools
import math

import numpy as np
import pytest
from scipy.optimize import linprog

from uav_comm_planner.core.fleet import FleetScenario, plan_fleet
from uav_comm_planner.core.fleet.shared_band import (gains, link_rates, node_throughputs,
                                                     plan_shared_band, schedule_block)
from uav_comm_planner.core.scenario import paper_scenario
from uav_comm_planner.errors import InvalidScenarioError

#: Wu 2018's radio (sigma^2 = -110 dBm over the band, beta0 = -60 dB, P = 0.1 W on average),
#: H = 100 m, V = 50 m/s, on three nodes of a 2 km square, 30 slots of 2 s.
SLOTS = 30


def wu_fleet(count: int, separation: float = 100.0) -> FleetScenario:
    base = paper_scenario('I', ground_nodes_m=((300.0, 500.0), (1000.0, 1500.0),
                                               (1700.0, 600.0)),
                          altitude_m=100.0, max_speed_mps=50.0, horizon_s=2.0 * SLOTS,
                          num_slots=SLOTS, start_m=(0.0, 1000.0), goal_m=(2000.0, 1000.0),
                          noise_psd_dbm_per_hz=-110.0, reference_gain=1e-6,
                          power_budget_w=0.1 * SLOTS)
    if count == 1:
        return FleetScenario(base, ((0.0, 1000.0),), ((2000.0, 1000.0),), 0.0)
    return FleetScenario(base, ((0.0, 800.0), (0.0, 1200.0)),
                         ((2000.0, 800.0), (2000.0, 1200.0)), separation)


def throughputs_by_hand(alpha, p, q, fleet):
    """eta_n = (1/M) sum_m sum_k alpha log2(1 + p_k g_k / (1 + sum_{j != k} p_j g_j)), with
    g = beta0 / (B sigma^2 (H^2 + horizontal^2)), loop by loop."""
    s = fleet.scenario
    noise = s.bandwidth_hz * 10 ** ((s.noise_psd_dbm_per_hz - 30) / 10)
    k_count, n_count, m_count = alpha.shape
    eta = np.zeros(n_count)
    for n, (x, y) in enumerate(s.ground_nodes_m):
        for m in range(m_count):
            g = [s.reference_gain / (noise * ((q[k, m, 0] - x) ** 2 + (q[k, m, 1] - y) ** 2
                                              + s.altitude_m ** 2)) for k in range(k_count)]
            for k in range(k_count):
                others = sum(p[j, m] * g[j] for j in range(k_count) if j != k)
                eta[n] += alpha[k, n, m] * math.log2(1 + p[k, m] * g[k] / (1 + others))
    return eta / m_count


@pytest.fixture(scope='module')
def plans():
    fleet = wu_fleet(2)
    start = plan_fleet(fleet).trajectories
    without = plan_shared_band(fleet, start, power_control=False)
    with_control = plan_shared_band(fleet, without.trajectories, power=without.power)
    single_fleet = wu_fleet(1)
    single = plan_shared_band(single_fleet, plan_fleet(single_fleet).trajectories)
    return without, with_control, single


def test_the_rates_are_the_definition():
    fleet = wu_fleet(2)
    rng = np.random.default_rng(3)
    q = rng.uniform(0, 2000, size=(2, SLOTS, 2))
    p = rng.uniform(0, 0.2, size=(2, SLOTS))
    alpha = rng.uniform(0, 0.5, size=(2, 3, SLOTS))
    assert np.allclose(node_throughputs(alpha, p, q, fleet),
                       throughputs_by_hand(alpha, p, q, fleet), rtol=1e-12)


def test_the_schedule_is_the_linear_programs_optimum():
    """scipy's HiGHS on the same LP, written with its own matrices."""
    rng = np.random.default_rng(1)
    rates = rng.uniform(0, 5, size=(2, 3, 8))
    alpha = schedule_block(rates)
    k, n, m = rates.shape
    size = k * n * m
    cost = np.zeros(size + 1)
    cost[-1] = -1.0                                   # maximise t
    rows, bounds = [], []
    for node in range(n):                             # t - (1/M) sum alpha r <= 0
        row = np.zeros(size + 1)
        for uav in range(k):
            row[[uav * n * m + node * m + slot for slot in range(m)]] = -rates[uav, node] / m
        row[-1] = 1.0
        rows.append(row)
        bounds.append(0.0)
    for uav, slot in itertools.product(range(k), range(m)):      # one node per UAV
        row = np.zeros(size + 1)
        row[[uav * n * m + node * m + slot for node in range(n)]] = 1.0
        rows.append(row)
        bounds.append(1.0)
    for node, slot in itertools.product(range(n), range(m)):     # one UAV per node
        row = np.zeros(size + 1)
        row[[uav * n * m + node * m + slot for uav in range(k)]] = 1.0
        rows.append(row)
        bounds.append(1.0)
    reference = linprog(cost, A_ub=np.array(rows), b_ub=bounds,
                        bounds=[(0, 1)] * size + [(None, None)], method='highs')
    value = ((alpha * rates).sum(axis=0).mean(axis=1)).min()
    assert value == pytest.approx(-reference.fun, rel=1e-6)


def test_every_plan_keeps_its_constraints_and_states_its_throughput(plans):
    for plan in plans:
        fleet, q, p, alpha = plan.fleet, plan.trajectories, plan.power, plan.schedule
        s = fleet.scenario
        by_hand = throughputs_by_hand(alpha, p, q, fleet)
        assert np.allclose(plan.throughputs, by_hand, rtol=1e-10)
        assert plan.min_throughput == pytest.approx(by_hand.min(), rel=1e-10)
        assert alpha.min() >= 0 and alpha.max() <= 1
        assert alpha.sum(axis=1).max() <= 1 + 1e-6 and alpha.sum(axis=0).max() <= 1 + 1e-6
        assert p.min() >= 0 and np.all(p.sum(axis=1) <= s.power_budget_w * (1 + 1e-9))
        for k in range(fleet.num_uavs):
            path = np.vstack([fleet.starts_m[k], q[k], fleet.goals_m[k]])
            assert np.linalg.norm(np.diff(path, axis=0), axis=1).max() <= s.max_step_m
        for j, k in fleet.pairs:
            assert np.linalg.norm(q[j] - q[k], axis=1).min() >= fleet.min_separation_m
        values = [value for _, value in plan.history]
        assert all(b >= a for a, b in zip(values, values[1:]))
        assert plan.history[-1][1] == pytest.approx(plan.min_throughput, rel=1e-9)


def test_wu_s_trend_power_control_above_none_and_two_uavs_above_one(plans):
    without, with_control, single = plans
    assert not without.power_control and np.allclose(without.power, 0.1)
    assert with_control.min_throughput >= without.min_throughput
    assert without.min_throughput > single.min_throughput
    # Interference is real: the two UAVs' SINRs are below their SNRs somewhere it matters.
    rates = link_rates(with_control.power, gains(with_control.trajectories, with_control.fleet))
    alone = np.log2(1 + with_control.power[:, None, :]
                    * gains(with_control.trajectories, with_control.fleet))
    assert np.any((with_control.schedule > 0.5) & (rates < 0.99 * alone))


def test_a_start_that_breaks_the_separation_is_refused():
    fleet = wu_fleet(2)
    together = np.zeros((2, SLOTS, 2)) + np.linspace(0, 2000, SLOTS)[None, :, None]
    with pytest.raises(InvalidScenarioError, match='kept 100 m apart'):
        plan_shared_band(fleet, together)
    with pytest.raises(InvalidScenarioError, match='power must be'):
        plan_shared_band(fleet, plan_fleet(fleet).trajectories, power=np.ones((2, SLOTS)))
