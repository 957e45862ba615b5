"""Result files that run again, the version, figures fit for a paper, mission file precision."""

from __future__ import annotations

import importlib.metadata
import json
from pathlib import Path

import numpy as np
import pytest

from uav_comm_planner.core.optimizer import plan
from uav_comm_planner.core.scenario import paper_scenario, Scenario, SolverSettings
from uav_comm_planner.errors import PlannerError
from uav_comm_planner.tools import cli, plots
from uav_comm_planner.tools.serialize import (package_version, scenario_to_dict,
                                              settings_from_dict, settings_to_dict)
from uav_comm_planner.vehicle.geodesy import DEFAULT_HOME, Home
from uav_comm_planner.vehicle.mavlink.files import export_mission
from uav_comm_planner.vehicle.mavlink.items import DEGREE_DECIMALS


def run(capsys, *argv):
    status = cli.main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def small_scenario(**changes) -> Scenario:
    return paper_scenario('I', num_slots=12, horizon_s=36.0, **changes)


# --- version and result files ----------------------------------------------------------------

def test_version_is_the_installed_packages(capsys):
    with pytest.raises(SystemExit) as exit_info:
        cli.main(['--version'])
    assert exit_info.value.code == 0
    expected = importlib.metadata.version('uav_comm_planner')
    assert capsys.readouterr().out.strip() == f'uav-comm-planner {expected}'
    assert package_version() == expected


def test_version_of_a_checkout_that_is_not_installed_is_package_xml_s(monkeypatch):
    def not_installed(name):
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(importlib.metadata, 'version', not_installed)
    xml = (Path(__file__).resolve().parents[1] / 'package.xml').read_text()
    assert f'<version>{package_version()}</version>' in xml
    assert package_version() != 'unknown'


def test_settings_round_trip_and_unknown_settings_are_refused():
    settings = SolverSettings.letter(max_nodes=7)
    assert settings_from_dict(json.loads(json.dumps(settings_to_dict(settings)))) == settings
    with pytest.raises(PlannerError, match=r"unknown solver setting\(s\) \['tolerance'\]"):
        settings_from_dict({'tolerance': 0.1})


def test_a_result_file_runs_again_with_its_settings(tmp_path, capsys):
    """--letter's result, re-run from its file without --letter, is the letter's plan again.

    The default settings give a different plan (11.5728 against 11.5533 bit/s for case I),
    so an equal objective shows the settings were read from the file.
    """
    first, again = tmp_path / 'letter.json', tmp_path / 'again.json'
    assert run(capsys, 'plan', '--case', 'I', '--letter', '--json', str(first))[0] == 0
    assert run(capsys, 'plan', '--scenario', str(first), '--json', str(again))[0] == 0
    recorded, rerun = json.loads(first.read_text()), json.loads(again.read_text())
    assert recorded['version'] == package_version()
    assert recorded['settings'] == settings_to_dict(SolverSettings.letter())
    assert rerun['settings'] == recorded['settings']
    assert rerun['min_throughput'] == pytest.approx(recorded['min_throughput'], rel=1e-12)
    assert np.allclose(rerun['trajectory'], recorded['trajectory'], rtol=0.0, atol=1e-9)
    default = plan(paper_scenario('I')).min_throughput
    assert abs(default - recorded['min_throughput']) > 1e-3
    # A flag still overrides the file's setting.
    status, _, _ = run(capsys, 'plan', '--scenario', str(first), '--tolerance', '0.5',
                       '--json', str(again))
    assert status == 0 and json.loads(again.read_text())['settings']['tolerance_bps'] == 0.5


def test_a_sweep_file_records_scenario_settings_and_version(tmp_path, capsys):
    sweep = tmp_path / 'sweep.json'
    status, _, _ = run(capsys, 'sweep', '--case', 'II', '--slots', '12', '--horizon', '36',
                       '--budgets', '1,4', '--json', str(sweep))
    assert status == 0
    data = json.loads(sweep.read_text())
    assert data['version'] == package_version()
    assert data['settings'] == settings_to_dict(SolverSettings())
    assert data['scenario']['goal_m'] == [2000.0, 500.0] and data['scenario']['num_slots'] == 12
    assert set(data['min_throughput']) == {'proposed', 'straight', 'static'}
    assert all(bound >= value for bound, value in zip(data['dual_upper_bound'],
                                                      data['min_throughput']['proposed']))
    again = tmp_path / 'again.json'
    status, _, _ = run(capsys, 'plan', '--scenario', str(sweep), '--budget', '4',
                       '--json', str(again))
    assert status == 0
    assert json.loads(again.read_text())['min_throughput'] == pytest.approx(
        data['min_throughput']['proposed'][1], rel=1e-9)


def test_a_sweep_file_runs_again_with_its_budgets(tmp_path, capsys):
    first, again = tmp_path / 'first.json', tmp_path / 'again.json'
    status, _, _ = run(capsys, 'sweep', '--case', 'I', '--slots', '12', '--horizon', '36',
                       '--letter', '--budgets', '0.5,3', '--json', str(first))
    assert status == 0
    status, out, _ = run(capsys, 'sweep', '--scenario', str(first), '--json', str(again))
    assert status == 0 and len(out.splitlines()) == 4   # header, two budgets, 'wrote'
    recorded, rerun = json.loads(first.read_text()), json.loads(again.read_text())
    assert rerun['budgets_w'] == [0.5, 3.0] and rerun['settings'] == recorded['settings']
    for method, values in recorded['min_throughput'].items():
        assert rerun['min_throughput'][method] == pytest.approx(values, rel=1e-9), method
    bad = tmp_path / 'bad.json'
    bad.write_text(json.dumps({**recorded, 'budgets_w': ['a lot']}))
    status, _, err = run(capsys, 'sweep', '--scenario', str(bad))
    assert status == 2 and err.count('\n') == 1 and 'must be a list of numbers' in err


def test_a_file_with_unknown_settings_ends_with_one_line(tmp_path, capsys):
    bad = tmp_path / 'bad.json'
    bad.write_text(json.dumps({'scenario': {'ground_nodes_m': [[0, 100]]},
                               'settings': {'epsilon': 1}}))
    status, out, err = run(capsys, 'plan', '--scenario', str(bad))
    assert status == 2 and out == ''
    assert err.count('\n') == 1 and "unknown solver setting(s) ['epsilon']" in err


# --- figures ---------------------------------------------------------------------------------

@pytest.mark.parametrize('value, text', [
    (841201.683, '841.2 kbit/s'), (11.5712, '11.57 bit/s'), (2.5e6, '2.5 Mbit/s'),
    (0.25, '0.25 bit/s'), (999.95, '1 kbit/s'), (999.94, '999.9 bit/s'), (3.2e9, '3.2 Gbit/s')])
def test_rates_are_shown_in_scaled_units(value, text):
    assert plots.format_rate(value) == text


def test_titles_name_the_case_and_what_differs():
    assert plots.scenario_label(paper_scenario('I')) == 'case I'
    assert plots.scenario_label(paper_scenario('II', power_budget_w=2.0)) == 'case II'
    low_snr = paper_scenario('I', bandwidth_hz=1e6, reference_gain=1e-6, power_budget_w=0.5)
    assert plots.scenario_label(low_snr) == r'case I, B = 1 MHz, $\beta_0$ = -60 dB'
    assert plots.scenario_label(paper_scenario('II', num_slots=12, horizon_s=36.0)) == \
        'case II, T = 36 s, M = 12'
    other = Scenario(ground_nodes_m=((0.0, 100.0), (50.0, 0.0)), goal_m=(100.0, 0.0))
    assert plots.scenario_label(other) == '2 ground nodes, M = 50'
    # A title that states M, T, V and H apart leaves them out of the label.
    stated = plots.STATED_SETTINGS
    assert plots.scenario_label(paper_scenario('II', num_slots=12, horizon_s=36.0),
                                besides=stated) == 'case II'
    assert plots.scenario_label(other, besides=stated) == '2 ground nodes'


def _extent(artist, renderer):
    return artist.get_window_extent(renderer)


def _assert_apart(first, second, what):
    assert not first.overlaps(second), what


def test_plan_figure_title_and_no_overlaps():
    result = plan(small_scenario(bandwidth_hz=1e6, reference_gain=1e-6, power_budget_w=0.5))
    figure = plots.draw_plan(result)
    title = figure._suptitle.get_text()
    assert title == (r'case I, B = 1 MHz, $\beta_0$ = -60 dB: min average throughput '
                     f'{plots.format_rate(result.min_throughput)} as planned\n'
                     'M = 12 slots of 3 s (T = 36 s), V = 100 m/s, H = 100 m, $P_T$ = 0.5 W')
    assert 'Mbit/s' in title
    figure.canvas.draw()
    renderer = figure.canvas.get_renderer()
    axes = figure.axes
    for ax in axes:
        legend = _extent(ax.get_legend(), renderer)
        for other in axes:
            _assert_apart(legend, _extent(other, renderer), f'legend of {ax.get_title()}')
            _assert_apart(legend, _extent(other.xaxis.label, renderer), 'legend and x label')
        _assert_apart(_extent(figure._suptitle, renderer), _extent(ax.title, renderer),
                      'figure title and axes title')
    for ax, other in zip(axes, axes[1:]):
        _assert_apart(ax.get_tightbbox(renderer), other.get_tightbbox(renderer), 'panels')
    plots._pyplot().close(figure)


def test_sweep_ticks_are_the_budgets_and_the_axis_is_scaled():
    budgets = [0.5, 1.0, 2.0, 5.0, 20.0]
    rows = {'proposed': [1.5e5 * (1 + k) for k in range(5)],
            'straight': [1.2e5 * (1 + k) for k in range(5)]}
    figure = plots.draw_sweep(budgets, rows, scenario=paper_scenario('II'))
    (ax,) = figure.axes
    figure.canvas.draw()
    assert list(ax.get_xticks()) == budgets
    assert [label.get_text() for label in ax.get_xticklabels()] == ['0.5', '1', '2', '5', '20']
    assert ax.get_ylabel() == 'min average throughput (kbit/s)'
    assert ax.lines[0].get_ydata()[0] == pytest.approx(150.0)
    assert ax.get_title().startswith('case II: ')
    renderer = figure.canvas.get_renderer()
    _assert_apart(_extent(ax.get_legend(), renderer), _extent(ax, renderer), 'legend on data')
    plots._pyplot().close(figure)


@pytest.mark.parametrize('suffix, magic', [('png', b'\x89PNG'), ('pdf', b'%PDF'),
                                           ('svg', b'<?xml')])
def test_figures_are_byte_identical_when_drawn_twice(tmp_path, suffix, magic):
    result = plan(small_scenario())
    first = plots.plan_figure(result, tmp_path / f'a.{suffix}').read_bytes()
    second = plots.plan_figure(result, tmp_path / f'b.{suffix}').read_bytes()
    assert first.startswith(magic)
    assert first == second
    sweep = {'proposed': [10.0, 11.0], 'straight': [9.5, 10.4]}
    assert (plots.sweep_figure([1, 2], sweep, tmp_path / f'c.{suffix}').read_bytes()
            == plots.sweep_figure([1, 2], sweep, tmp_path / f'd.{suffix}').read_bytes())


def test_an_unknown_figure_format_is_refused_before_planning(tmp_path, capsys):
    with pytest.raises(PlannerError, match=r'unknown figure format .*\.png, \.pdf, \.svg'):
        plots.check_figure_path(tmp_path / 'f.jpg')
    status, out, err = run(capsys, 'plan', '--figure', str(tmp_path / 'f.jpg'))
    assert status == 2 and out == '' and err.count('\n') == 1
    assert not (tmp_path / 'f.jpg').exists()


# --- mission file precision ------------------------------------------------------------------

def _decimals(text: str) -> int:
    return len(text.split('.')[1]) if '.' in text else 0


def test_mission_coordinates_have_the_precision_the_comment_states(tmp_path):
    """.waypoints: 6 decimals (pymavlink's %f); .plan: the items' 1e-8 degree rounding."""
    result = plan(paper_scenario('I', max_speed_mps=10.0, horizon_s=400.0, num_slots=100))
    home = Home(*DEFAULT_HOME)
    waypoints = export_mission(result, tmp_path / 'm.waypoints', home)
    rows = [line.split('\t') for line in waypoints.read_text().splitlines()[1:]]
    assert rows and all(len(row) == 12 for row in rows)   # what QGroundControl requires
    assert {(_decimals(row[8]), _decimals(row[9])) for row in rows} == {(6, 6)}
    document = json.loads(export_mission(result, tmp_path / 'm.plan', home).read_text())
    coordinates = np.array([item['params'][4:6] for item in document['mission']['items']
                            if item['command'] == 16 and item['frame'] == 3])
    assert len(coordinates) >= 2
    assert np.array_equal(coordinates, np.round(coordinates, DEGREE_DECIMALS))
    assert not np.array_equal(coordinates, np.round(coordinates, 6))
    planned = np.array([[float(row[8]), float(row[9])] for row in rows
                        if row[3] == '16' and row[2] == '3'])
    assert np.abs(planned - coordinates).max() <= 0.5e-6 + 1e-12
    assert Path(waypoints).read_text().startswith('QGC WPL 110\n')


@pytest.mark.parametrize('record', [
    {'budgets_w': '12'}, {'budgets_w': []},
    {'budgets_w': [1.0], 'settings': {'compute_baselines': False}}])
def test_a_sweep_file_with_odd_budgets_or_no_baselines_is_refused_or_swept(
        tmp_path, capsys, record):
    source = tmp_path / 'sweep.json'
    source.write_text(json.dumps({'scenario': scenario_to_dict(small_scenario()), **record}))
    status = cli.main(['sweep', '--scenario', str(source)])
    out, err = capsys.readouterr()
    if 'settings' in record:
        assert status == 0 and 'Traceback' not in err
    else:
        assert status == 2 and 'must be a list of numbers, at least one' in err
