"""Scenario and solver settings: the letter's values and every bad input of the model."""

import math

import pytest

from uav_comm_planner import (InfeasibleHorizonError, InvalidScenarioError, paper_scenario,
                              plan, Scenario, SolverSettings)


def test_paper_cases_are_the_letters_section_iv():
    first, second = paper_scenario('I'), paper_scenario('II')
    assert first.ground_nodes_m == ((200.0, 400.0), (1000.0, 200.0), (1800.0, 400.0))
    assert first.goal_m == (2000.0, 0.0) and second.goal_m == (2000.0, 500.0)
    assert first.start_m == second.start_m == (0.0, 0.0)
    assert first.slot_s == 1.0 and first.num_slots == 50 and first.max_step_m == 100.0
    # -169 dBm/Hz is 10^(-16.9) mW/Hz = 10^(-19.9) W/Hz.
    assert math.isclose(first.noise_psd_w_per_hz, 10 ** -19.9, rel_tol=1e-12)
    assert first.times_s[0] == 1.0 and first.times_s[-1] == 50.0


@pytest.mark.parametrize('nodes, message', [
    ([], 'no ground nodes'),
    ([(float('nan'), 1.0)], 'ground node 1 must be finite'),
    ([(0.0, 0.0), (1.0, float('inf'))], 'ground node 2 must be finite'),
    ([(5.0, 5.0), (7.0, 1.0), (5.0, 5.0)], 'duplicate ground nodes: node 1 and node 3'),
    ([(1.0, 2.0, 3.0)], r'must be a pair \(x, y\)'),
])
def test_bad_ground_nodes_are_refused(nodes, message):
    with pytest.raises(InvalidScenarioError, match=message):
        paper_scenario('I', ground_nodes_m=nodes)


@pytest.mark.parametrize('field', ['altitude_m', 'max_speed_mps', 'horizon_s', 'bandwidth_hz',
                                   'reference_gain', 'power_budget_w'])
@pytest.mark.parametrize('value', [0.0, -1.0, float('nan'), float('inf')])
def test_non_positive_or_non_finite_settings_are_refused(field, value):
    with pytest.raises(InvalidScenarioError, match=f'{field} must be a positive finite number'):
        paper_scenario('I', **{field: value})


@pytest.mark.parametrize('slots', [0, -3, 2.5, True])
def test_slot_count_must_be_a_positive_integer(slots):
    with pytest.raises(InvalidScenarioError, match='num_slots must be an integer'):
        paper_scenario('I', num_slots=slots)


def test_non_finite_start_goal_and_noise_are_refused():
    with pytest.raises(InvalidScenarioError, match='start_m must be finite'):
        paper_scenario('I', start_m=(float('nan'), 0.0))
    with pytest.raises(InvalidScenarioError, match='goal_m must be finite'):
        paper_scenario('I', goal_m=(0.0, float('-inf')))
    with pytest.raises(InvalidScenarioError, match='noise_psd_dbm_per_hz must be finite'):
        paper_scenario('I', noise_psd_dbm_per_hz=float('nan'))


def test_unreachable_goal_is_a_clear_error_not_a_solver_crash():
    # 2000 m in M + 1 = 11 legs of at most 100 m: 1100 m of reach.
    with pytest.raises(InfeasibleHorizonError, match=r'goal unreachable: .*2000\.0 m apart'):
        paper_scenario('I', num_slots=10, horizon_s=10.0)
    # Exactly (M + 1) V delta is still feasible: 20 legs of 100 m.
    scenario = paper_scenario('I', num_slots=19, horizon_s=19.0)
    assert scenario.num_slots == 19


def test_more_nodes_than_the_limit_is_refused_by_plan():
    scenario = paper_scenario('I')
    with pytest.raises(InvalidScenarioError, match='too many ground nodes: 3 given.*is 2'):
        plan(scenario, SolverSettings(max_nodes=2))


@pytest.mark.parametrize('changes, message', [
    ({'tolerance_bps': -1.0}, 'tolerance_bps must be >= 0'),
    ({'relative_tolerance': 1.5}, r'relative_tolerance must be in \[0, 1\)'),
    ({'tolerance_bps': 0.0, 'relative_tolerance': 0.0}, 'cannot both be 0'),
    ({'max_outer_iterations': 0}, 'max_outer_iterations must be an integer >= 1'),
    ({'max_nodes': 2.0}, 'max_nodes must be an integer >= 1'),
])
def test_bad_solver_settings_are_refused(changes, message):
    with pytest.raises(InvalidScenarioError, match=message):
        SolverSettings(**changes)


def test_replace_validates_again_and_keeps_the_original():
    scenario = paper_scenario('II')
    assert scenario.replace(power_budget_w=1.0).power_budget_w == 1.0
    assert scenario.power_budget_w == 5.0
    with pytest.raises(InvalidScenarioError, match='power_budget_w'):
        scenario.replace(power_budget_w=-5.0)


def test_unknown_case_is_refused():
    with pytest.raises(InvalidScenarioError, match="unknown case 'III'"):
        paper_scenario('III')


def test_scenario_is_frozen():
    scenario = Scenario(ground_nodes_m=[(0.0, 0.0)], goal_m=(100.0, 0.0))
    with pytest.raises(AttributeError):
        scenario.altitude_m = 50.0  # type: ignore[misc]
    assert scenario.ground_nodes_m == ((0.0, 0.0),)
