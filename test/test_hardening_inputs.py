"""Every input bounded before work, with the bound in the error: zones (their coordinates,
count and vertices), huge integers, a sweep's budgets, a study's design, its table and its
scheduler; ArduCopter's jerk time read as ArduCopter flies it. Each a typed error in Python and
one line with exit 2 on the command line."""

from __future__ import annotations

import json
import math
from pathlib import Path
import re
import warnings

from helpers import run_fuzz_target
import pytest

from uav_comm_planner import paper_scenario
from uav_comm_planner.core.zones import (KeepOutCircle, KeepOutPolygon, MAX_KEEP_OUT_ZONES,
                                         MAX_TOTAL_VERTICES, MAX_ZONE_EXTENT_M, OperatingArea,
                                         Zones)
from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.tools import cli
from uav_comm_planner.tools.serialize import scenario_to_dict
from uav_comm_planner.tools.study.design import (MAX_ROWS, MAX_STUDY_NODES, StudyDesign,
                                                 StudyError)
from uav_comm_planner.tools.study.runner import check_scheduler
from uav_comm_planner.vehicle.limits import read_parameter_file

HUGE = 10 ** 400


def one_line_refusal(capsys, argv: list[str]) -> str:
    """The command line's one error line and exit 2, with every warning an error (none may
    leak into the refusal)."""
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        status = cli.main(argv)
    out, err = capsys.readouterr()
    assert status == 2, (out, err)
    assert err.count('\n') == 1 and err.startswith('uav-comm-planner: error: '), err
    return err


def scenario_file(folder: Path, zones: dict) -> Path:
    data = scenario_to_dict(paper_scenario('I'))
    data['zones'] = zones
    path = folder / 'scenario.json'
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize('make, match', [
    (lambda: KeepOutPolygon([[HUGE, 0], [1, 0], [0, 1]]), 'has a vertex beyond a double'),
    (lambda: OperatingArea([[HUGE, 0], [1, 0], [0, 1]]), 'has a vertex beyond a double'),
    (lambda: KeepOutCircle((0.0, 0.0), HUGE), r'finite number of metres, got 1000.*\(401 '
                                              r'digits\)'),
    (lambda: KeepOutCircle((0.0, 0.0), 1e308), 'reaches beyond 1e\\+07 m'),
    (lambda: KeepOutPolygon([[0, 0], [1e308, 0], [0, 1e308]]), 'has a vertex 1e\\+308 m'),
])
def test_zones_beyond_a_double_or_the_earth_are_typed_errors_in_one_short_line(make, match):
    with pytest.raises(InvalidScenarioError, match=match) as caught:
        make()
    assert len(str(caught.value)) < 200


@pytest.mark.parametrize('zones, match', [
    ({'keep_out': [{'center_m': [1000, 3000], 'radius_m': 1e308}]}, 'reaches beyond'),
    ({'keep_out': [{'vertices_m': [[0, 1e308], [1e308, 1e308], [1e308, -1e308]]}]},
     'has a vertex 1e\\+308 m from the origin'),
    ({'area': [[-1e308, -1e308], [1e308, -1e308], [1e308, 1e308]]}, 'the operating area'),
    ({'keep_out': [{'vertices_m': [[HUGE, 0], [1, 0], [0, 1]]}]}, 'beyond a double'),
])
def test_a_scenario_files_far_zones_are_one_line_without_warnings(tmp_path, capsys, zones,
                                                                  match):
    err = one_line_refusal(capsys, ['plan', '--scenario', str(scenario_file(tmp_path, zones))])
    assert re.search(match, err), err


def test_the_count_of_zones_and_their_vertices_is_bounded_before_they_are_built(
        tmp_path, capsys, monkeypatch):
    many = [{'center_m': [10.0 * i, 5000.0], 'radius_m': 1.0}
            for i in range(MAX_KEEP_OUT_ZONES + 1)]

    def never(*args, **kwargs):
        raise AssertionError('a zone was built before the count was checked')
    monkeypatch.setattr(KeepOutCircle, '__post_init__', never)
    err = one_line_refusal(capsys, ['plan', '--scenario',
                                    str(scenario_file(tmp_path, {'keep_out': many}))])
    assert f'holds {MAX_KEEP_OUT_ZONES + 1} zones, more than {MAX_KEEP_OUT_ZONES}' in err
    monkeypatch.undo()
    ring = [[1000.0 * math.cos(2 * math.pi * k / 999), 1000.0 * math.sin(2 * math.pi * k / 999)]
            for k in range(999)]
    rings = tuple(KeepOutPolygon([[x + 3000 * i, y] for x, y in ring])
                  for i in range(MAX_TOTAL_VERTICES // 999 + 1))
    assert len(Zones(keep_out=rings[:-1]).keep_out) == len(rings) - 1   # within the bound
    with pytest.raises(InvalidScenarioError, match=f'more than {MAX_TOTAL_VERTICES}'):
        Zones(keep_out=rings)
    assert MAX_ZONE_EXTENT_M == 1e7


def test_a_sweep_file_with_a_huge_integer_budget_is_one_line(tmp_path, capsys):
    sweep = tmp_path / 'sweep.json'
    sweep.write_text('{"scenario": {"ground_nodes_m": [[0, 0]]}, "budgets_w": [1' + '0' * 400
                     + ']}')
    err = one_line_refusal(capsys, ['sweep', '--scenario', str(sweep)])
    assert 'must be a list of numbers' in err and len(err) < 300


@pytest.mark.parametrize('value, jerk_time_s', [('0', 0.2), ('0.05', 0.2), ('0.1', 0.2),
                                                ('0.15', 0.3), ('0.3', 0.6)])
def test_atc_input_tc_is_read_as_arducopter_flies_it(tmp_path, value, jerk_time_s):
    """AC_WPNav's snap is J pi / (2 max(ATC_INPUT_TC, 0.1)), halved; SCurve's jerk time is
    J pi / (2 snap): tj = 2 max(ATC_INPUT_TC, 0.1). 0 is ArduCopter's floor, a legal value."""
    path = tmp_path / 'copter.param'
    path.write_text(f'ATC_INPUT_TC,{value}\n')
    assert read_parameter_file(path).jerk_time_s == pytest.approx(jerk_time_s)


def test_a_parameter_that_is_not_finite_is_refused_with_its_line(tmp_path):
    path = tmp_path / 'copter.param'
    path.write_text('WPNAV_SPEED,1000\nATC_INPUT_TC,nan\n')
    with pytest.raises(InvalidScenarioError, match=r'copter.param:2: ATC_INPUT_TC is .nan., '
                                                   r'not a finite number'):
        read_parameter_file(path)


@pytest.mark.parametrize('address', ['not a url', 'file:///etc/passwd', 'tcp://127.0.0.1',
                                     'tcp://127.0.0.1:99999', 'http://127.0.0.1:8786',
                                     'tcp://127.0.0.1:8786/path'])
def test_a_scheduler_that_is_not_an_address_is_refused_before_the_table(tmp_path, capsys,
                                                                        address):
    with pytest.raises(StudyError, match='is not a Dask scheduler address'):
        check_scheduler(address)
    out = tmp_path / 'study.csv'
    err = one_line_refusal(capsys, ['montecarlo', '--cases', '1', '--scheduler', address,
                                    '--out', str(out)])
    assert 'give tcp://HOST:PORT' in err
    assert list(tmp_path.iterdir()) == []


def test_accepted_scheduler_addresses():
    for address in ('tcp://127.0.0.1:8786', 'tls://scheduler.example:8786', 'tcp://[::1]:1'):
        check_scheduler(address)


@pytest.mark.parametrize('draws, match', [
    ({'nodes': '100000000'}, f'nodes reach 1e\\+08, more than {MAX_STUDY_NODES}'),
    ({'nodes': '2:20000'}, 'nodes reach 20000, more than 10000'),
    ({'slots': '10,1000000'}, 'slots reach 1e\\+06, more than 100000'),
])
def test_a_study_design_beyond_the_planners_budget_is_refused(draws, match):
    with pytest.raises(InvalidScenarioError, match=match):
        StudyDesign(cases=1, draws=draws)


def test_a_study_grid_beyond_the_row_bound_is_refused_before_it_is_crossed():
    grid = ','.join(str(v) for v in range(1, 1001))
    with pytest.raises(InvalidScenarioError, match=f'more than {MAX_ROWS}'):
        StudyDesign(cases=1001, draws={'altitude_m': grid})


def test_a_tampered_study_table_is_one_line_on_resume(tmp_path, capsys):
    out = tmp_path / 'study.csv'
    argv = ['montecarlo', '--cases', '1', '--slots', '20', '--workers', '1', '--quiet',
            '--out', str(out)]
    assert cli.main(argv) == 0
    capsys.readouterr()
    lines = out.read_text().splitlines()
    lines[1] = 'zero' + lines[1][lines[1].index(','):]
    out.write_text('\n'.join(lines) + '\n')
    argv[2] = '2'
    err = one_line_refusal(capsys, argv)
    assert "study.csv:2: 'zero' is not an integer; the table was changed by hand" in err


def test_a_short_seeded_run_of_the_zone_and_fence_fuzzer_finds_nothing(capsys):
    status = run_fuzz_target('fuzz_zones', ['--cases', '80', '--seed', '7'])
    out = capsys.readouterr().out
    assert status == 0, out
    assert '0 failures' in out
    accepted = re.search(r'fence +ok +(\d+)', out)
    assert accepted and int(accepted.group(1)) >= 10, out


def tampered(tmp_path, capsys, argv, column, value) -> str:
    """Run the study of ``argv``, set ``column`` of its first row to ``value`` and resume it
    with one more drop: the one-line refusal."""
    assert cli.main(argv) == 0
    capsys.readouterr()
    out = Path(argv[argv.index('--out') + 1])
    lines = out.read_text().splitlines()
    names = lines[0].split(',')
    cells = lines[1].split(',')
    cells[names.index(column)] = value
    lines[1] = ','.join(cells)
    out.write_text('\n'.join(lines) + '\n')
    argv[argv.index('--cases') + 1] = '2'
    return one_line_refusal(capsys, argv)


@pytest.mark.parametrize('column, value, match', [
    ('index', '-5', 'index -5 is not a row of a study'),
    ('index', '1' + '0' * 30, 'index 100000000000000000000000 is not a row'),
    ('nodes', '100000000', 'row 0 has nodes 100000000, its study 3'),
    ('seed', '7', 'row 0 has seed 7, its study 0'),
    ('slots', '5', 'outside its study\'s range 10:20'),
])
def test_a_row_that_is_not_its_studys_is_one_line_on_resume(tmp_path, capsys, column, value,
                                                            match):
    argv = ['montecarlo', '--cases', '1', '--nodes', '3', '--slots', '10:20', '--workers', '1',
            '--quiet', '--methods', 'straight', '--out', str(tmp_path / 'study.csv')]
    err = tampered(tmp_path, capsys, argv, column, value)
    assert match in err and 'the table was changed by hand' in err, err


def test_a_table_that_is_not_utf8_is_one_line_on_resume(tmp_path, capsys):
    out = tmp_path / 'study.csv'
    argv = ['montecarlo', '--cases', '1', '--slots', '20', '--workers', '1', '--quiet',
            '--methods', 'straight', '--out', str(out)]
    assert cli.main(argv) == 0
    capsys.readouterr()
    out.write_bytes(out.read_bytes() + b'\xff\xfe\x00,garbage\n')
    argv[2] = '2'
    err = one_line_refusal(capsys, argv)
    assert 'is not a CSV table of this package' in err


def test_an_untouched_table_with_drawn_settings_resumes(tmp_path, capsys):
    out = tmp_path / 'study.csv'
    argv = ['montecarlo', '--cases', '2', '--nodes', '2:4', '--altitude', '50,100',
            '--slots', '10:20', '--workers', '1', '--quiet', '--methods', 'straight',
            '--out', str(out)]
    assert cli.main(argv) == 0
    argv[2] = '3'
    assert cli.main(argv) == 0
    capsys.readouterr()
    assert len(out.read_text().splitlines()) == 1 + 3 * 2


def test_a_parameter_that_overflows_its_unit_is_refused_with_its_line(tmp_path):
    path = tmp_path / 'copter.param'
    path.write_text('WPNAV_SPEED,1000\nATC_INPUT_TC,1e308\n')
    with pytest.raises(InvalidScenarioError, match=r"copter.param:2: ATC_INPUT_TC is '1e308', "
                                                   r"beyond what a plan can be made with"):
        read_parameter_file(path)
