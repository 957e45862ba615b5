"""The altitude settings as scenario fields: ``altitude_range_m`` and ``max_climb_mps`` checked
on a Scenario, carried by a scenario file and by the JSON result, planned from a file exactly as
from the flags (a flag wins over the file's field), refused where altitudes are not planned."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from test_altitude import hover_scenario

from uav_comm_planner import paper_scenario, SolverSettings
from uav_comm_planner.core.altitude import AltitudeLimits, plan_with_altitude
from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.tools import cli
from uav_comm_planner.tools.serialize import scenario_from_dict, scenario_to_dict

#: One node 300 m from a UAV held at the origin, where altitude matters (test_altitude's).
HOVER = ['--nodes', '300,0', '--start', '0,0', '--goal', '0,0', '--speed', '0.01',
         '--horizon', '20', '--slots', '10', '--bandwidth', '1e6', '--noise-dbm', '-145',
         '--budget', '0.1', '--channel', 'los:urban']
#: The scenario file the flags above describe, without its altitudes.
HOVER_FILE = {'ground_nodes_m': [[300.0, 0.0]], 'start_m': [0.0, 0.0], 'goal_m': [0.0, 0.0],
              'max_speed_mps': 0.01, 'horizon_s': 20.0, 'num_slots': 10,
              'bandwidth_hz': 1e6, 'noise_psd_dbm_per_hz': -145.0, 'power_budget_w': 0.1,
              'channel': 'los:urban'}
PLAN_KEYS = ('trajectory', 'altitudes_m', 'power', 'rates', 'min_throughput',
             'altitude_range_m', 'max_climb_mps', 'fixed_altitude_m')


@pytest.mark.parametrize('fields, reason', [
    ({'altitude_range_m': (300.0, 30.0)}, 'lowest <= highest'),
    ({'altitude_range_m': (0.0, 30.0)}, '0 < lowest'),
    ({'altitude_range_m': (30.0, math.inf)}, 'finite'),
    ({'altitude_range_m': (30.0,)}, 'pair'),
    ({'altitude_range_m': '30,300'}, 'pair'),
    ({'altitude_range_m': (30.0, 'high')}, 'altitude range'),
    ({'altitude_range_m': (30.0, 300.0), 'max_climb_mps': 0.0}, 'positive'),
    ({'altitude_range_m': (30.0, 300.0), 'max_climb_mps': math.nan}, 'positive'),
    ({'altitude_range_m': (30.0, 300.0), 'max_climb_mps': 'fast'}, 'max_climb_mps'),
    ({'max_climb_mps': 2.0}, 'needs altitude_range_m')])
def test_scenario_refuses_bad_altitude_fields(fields, reason):
    with pytest.raises(InvalidScenarioError, match=reason):
        paper_scenario('I', **fields)


def test_scenario_holds_the_fields_as_numbers_and_round_trips_through_a_dict():
    scenario = paper_scenario('I', altitude_range_m=[30, 300], max_climb_mps=2)
    assert scenario.altitude_range_m == (30.0, 300.0) and scenario.max_climb_mps == 2.0
    assert isinstance(scenario.altitude_range_m[0], float)
    assert isinstance(scenario.max_climb_mps, float)
    again = scenario_from_dict(json.loads(json.dumps(scenario_to_dict(scenario))))
    assert again == scenario
    level = paper_scenario('I')
    assert level.altitude_range_m is None and level.max_climb_mps is None
    assert scenario_from_dict(json.loads(json.dumps(scenario_to_dict(level)))) == level


def test_plan_with_altitude_takes_the_scenarios_own_limits():
    settings = SolverSettings(max_outer_iterations=3)
    scenario = hover_scenario('los:urban', 300.0)
    given = plan_with_altitude(scenario, AltitudeLimits((20.0, 800.0), 5.0), settings)
    own = plan_with_altitude(scenario.replace(altitude_range_m=(20.0, 800.0), max_climb_mps=5.0),
                             None, settings)
    np.testing.assert_array_equal(own.altitudes, given.altitudes)
    np.testing.assert_array_equal(own.trajectory, given.trajectory)
    assert own.min_throughput == given.min_throughput
    assert given.scenario.altitude_range_m == (20.0, 800.0)
    assert given.scenario.max_climb_mps == 5.0
    with pytest.raises(InvalidScenarioError, match='altitude_range_m'):
        plan_with_altitude(scenario)


def _plan(argv, tmp_path, name: str) -> dict:
    out = tmp_path / name
    assert cli.main(['plan', *argv, '--json', str(out)]) == 0
    return json.loads(out.read_text())


def _same_plan(a: dict, b: dict) -> None:
    for key in PLAN_KEYS:
        assert a[key] == b[key], key


def test_a_scenario_file_plans_as_the_flags_do_and_its_result_plans_the_same_again(
        tmp_path, capsys):
    by_flags = _plan([*HOVER, '--altitude-range', '20,800', '--climb-rate', '5'], tmp_path,
                     'flags.json')
    scenario_file = tmp_path / 'scenario.json'
    scenario_file.write_text(json.dumps({**HOVER_FILE, 'altitude_range_m': [20, 800],
                                         'max_climb_mps': 5}))
    by_file = _plan(['--scenario', str(scenario_file)], tmp_path, 'file.json')
    _same_plan(by_flags, by_file)
    assert by_file['scenario']['altitude_range_m'] == [20.0, 800.0]
    assert by_file['scenario']['max_climb_mps'] == 5.0
    assert min(by_file['altitudes_m']) >= 20.0 and max(by_file['altitudes_m']) <= 800.0
    assert np.abs(np.diff(by_file['altitudes_m'])).max() <= 5.0 * 2.0 + 1e-6
    # The result file, given as the scenario, plans the same again.
    _same_plan(by_file, _plan(['--scenario', str(tmp_path / 'file.json')], tmp_path, 'r.json'))
    capsys.readouterr()


def test_the_default_climb_rate_is_written_into_the_result(tmp_path, capsys):
    scenario_file = tmp_path / 'scenario.json'
    scenario_file.write_text(json.dumps({**HOVER_FILE, 'altitude_range_m': [20, 800]}))
    data = _plan(['--scenario', str(scenario_file)], tmp_path, 'file.json')
    assert data['max_climb_mps'] == 2.5 and data['scenario']['max_climb_mps'] == 2.5
    _same_plan(data, _plan([*HOVER, '--altitude-range', '20,800'], tmp_path, 'flags.json'))
    capsys.readouterr()


def test_a_flag_wins_over_the_files_field(tmp_path, capsys):
    scenario_file = tmp_path / 'scenario.json'
    scenario_file.write_text(json.dumps({**HOVER_FILE, 'altitude_range_m': [20, 800],
                                         'max_climb_mps': 5}))
    climb_flag = _plan(['--scenario', str(scenario_file), '--climb-rate', '1'], tmp_path,
                       'climb.json')
    assert climb_flag['altitude_range_m'] == [20.0, 800.0] and climb_flag['max_climb_mps'] == 1
    _same_plan(climb_flag, _plan([*HOVER, '--altitude-range', '20,800', '--climb-rate', '1'],
                                 tmp_path, 'flags1.json'))
    range_flag = _plan(['--scenario', str(scenario_file), '--altitude-range', '40,60'],
                       tmp_path, 'range.json')
    assert range_flag['altitude_range_m'] == [40.0, 60.0] and range_flag['max_climb_mps'] == 5
    assert min(range_flag['altitudes_m']) >= 40.0 and max(range_flag['altitudes_m']) <= 60.0
    _same_plan(range_flag, _plan([*HOVER, '--altitude-range', '40,60', '--climb-rate', '5'],
                                 tmp_path, 'flags2.json'))
    capsys.readouterr()


@pytest.mark.parametrize('fields, argv, reason', [
    ({'altitude_range_m': [300, 30]}, [], 'lowest <= highest'),
    ({'altitude_range_m': '30,300'}, [], 'pair'),
    ({'altitude_range_m': [30, 300], 'max_climb_mps': -1}, [], 'positive'),
    ({'altitude_range_m': [30, 300], 'max_climb_mps': 'fast'}, [], 'max_climb_mps'),
    ({'max_climb_mps': 2}, [], 'needs altitude_range_m'),
    ({}, ['--climb-rate', '2'], 'needs --altitude-range'),
    ({'altitude_range_m': [30, 300]}, ['--figure', 'f.png'], 'does not combine'),
    ({'altitude_range_m': [30, 300]}, ['--uavs', '2', '--start', '0,0;0,10', '--goal',
                                       '0,0;0,10'], 'plan command'),
    ({'altitude_range_m': [30, 300]}, ['--climb-rate', '0'], 'positive')])
def test_command_line_refuses_bad_altitude_fields_in_one_line(fields, argv, reason, tmp_path,
                                                              monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    scenario_file = tmp_path / 'scenario.json'
    scenario_file.write_text(json.dumps({**HOVER_FILE, **fields}))
    assert cli.main(['plan', '--scenario', str(scenario_file), *argv]) == 2
    err = capsys.readouterr()[1]
    assert len(err.strip().splitlines()) == 1 and reason in err


@pytest.mark.parametrize('command', [['sweep', '--budgets', '1,2'],
                                     ['energy-sweep', '--airframe', 'x.json']])
def test_commands_that_keep_one_altitude_refuse_a_range(command, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    scenario_file = tmp_path / 'scenario.json'
    scenario_file.write_text(json.dumps({**HOVER_FILE, 'altitude_range_m': [30, 300]}))
    assert cli.main([*command, '--scenario', str(scenario_file)]) == 2
    err = capsys.readouterr()[1]
    assert len(err.strip().splitlines()) == 1 and 'plan command' in err
