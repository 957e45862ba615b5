"""Several UAVs on orthogonal channels: the fleet's plan, checked against the model recomputed
with numpy, its constraints, its power step against the conic solver's, and its guarantee."""

import itertools
import math

import cvxpy as cp
import numpy as np
import pytest

from devtools.fleet_flight import fly_fleet, LinkCut
from uav_comm_planner.core.drops import random_scenario
from uav_comm_planner.core.fleet import FleetScenario, FleetSettings, plan_fleet
from uav_comm_planner.core.fleet.model import fleet_snr
from uav_comm_planner.core.fleet.power import (coordinate_power, fleet_dual_bound,
                                               joint_power)
from uav_comm_planner.core.fleet.separation import separation_rows
from uav_comm_planner.core.fleet.starts import partition, separate, straight_lines
from uav_comm_planner.core.fleet.step import FleetStep, step_clarabel, step_cvxpy
from uav_comm_planner.core.optimizer import plan
from uav_comm_planner.core.scenario import paper_scenario, SolverSettings
from uav_comm_planner.errors import ComputeBudgetError, InvalidScenarioError


def rates_by_hand(q, p, fleet):
    """R_n = (B/N) sum_k (1/M) sum_m log2(1 + p_{k,n}[m] N beta0 / (B sigma2 d_{k,n}[m])),
    written from the model's definition, loop by loop, with none of the package's model."""
    s = fleet.scenario
    sigma2 = 10 ** ((s.noise_psd_dbm_per_hz - 30) / 10)
    n_nodes, m_slots = s.num_nodes, s.num_slots
    rates = np.zeros(n_nodes)
    for k in range(q.shape[0]):
        for n, (x, y) in enumerate(s.ground_nodes_m):
            for m in range(m_slots):
                d = (q[k, m, 0] - x) ** 2 + (q[k, m, 1] - y) ** 2 + s.altitude_m ** 2
                snr = p[k, n, m] * n_nodes * s.reference_gain / (s.bandwidth_hz * sigma2 * d)
                rates[n] += s.bandwidth_hz / n_nodes * math.log2(1 + snr) / m_slots
    return rates


def check_plan(result):
    """Every constraint of the fleet's problem on the plan, and its stated figures."""
    fleet, q, p = result.fleet, result.trajectories, result.power
    s = fleet.scenario
    assert q.shape == (fleet.num_uavs, s.num_slots, 2)
    assert p.shape == (fleet.num_uavs, s.num_nodes, s.num_slots)
    by_hand = rates_by_hand(q, p, fleet)
    assert np.allclose(result.rates, by_hand, rtol=1e-12, atol=0)
    assert result.min_throughput == pytest.approx(by_hand.min(), rel=1e-12)
    assert result.history[-1].min_throughput == pytest.approx(result.min_throughput, rel=1e-9)
    for j, k in itertools.combinations(range(fleet.num_uavs), 2):
        assert np.linalg.norm(q[j] - q[k], axis=1).min() >= fleet.min_separation_m
    for k in range(fleet.num_uavs):
        path = np.vstack([fleet.starts_m[k], q[k], fleet.goals_m[k]])
        assert np.linalg.norm(np.diff(path, axis=0), axis=1).max() <= s.max_step_m
        assert p[k].min() >= 0 and p[k].sum() <= s.power_budget_w
    values = [step.min_throughput for step in result.history]
    assert all(b >= a for a, b in zip(values, values[1:]))


@pytest.fixture(scope='module')
def two_uavs():
    """The letter's three nodes, two UAVs from (0, 0) and (0, 500) to (2000, 0) and
    (2000, 500), 100 m apart at least."""
    fleet = FleetScenario(paper_scenario('I'), ((0, 0), (0, 500)), ((2000, 0), (2000, 500)),
                          100.0)
    return plan_fleet(fleet)


def test_the_fleet_plan_keeps_every_constraint_and_states_its_rates(two_uavs):
    check_plan(two_uavs)


@pytest.mark.parametrize('uav', [-1, 2])
def test_a_link_cut_on_a_vehicle_the_fleet_lacks_is_refused_before_flying(
        two_uavs, tmp_path, uav):
    with pytest.raises(InvalidScenarioError, match=f'UAV {uav + 1} of a fleet of 2'):
        fly_fleet(two_uavs, tmp_path, home=None, cut=LinkCut(uav, 60.0, 20.0))
    assert list(tmp_path.iterdir()) == []


def test_two_uavs_serve_at_least_the_better_single_uav_plan(two_uavs):
    """Each UAV's single-UAV plan over all nodes from its own ends, computed here again."""
    fleet = two_uavs.fleet
    singles = [plan(fleet.vehicle(k), FleetSettings().single).min_throughput
               for k in range(2)]
    assert two_uavs.single_throughputs == pytest.approx(
        {'single 1': singles[0], 'single 2': singles[1]}, rel=1e-12)
    assert not two_uavs.left_out
    assert two_uavs.min_throughput >= max(singles)
    # On orthogonal channels, two UAVs give each node two bands: well above one UAV.
    assert two_uavs.min_throughput > 1.5 * max(singles)


def test_the_separation_binds_somewhere_when_the_uavs_would_meet():
    """Both UAVs from one side to the other over a single node: alone, each would hover over
    it; kept 300 m apart, neither reaches it, and the rows hold at d_min."""
    base = paper_scenario('I', ground_nodes_m=((1000.0, 250.0),), power_budget_w=1.0)
    fleet = FleetScenario(base, ((0, 0), (0, 500)), ((2000, 0), (2000, 500)), 300.0)
    result = plan_fleet(fleet)
    check_plan(result)
    gap = np.linalg.norm(result.trajectories[0] - result.trajectories[1], axis=1)
    assert gap.min() == pytest.approx(300.0, abs=0.05)


def test_three_uavs_over_a_random_drop():
    base = random_scenario(8, 40, 3, side_m=1500.0, horizon_s=60.0, max_speed_mps=60.0)
    fleet = FleetScenario(base, ((0, 0), (750, 0), (1500, 0)),
                          ((0, 1500), (750, 1500), (1500, 1500)), 120.0)
    result = plan_fleet(fleet, FleetSettings(single=SolverSettings(screened_tours=4)))
    check_plan(result)
    assert result.min_throughput >= max(result.single_throughputs.values())


def test_the_joint_power_step_equals_a_conic_program_written_here():
    """max t s.t. sum_k mean_m log2(1 + p a) >= t, per-UAV budgets: cvxpy on p itself."""
    rng = np.random.default_rng(7)
    a = 10 ** rng.uniform(-1, 2, size=(2, 3, 12))       # SNRs of order one: p matters
    budget = 2.0
    allocation = joint_power(a, budget)
    p = cp.Variable((2, 3 * 12), nonneg=True)
    t = cp.Variable()
    rates = sum(cp.sum(cp.reshape(cp.log(1 + cp.multiply(a[k].ravel(), p[k])) / math.log(2),
                                  (3, 12), order='C'), axis=1) / 12 for k in range(2))
    problem = cp.Problem(cp.Maximize(t), [rates >= t, cp.sum(p, axis=1) <= budget])
    problem.solve(solver='CLARABEL')
    assert allocation.efficiency == pytest.approx(problem.value, rel=1e-6)
    assert allocation.p.sum(axis=(1, 2)) == pytest.approx([budget, budget], rel=1e-9)
    # The coordinate sweeps never beat it; the dual bound is above both.
    fast = coordinate_power(a, budget)
    assert fast.efficiency <= allocation.efficiency * (1 + 1e-9)
    assert fleet_dual_bound(a, budget, np.ones(3), np.ones(2)) >= allocation.efficiency


def test_the_coordinate_step_is_each_uavs_own_optimum_given_the_others():
    """Its answer: no UAV alone can raise the minimum (each UAV's part solved by cvxpy with
    the others fixed)."""
    rng = np.random.default_rng(2)
    a = 10 ** rng.uniform(0, 2, size=(2, 3, 8))
    budget = 1.0
    p = coordinate_power(a, budget).p
    for k in range(2):
        others = sum(np.log2(1 + a[j] * p[j]).mean(axis=1) for j in range(2) if j != k)
        x = cp.Variable((3, 8), nonneg=True)
        t = cp.Variable()
        own = cp.sum(cp.log(1 + cp.multiply(a[k], x)), axis=1) / (8 * math.log(2))
        problem = cp.Problem(cp.Maximize(t), [own + others >= t, cp.sum(x) <= budget])
        problem.solve(solver='CLARABEL')
        total = sum(np.log2(1 + a[j] * p[j]).mean(axis=1) for j in range(2))
        assert total.min() == pytest.approx(problem.value, rel=1e-6)


def test_a_separation_row_implies_the_separation_whatever_its_direction():
    fleet = FleetScenario(paper_scenario('I'), ((0, 0), (0, 500)), ((2000, 0), (2000, 500)),
                          100.0)
    rng = np.random.default_rng(0)
    expansion = rng.normal(scale=300.0, size=(2, 50, 2))
    rows = separation_rows(expansion, fleet)
    for _ in range(200):
        q = rng.normal(scale=300.0, size=(2, 50, 2))
        kept = rows.slack(q)[0] >= 0
        assert np.all(np.linalg.norm(q[0] - q[1], axis=1)[kept] >= 100.0)
    # At the expansion point itself, each row holds exactly when the pair is d_min apart.
    gap = np.linalg.norm(expansion[0] - expansion[1], axis=1)
    assert np.array_equal(rows.slack(expansion)[0] >= 0, gap >= 100.0 + 1e-3)


def test_the_push_apart_separates_crossing_lines_and_holds_a_fixed_uav():
    base = paper_scenario('I')
    fleet = FleetScenario(base, ((0, 0), (0, 500)), ((2000, 500), (2000, 0)), 150.0)
    crossing = straight_lines(fleet)
    assert np.linalg.norm(crossing[0] - crossing[1], axis=1).min() < 150.0
    pushed = separate(crossing, fleet, fixed=(0,))
    assert pushed is not None
    assert np.array_equal(pushed[0], crossing[0])
    assert np.linalg.norm(pushed[0] - pushed[1], axis=1).min() >= 150.0
    path = np.vstack([fleet.starts_m[1], pushed[1], fleet.goals_m[1]])
    assert np.linalg.norm(np.diff(path, axis=0), axis=1).max() <= base.max_step_m


def test_partition_gives_every_uav_the_nodes_near_its_path():
    base = paper_scenario('I', ground_nodes_m=((100, 0), (200, 50), (1900, 480), (1800, 500)))
    fleet = FleetScenario(base, ((0, 0), (0, 500)), ((300, 0), (2000, 500)), 0.0)
    assert partition(fleet) == [[0, 1], [2, 3]]
    lonely = FleetScenario(base, ((0, 0), (0, 0)), ((0, 0), (0, 0)), 0.0)
    assert sorted(len(group) for group in partition(lonely)) == [1, 3]


@pytest.mark.parametrize('change, message', [
    (dict(starts_m=((0, 0),)), 'one goal per UAV'),
    (dict(starts_m=((0, 0), (0, 50)), goals_m=((2000, 0), (2000, 500))), 'starts of UAV 1'),
    (dict(min_separation_m=-1.0), 'min_separation_m'),
    (dict(min_separation_m=math.nan), 'min_separation_m'),
    (dict(starts_m=((0, 0), (0, 'a'))), 'must be a number'),
    (dict(starts_m=(), goals_m=()), '1 to 8 UAVs'),
    (dict(goals_m=((2000, 0), (9000, 500))), 'goal unreachable'),
])
def test_bad_fleets_are_refused_with_a_typed_error(change, message):
    fields = dict(scenario=paper_scenario('I'), starts_m=((0, 0), (0, 500)),
                  goals_m=((2000, 0), (2000, 500)), min_separation_m=100.0)
    fields.update(change)
    with pytest.raises(InvalidScenarioError, match=message):
        FleetScenario(**fields)


def test_bad_settings_are_refused():
    with pytest.raises(InvalidScenarioError, match='power_method'):
        FleetSettings(power_method='guess')
    with pytest.raises(InvalidScenarioError, match='starts'):
        FleetSettings(starts=('nowhere',))
    with pytest.raises(InvalidScenarioError, match='FleetScenario'):
        plan_fleet(paper_scenario('I'))
    fleet = FleetScenario(paper_scenario('I'), ((0, 0), (0, 500)), ((2000, 0), (2000, 500)))
    with pytest.raises(ComputeBudgetError, match='K x N x M = 2 UAVs x 3 nodes x 50 slots'):
        plan_fleet(fleet, FleetSettings(single=SolverSettings(max_node_slots=200)))


def test_one_uav_is_the_single_uav_plan_or_better():
    """K = 1: the fleet's loop from the single plan of all nodes; no separation rows."""
    fleet = FleetScenario(paper_scenario('II'), ((0, 0),), ((2000, 500),), 0.0)
    result = plan_fleet(fleet)
    check_plan(result)
    single = plan(fleet.vehicle(0), FleetSettings().single)
    # The conic power step meets the water-filling's optimum to its certified 1e-8.
    assert result.min_throughput >= single.min_throughput * (1 - 1e-8)
    assert result.min_throughput == pytest.approx(single.min_throughput, rel=1e-3)
    alone = plan_fleet(fleet, FleetSettings(starts=('single',)))
    assert alone.start == 'single 1' and alone.single_throughputs['single 1'] == pytest.approx(
        single.min_throughput, rel=1e-12)


def test_without_separation_two_uavs_may_meet_and_the_coordinate_power_serves():
    fleet = FleetScenario(paper_scenario('I'), ((0, 0), (0, 0)), ((2000, 0), (2000, 0)), 0.0)
    result = plan_fleet(fleet, FleetSettings(power_method='coordinate'))
    check_plan(result)
    assert result.min_throughput >= max(result.single_throughputs.values())


def steps_of_both_solvers(fleet: FleetScenario, q: np.ndarray):
    """One step from q by each solver: the data, and per solver z (K, M, 2) km and min_n of the
    summed bounds (each UAV's bound rows evaluated here at its z)."""
    p = joint_power(fleet_snr(q, fleet), fleet.scenario.power_budget_w).p
    step = FleetStep(fleet)
    data = step.data(q, p)
    w = step.frames[0].nodes
    answers = []
    for solve in (step_clarabel, step_cvxpy):
        z = solve(fleet, step.frames, step.rates, data)
        answers.append((z, sum(rows.values(z_k, w) for rows, z_k in zip(data.rows, z)).min()))
    start = sum(rows.values(step.frames[k].km(q[k]), w) for k, rows in enumerate(data.rows))
    return step, data, answers, start.min()


def test_the_clarabel_step_and_the_cvxpy_step_reach_the_same_bound():
    """One step from crossing-free straight lines, where the separation binds (300 m apart,
    one node between the lines): both solvers' answers give the same min_n of the summed
    bounds, computed here from each UAV's bound rows."""
    base = paper_scenario('I', ground_nodes_m=((1000.0, 250.0), (400.0, 100.0)))
    fleet = FleetScenario(base, ((0, 0), (0, 500)), ((2000, 0), (2000, 500)), 300.0)
    _, data, answers, start = steps_of_both_solvers(fleet, straight_lines(fleet))
    for z, _ in answers:
        assert np.linalg.norm(z[0] - z[1], axis=1).min() * 1000 >= 300.0
        slack = data.separation.slack(z)
        assert slack.min() > -1e-7 and slack.min() < 1e-6      # a separation row binds
    values = [value for _, value in answers]
    assert values[0] == pytest.approx(values[1], rel=1e-6)
    assert values[0] > start


def test_the_fleet_benchmark_reports_each_fleet_above_its_single_plans(capsys):
    from devtools import fleet_bench
    assert fleet_bench.main(['--quick']) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines()[1:]]
    assert [row[0] for row in rows] == ['1', '2', '3']
    for row in rows[1:]:
        assert float(row[3]) >= float(row[5]) and float(row[6]) >= 100.0


def test_in_wind_every_uav_keeps_its_airspeed():
    """8 m/s from the east, V_air = 30 m/s: every leg's ground velocity minus the wind within
    V_air (the leg block's airspeed cone, per UAV)."""
    base = paper_scenario('I', max_speed_mps=40.0, max_airspeed_mps=30.0, wind_speed_mps=8.0,
                          wind_from_deg=90.0, horizon_s=100.0)
    fleet = FleetScenario(base, ((0, 0), (0, 500)), ((2000, 0), (2000, 500)), 150.0)
    result = plan_fleet(fleet, FleetSettings(single=SolverSettings(screened_tours=4)))
    check_plan(result)
    wind = np.array([-8.0, 0.0])          # from the east: the air moves west
    for k in range(2):
        path = np.vstack([fleet.starts_m[k], result.trajectories[k], fleet.goals_m[k]])
        velocity = np.diff(path, axis=0) / base.slot_s
        assert np.linalg.norm(velocity - wind, axis=1).max() <= 30.0 * (1 + 1e-9)
    assert result.min_throughput >= max(result.single_throughputs.values())
