"""Bad input of every kind: typed errors in the API, one-line refusals on the command line,
bounded cost before the limits, exact numbers at the edges and safe output files."""

from __future__ import annotations

import json
import math
import os
import stat
import tracemalloc

import numpy as np
import pytest

from uav_comm_planner import (ComputeBudgetError, InvalidScenarioError, MissionExportError,
                              paper_scenario, plan, PlanCancelledError, PlannerError, Scenario,
                              SolverSettings)
from uav_comm_planner.core.feasibility import project_onto_speed_limit
from uav_comm_planner.core.initial import straight_line
from uav_comm_planner.core.model import leg_lengths, snr_per_watt, spectral_efficiencies
from uav_comm_planner.core.power import waterfilling_power
from uav_comm_planner.files import NotARegularFileError, PARTIAL_MARK, write_text_atomic
from uav_comm_planner.tools import cli
from uav_comm_planner.vehicle.firmware import FIRMWARES
from uav_comm_planner.vehicle.flyable import schedule_flight
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink.files import export_mission
from uav_comm_planner.vehicle.mavlink.items import build_mission_items, NAV_WAYPOINT

SMALL = dict(num_slots=12, horizon_s=30.0)


def peak_bytes(function) -> int:
    """The peak of Python-allocated memory (numpy included) while ``function`` runs."""
    tracemalloc.start()
    try:
        function()
    except PlannerError:
        pass
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak


# API: strict types.

@pytest.mark.parametrize('changes, message', [
    ({'altitude_m': True}, 'altitude_m must be a number'),
    ({'altitude_m': '100'}, 'altitude_m must be a number'),
    ({'altitude_m': None}, 'altitude_m must be a number'),
    ({'noise_psd_dbm_per_hz': 'x'}, 'noise_psd_dbm_per_hz must be a number'),
    ({'start_m': '12'}, 'start_m must be a pair'),
    ({'start_m': (1.0, 2.0, 3.0)}, 'start_m must be a pair'),
    ({'goal_m': None}, 'goal_m must be a pair'),
    ({'ground_nodes_m': '12'}, 'ground_nodes_m must be a sequence'),
    ({'ground_nodes_m': [[1.0, '2']]}, 'ground node 1 must be a number'),
    ({'ground_nodes_m': [[1.0, True]]}, 'ground node 1 must be a number'),
    ({'ground_nodes_m': 5}, 'ground_nodes_m must be a sequence'),
    ({'num_slots': 50.0}, 'num_slots must be an integer'),
    ({'num_slots': True}, 'num_slots must be an integer'),
    ({'power_budget_w': 10 ** 400}, 'power_budget_w must be a finite number'),
])
def test_scenario_numbers_are_real_numbers_and_points_real_pairs(changes, message):
    with pytest.raises(InvalidScenarioError, match=message):
        paper_scenario('I', **changes)


@pytest.mark.parametrize('changes, message', [
    ({'starts': None}, 'starts must name'),
    ({'starts': [1]}, 'starts must name'),
    ({'tolerance_bps': '0.1'}, 'tolerance_bps must be a number'),
    ({'max_nodes': True}, 'max_nodes must be an integer'),
    ({'max_node_slots': 0}, 'max_node_slots must be an integer >= 1'),
    ({'compute_baselines': 'yes'}, 'compute_baselines must be True or False'),
    ({'shortlist': 0}, 'shortlist must be an integer from 1 to 100'),
    ({'shortlist': 2.0}, 'shortlist must be an integer from 1 to 100'),
    ({'shortlist': True}, 'shortlist must be an integer from 1 to 100'),
])
def test_solver_settings_are_strict(changes, message):
    with pytest.raises(InvalidScenarioError, match=message):
        SolverSettings(**changes)


@pytest.mark.parametrize('changes, message', [
    ({'altitude_m': 1e300}, 'H\\^2 .* overflows'),
    ({'noise_psd_dbm_per_hz': 1e6}, 'sigma\\^2 .* overflows'),
    ({'noise_psd_dbm_per_hz': -1e6}, 'sigma\\^2 .* is 0'),
    ({'bandwidth_hz': 5e-324}, 'N beta0 / \\(B sigma\\^2\\) is inf'),
    ({'power_budget_w': 1e300}, 'P_T a_max is inf'),
    ({'reference_gain': 1e-320, 'altitude_m': 1e10}, 'SNR per watt'),
    ({'start_m': (1e300, 0.0)}, 'out of range'),
    ({'max_speed_mps': 1e-300, 'goal_m': (0.0, 0.0)}, 'cannot move measurably'),
])
def test_derived_quantities_out_of_floating_point_range_are_refused(changes, message):
    with pytest.raises(InvalidScenarioError, match=message):
        paper_scenario('I', **changes)


def test_plan_refuses_what_is_not_a_scenario_and_unknown_methods():
    with pytest.raises(InvalidScenarioError, match='plan needs a Scenario, got NoneType'):
        plan(None)
    with pytest.raises(InvalidScenarioError, match='settings must be SolverSettings'):
        plan(paper_scenario(), 'fast')
    with pytest.raises(InvalidScenarioError, match="unknown method 'newton'"):
        plan(paper_scenario(), power_method='newton')
    with pytest.raises(InvalidScenarioError, match='methods are names'):
        plan(paper_scenario(), trajectory_method=['cvxpy'])
    with pytest.raises(InvalidScenarioError, match='should_stop must be callable'):
        plan(paper_scenario(), should_stop=True)


# Cost before the limits.

def test_a_huge_slot_count_is_refused_by_the_compute_budget_before_any_allocation():
    scenario = paper_scenario('I', num_slots=10 ** 18, horizon_s=1e18)
    with pytest.raises(ComputeBudgetError, match=r'3 nodes x 1000000000000000000 slots = '
                                                 r'3000000000000000000 exceeds the compute '
                                                 r'budget max_node_slots = 100000'):
        plan(scenario)
    assert peak_bytes(lambda: plan(scenario)) < 1_000_000
    small = paper_scenario('I', **SMALL)
    with pytest.raises(ComputeBudgetError, match='= 36 exceeds .* max_node_slots = 35'):
        plan(small, SolverSettings(max_node_slots=35))


def test_the_node_limit_comes_before_the_scenario_checks_and_duplicates_cost_n_log_n():
    from uav_comm_planner.ros.params import config_from_parameters
    count = 200_000
    flat = np.random.default_rng(1).uniform(-1e4, 1e4, 2 * count).tolist()
    with pytest.raises(InvalidScenarioError, match=f'{count} given, the limit max_nodes is 100'):
        config_from_parameters({'ground_nodes': flat})
    # 20 000 nodes: a pairwise check would need 20 000^2 x 16 bytes = 6.4 GB.
    nodes = np.random.default_rng(2).uniform(-1e5, 1e5, (20_000, 2))
    nodes[12_345] = nodes[777] + 1e-4
    with pytest.raises(InvalidScenarioError, match='node 778 and node 12346'):
        Scenario(ground_nodes_m=nodes, goal_m=(0.0, 0.0))
    peak = peak_bytes(lambda: Scenario(ground_nodes_m=nodes, goal_m=(0.0, 0.0)))
    print(f'duplicate check of 20 000 nodes: peak {peak / 1e6:.1f} MB')
    assert peak < 100e6


# Exact numbers at the edges.

def test_at_the_goals_maximum_reach_the_plan_is_the_straight_line_and_claims_no_gain():
    # ||qF - q0|| = 2000 m = (M + 1) V delta with M = 19, delta = 1 s, V = 100 m/s.
    scenario = paper_scenario('I', num_slots=19, horizon_s=19.0)
    assert math.dist(scenario.start_m, scenario.goal_m) == pytest.approx(
        20 * scenario.max_step_m, rel=1e-15)
    result = plan(scenario)
    assert leg_lengths(result.trajectory, scenario).max() <= scenario.max_step_m * (1 + 1e-12)
    np.testing.assert_allclose(result.trajectory, straight_line(scenario), atol=1e-9)
    assert result.min_throughput <= result.baselines['straight'] * (1 + 1e-12)


def test_projection_onto_the_speed_limit_moves_only_what_is_too_long():
    scenario = paper_scenario('II', **SMALL)
    rng = np.random.default_rng(3)
    base = straight_line(scenario) + rng.normal(0.0, 150.0, (scenario.num_slots, 2))
    # The wiggle breaks the limit, so the projection has work to do.
    assert leg_lengths(base, scenario).max() > scenario.max_step_m * 1.1
    feasible = project_onto_speed_limit(base, scenario)
    assert leg_lengths(feasible, scenario).max() <= scenario.max_step_m * (1 + 1e-12)
    # A path within the limit is returned exactly as it is.
    np.testing.assert_array_equal(project_onto_speed_limit(feasible, scenario), feasible)
    # A leg 5e-6 too long, as a solver's round-off leaves it, moves by about that much.
    stretched = feasible * (1 + 5e-6)
    projected = project_onto_speed_limit(stretched, scenario)
    assert leg_lengths(projected, scenario).max() <= scenario.max_step_m * (1 + 1e-12)
    assert np.abs(projected - stretched).max() < 1.0


def test_rates_at_low_snr_match_the_series_of_log2_1_plus_x():
    a = np.array([[1e-9, 3e-12], [2e-14, 5e-10]])
    p = np.array([[1e-6, 2e-3], [1.0, 1e-7]])
    x = p * a
    series = (x - x ** 2 / 2 + x ** 3 / 3) / math.log(2.0)   # exact to 1e-30 relative here
    np.testing.assert_allclose(spectral_efficiencies(a, p), series.mean(axis=1), rtol=1e-14)


def test_issue_case_beta0_1e_12_has_rates_exact_to_the_last_digits():
    scenario = paper_scenario('I', reference_gain=1e-12, bandwidth_hz=1e6,
                              power_budget_w=1e-9, **SMALL)
    result = plan(scenario, SolverSettings(compute_baselines=False))
    x = result.power * snr_per_watt(result.trajectory, scenario)
    series = (x - x ** 2 / 2 + x ** 3 / 3 - x ** 4 / 4) / math.log(2.0)
    rates = scenario.bandwidth_hz / scenario.num_nodes * series.mean(axis=1)
    np.testing.assert_allclose(result.rates, rates, rtol=1e-13)


@pytest.mark.parametrize('noise_dbm', [100.0, 50.0, 30.0])
def test_low_snr_water_filling_assigns_the_whole_budget_at_the_first_order_optimum(noise_dbm):
    scenario = paper_scenario('I', noise_psd_dbm_per_hz=noise_dbm)
    a = snr_per_watt(straight_line(scenario), scenario)
    allocation = waterfilling_power(a, scenario.power_budget_w)
    assert allocation.p.sum() == pytest.approx(scenario.power_budget_w, rel=1e-12)
    # At SNR << 1, log2(1 + p a) = p a / ln 2 to first order: each node spends its power in
    # its best slot and equal rates give p_n a_n,best = P_T / sum_k (1 / a_k,best).
    best = a.max(axis=1)
    first_order = scenario.power_budget_w / (1.0 / best).sum() / (a.shape[1] * math.log(2.0))
    assert allocation.efficiency == pytest.approx(first_order, rel=1e-6)


# Cancellation between steps.

def test_should_stop_is_asked_between_steps_and_cancels_with_the_typed_error():
    asked = []

    def stop_after_three() -> bool:
        asked.append(True)
        return len(asked) > 3

    with pytest.raises(PlanCancelledError, match='cancelled between steps'):
        plan(paper_scenario('I', **SMALL), should_stop=stop_after_three)
    assert len(asked) == 4
    result = plan(paper_scenario('I', **SMALL), should_stop=lambda: False)
    assert result.converged


# Files.

def test_only_regular_files_are_written(tmp_path):
    with pytest.raises(NotARegularFileError, match='device, pipe or socket'):
        write_text_atomic('/dev/null', 'x')
    assert stat.S_ISCHR(os.stat('/dev/null').st_mode)
    elsewhere = tmp_path / 'elsewhere.json'
    elsewhere.write_text('keep')
    (tmp_path / 'link.json').symlink_to(elsewhere)
    with pytest.raises(NotARegularFileError, match='symbolic link'):
        write_text_atomic(tmp_path / 'link.json', 'x')
    os.mkfifo(tmp_path / 'pipe.json')
    with pytest.raises(NotARegularFileError, match='device, pipe or socket'):
        write_text_atomic(tmp_path / 'pipe.json', 'x')
    assert elsewhere.read_text() == 'keep'
    assert sorted(p.name for p in tmp_path.iterdir()) == ['elsewhere.json', 'link.json',
                                                          'pipe.json']


def test_read_only_and_foreign_files_are_not_replaced(tmp_path):
    locked = tmp_path / 'locked.json'
    locked.write_text('keep')
    locked.chmod(0o444)
    with pytest.raises(PermissionError, match='read-only'):
        write_text_atomic(locked, 'x')
    assert locked.read_text() == 'keep'
    if os.geteuid() == 0:
        foreign = tmp_path / 'survey.json'
        foreign.write_text('theirs')
        os.chown(foreign, 12345, -1)
        with pytest.raises(PermissionError, match='belongs to another user'):
            write_text_atomic(foreign, 'x')
        assert foreign.read_text() == 'theirs'


def test_new_files_follow_the_umask(tmp_path):
    previous = os.umask(0o027)
    try:
        write_text_atomic(tmp_path / 'a.json', 'x')
    finally:
        os.umask(previous)
    assert (tmp_path / 'a.json').stat().st_mode & 0o777 == 0o640


def test_stale_temporaries_of_dead_processes_are_removed_and_live_ones_kept(tmp_path):
    target = tmp_path / 'plan.json'
    dead_pid = 2 ** 22 + 12345  # above Linux's pid_max limit: no such process
    stale = tmp_path / f'.plan.json{PARTIAL_MARK}{dead_pid}-abc123.json'
    live = tmp_path / f'.plan.json{PARTIAL_MARK}{os.getpid()}-def456.json'
    other = tmp_path / f'.other.json{PARTIAL_MARK}{dead_pid}-ghi789.json'
    for path in (stale, live, other):
        path.write_text('half')
    write_text_atomic(target, 'whole')
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ['plan.json', live.name, other.name])


# Mission export.

def test_home_altitude_has_a_range():
    with pytest.raises(InvalidScenarioError, match='home altitude must be in'):
        Home(47.0, 8.0, 1e308)
    with pytest.raises(InvalidScenarioError, match='home altitude must be in'):
        Home.parse('47,8,-5000')
    with pytest.raises(InvalidScenarioError, match='home latitude_deg must be a finite number'):
        Home(10 ** 400, 8.0, 400.0)
    with pytest.raises(InvalidScenarioError, match='home altitude_m must be a finite number'):
        Home(47.0, 8.0, True)


def test_node_parameters_refuse_an_absurd_home_altitude_and_wrong_types():
    from uav_comm_planner.ros.params import config_from_parameters
    with pytest.raises(InvalidScenarioError, match='home altitude must be in'):
        config_from_parameters({'home_altitude_m': 1e308})
    with pytest.raises(InvalidScenarioError, match='start_m has the wrong type'):
        config_from_parameters({'start_m': ['a', 'b']})


def test_a_hold_beyond_ardupilots_uint16_is_split_into_repeated_waypoints(tmp_path):
    # Start = goal above the only node, 200 000 s in 4 slots: the UAV hovers the whole time.
    scenario = Scenario(ground_nodes_m=((0.0, 0.0),), goal_m=(0.0, 0.0), num_slots=4,
                        horizon_s=200_000.0, max_speed_mps=1.0)
    result = plan(scenario, SolverSettings(compute_baselines=False))
    total_hold = sum(stop.hold_s for stop in schedule_flight(result, VehicleLimits()).stops)
    assert total_hold > 3 * FIRMWARES['ardupilot'].max_hold_s
    home = Home(47.0, 8.0, 400.0)
    items = build_mission_items(result, home)
    holds = [item.params[0] for item in items[1:] if item.command == NAV_WAYPOINT]
    assert max(holds) <= FIRMWARES['ardupilot'].max_hold_s and all(h == int(h) for h in holds)
    assert sum(holds) == total_hold
    path = export_mission(result, tmp_path / 'long.waypoints', home)
    rows = [line.split('\t') for line in path.read_text().splitlines()[1:]]
    assert max(float(row[4]) for row in rows if int(row[3]) == NAV_WAYPOINT) <= 65535
    px4 = build_mission_items(result, home, firmware='px4')
    assert max(item.params[0] for item in px4 if item.command == NAV_WAYPOINT) == total_hold


def test_far_positions_map_to_valid_coordinates_and_non_finite_rows_are_refused(
        tmp_path, monkeypatch):
    from uav_comm_planner.vehicle.mavlink import items as mission_items
    scenario = Scenario(ground_nodes_m=((0.0, 9.0e6),), start_m=(0.0, 9.0e6),
                        goal_m=(0.0, 9.0e6), max_speed_mps=10.0, **SMALL)
    result = plan(scenario, SolverSettings(compute_baselines=False))
    items = build_mission_items(result, Home(89.0, 0.0, 0.0))
    assert all(abs(item.x) <= 90.0 and abs(item.y) <= 180.0 for item in items)

    def broken(east, north, up, home):
        return np.full(len(east), np.nan), np.full(len(east), np.nan), np.zeros(len(east))

    monkeypatch.setattr(mission_items, 'enu_to_geodetic', broken)
    with pytest.raises(MissionExportError, match='non-finite value'):
        export_mission(result, tmp_path / 'm.waypoints', Home(47.0, 8.0, 400.0))
    assert list(tmp_path.iterdir()) == []


# Command line.

def one_line_refusal(capsys, tmp_path, argv) -> str:
    before = sorted(p.name for p in tmp_path.iterdir())
    status = cli.main(argv)
    out, err = capsys.readouterr()
    assert status == 2, (out, err)
    assert err.count('\n') == 1 and err.startswith('uav-comm-planner: error: '), err
    assert 'Traceback' not in err and 'usage:' not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    return err


@pytest.mark.parametrize('content, message', [
    (b'\xff\xfe{}', 'is not UTF-8 text'),
    (b'5', 'must hold a JSON object'),
    (b'null', 'must hold a JSON object'),
    (b'[[1,2]]', 'must hold a JSON object'),
    (b'[' * 200_000 + b']' * 200_000, 'nested too deeply'),
    (b'{"ground_nodes_m": [[0, 0]], "noise_psd_dbm_per_hz": "x"}', 'must be a number'),
    (b'{"ground_nodes_m": [[0, 0]], "num_slots": 1' + b'0' * 5000 + b'}', 'not valid JSON'),
    (b'{"ground_nodes_m": [[0, 0]], "altitude_m": 1e400}', 'altitude_m must be a positive'),
    (b'{"ground_nodes_m": {"a": 1}}', 'ground_nodes_m must be a sequence'),
    (b'{"ground_nodes_m": [[0, 0]], "start_m": "12"}', 'start_m must be a pair'),
    (b'{"ground_nodes_m": [[0, 0]], "horizon_s": NaN}', 'horizon_s must be a positive'),
])
def test_bad_scenario_files_are_one_line_refusals(tmp_path, capsys, content, message):
    folder = tmp_path / 'in'
    folder.mkdir()
    scenario = folder / 's.json'
    scenario.write_bytes(content)
    out = tmp_path / 'out'
    out.mkdir()
    err = one_line_refusal(capsys, out, ['plan', '--scenario', str(scenario),
                                         '--json', str(out / 'r.json')])
    assert message in err


@pytest.mark.parametrize('argv, message', [
    (['plan', '--noise-dbm', '1e6'], 'overflows'),
    (['plan', '--altitude', '1e300'], 'overflows'),
    (['plan', '--bandwidth', '5e-324'], 'is inf'),
    (['plan', '--budget', '1e300'], 'P_T a_max is inf'),
    (['plan', '--slots', '3000000'], 'exceeds the compute budget'),
    (['plan', '--slots', 'many'], "argument --slots: invalid int value: 'many'"),
    (['plan', '--case', 'III'], 'invalid choice'),
    (['plan', '--bogus'], 'unrecognized arguments: --bogus'),
    (['launch'], 'invalid choice'),
    ([], 'the following arguments are required'),
    (['plan', '--home', '47,8,1e308', '--mission', '{tmp}/m.waypoints'],
     'home altitude must be in'),
    (['plan', '--json', '{tmp}/r.json', '--figure', '{tmp}/f.xyz'],
     'unknown figure format'),
    (['plan', '--json', '/dev/null'], 'not a regular file'),
    (['plan', '--json', '{tmp}/r.json', '--mission', '{tmp}/m.txt'],
     'unknown mission format'),
    (['sweep', '--budgets', '1,nan', '--json', '{tmp}/r.json'], 'power_budget_w must be'),
    (['sweep', '--budgets', ''], 'expected comma-separated numbers'),
    (['plan', '--vehicle', '--speed', '10', '--horizon', '400', '--wp-jerk', '1e-300'],
     'vehicle max_jerk_mpsss must be in [0.01, 10000]'),
    (['plan', '--vehicle', '--speed', '10', '--horizon', '400', '--wp-accel', '1e300'],
     'vehicle max_accel_mpss must be in [0.01, 1000]'),
])
def test_bad_command_lines_are_one_line_refusals_before_any_file(tmp_path, capsys, argv,
                                                                 message):
    argv = [arg.replace('{tmp}', str(tmp_path)) for arg in argv]
    assert message in one_line_refusal(capsys, tmp_path, argv)


def test_no_file_is_written_when_a_later_output_is_refused(tmp_path, capsys):
    (tmp_path / 'f.png').mkdir()
    err = one_line_refusal(capsys, tmp_path, ['plan', '--json', str(tmp_path / 'r.json'),
                                              '--figure', str(tmp_path / 'f.png')])
    assert 'it is a folder' in err


def test_json_output_never_holds_infinity_or_nan():
    with pytest.raises(PlannerError, match='non-finite number'):
        cli.json_text({'upper_bound': math.inf})
    assert json.loads(cli.json_text({'x': 1.5})) == {'x': 1.5}
