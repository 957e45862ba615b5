"""The command line as a user runs it: tables, JSON, figures and clear errors."""

import json

import pytest

from uav_comm_planner import paper_scenario, plan
from uav_comm_planner.tools import cli


def run(capsys, *argv):
    status = cli.main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def test_plan_writes_the_json_and_the_figure(tmp_path, capsys):
    result_file, figure = tmp_path / 'r.json', tmp_path / 'f.png'
    status, out, _ = run(capsys, 'plan', '--case', 'I', '--json', str(result_file),
                         '--figure', str(figure))
    assert status == 0
    assert 'proposed (joint power and trajectory)' in out and 'static access point' in out
    data = json.loads(result_file.read_text())
    for key in ('trajectory', 'times', 'power', 'rates', 'min_throughput', 'baselines',
                'history', 'scenario'):
        assert key in data
    assert len(data['trajectory']) == 50 and len(data['power']) == 3
    assert data['min_throughput'] > max(data['baselines']['straight'],
                                        data['baselines']['static'])
    assert figure.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


@pytest.mark.parametrize('flags', [(), ('--speed', '10', '--horizon', '400', '--slots', '100',
                                          '--vehicle')])
def test_the_json_result_carries_the_dual_bound_the_command_prints(tmp_path, capsys, flags):
    """Beside the loose upper_bound, the dual bound over the flyable paths (for a plan as the
    vehicle flies it: the optimiser's plan's, as the table prints it)."""
    result_file = tmp_path / 'r.json'
    status, out, _ = run(capsys, 'plan', '--case', 'I', *flags, '--json', str(result_file))
    assert status == 0
    (printed,) = [float(line.split()[-1]) for line in out.splitlines()
                  if line.startswith('upper bound (dual over the flyable paths)')]
    (loose,) = [float(line.split()[-1]) for line in out.splitlines()
                if line.startswith('upper bound (every channel at its best)')]
    data = json.loads(result_file.read_text())
    assert round(data['dual_upper_bound'], 4) == printed
    assert round(data['upper_bound'], 4) == loose
    assert data['min_throughput'] <= data['dual_upper_bound'] < data['upper_bound']


def test_a_result_file_is_a_scenario_file_and_flags_override_it(tmp_path, capsys):
    first = tmp_path / 'first.json'
    assert run(capsys, 'plan', '--case', 'II', '--json', str(first))[0] == 0
    second = tmp_path / 'second.json'
    status, out, _ = run(capsys, 'plan', '--scenario', str(first), '--budget', '1',
                         '--nodes', '300,300;900,100', '--json', str(second))
    assert status == 0 and 'N = 2 nodes' in out and 'P_T = 1 W' in out
    scenario = json.loads(second.read_text())['scenario']
    assert scenario['goal_m'] == [2000.0, 500.0]
    assert scenario['ground_nodes_m'] == [[300.0, 300.0], [900.0, 100.0]]


def test_sweep_prints_one_row_per_budget_and_draws_fig_2(tmp_path, capsys):
    figure = tmp_path / 'sweep.png'
    status, out, _ = run(capsys, 'sweep', '--case', 'I', '--budgets', '0.5,5',
                         '--figure', str(figure))
    assert status == 0
    rows = [line.split() for line in out.splitlines() if line.strip()[:1].isdigit()]
    assert [row[0] for row in rows] == ['0.5', '5']
    assert all(float(row[1]) > max(float(row[2]), float(row[3])) for row in rows)
    # The dual bound over the flyable paths, as the plan command states it, is above the plan.
    assert all(float(row[4]) >= float(row[1]) for row in rows)
    for row, budget in zip(rows, (0.5, 5.0)):
        result = plan(paper_scenario('I', power_budget_w=budget))
        assert float(row[4]) == pytest.approx(result.tight_upper_bound, abs=1e-4)
    assert figure.stat().st_size > 0


@pytest.mark.parametrize('argv, message', [
    (['plan', '--nodes', '1,1;1,1'], 'duplicate ground nodes'),
    (['plan', '--slots', '5', '--horizon', '5'], 'goal unreachable'),
    (['plan', '--budget', '-1'], 'power_budget_w must be a positive finite number'),
    (['plan', '--json', '/no/such/folder/r.json'], "folder '/no/such/folder'"),
    (['plan', '--nodes', '1,2;3,4', '--max-nodes', '1'], 'too many ground nodes'),
])
def test_bad_input_ends_with_a_one_line_error(capsys, argv, message):
    status, out, err = run(capsys, *argv)
    assert status == 2
    assert message in err and err.count('\n') == 1
    assert 'proposed' not in out


def test_unreadable_scenario_file_is_reported(tmp_path, capsys):
    bad = tmp_path / 'bad.json'
    bad.write_text('{"ground_nodes_m": [[0, 0]], "altitude": 3}')
    status, _, err = run(capsys, 'plan', '--scenario', str(bad))
    assert status == 2 and "unknown scenario field(s) ['altitude']" in err
    status, _, err = run(capsys, 'plan', '--scenario', str(tmp_path / 'missing.json'))
    assert status == 2 and 'cannot read scenario file' in err


def test_letter_flag_runs_algorithm_1_from_the_straight_line_only(tmp_path, capsys):
    letter, default = tmp_path / 'letter.json', tmp_path / 'default.json'
    assert run(capsys, 'plan', '--letter', '--json', str(letter))[0] == 0
    assert run(capsys, 'plan', '--json', str(default))[0] == 0
    letter_plan, default_plan = json.loads(letter.read_text()), json.loads(default.read_text())
    assert letter_plan['start'] == 'straight'
    assert default_plan['min_throughput'] >= letter_plan['min_throughput'] * (1 - 1e-9)


def test_counts_are_in_the_singular_for_one(capsys):
    """PX4's 5 m/s over case I stops once: '1 stop', not '1 stops'."""
    from uav_comm_planner.core.numbers import counted
    from uav_comm_planner.tools.study.runner import format_run, StudyRun

    status, out, _ = run(capsys, 'plan', '--case', 'I', '--speed', '5', '--horizon', '500',
                         '--slots', '125', '--firmware', 'px4', '--vehicle')
    assert status == 0 and '; 2 legs, 1 stop, qF reached at' in out
    assert [counted(n, 'worker') for n in (0, 1, 2)] == ['0 workers', '1 worker', '2 workers']
    one = StudyRun(planned=10, failed=0, wall_s=1.0, workers=1, batch_size=2, cpu_s=1.0,
                   coordinator_cpu_s=0.1, startup_s=0.5, in_table=10, total=10)
    assert ' on 1 worker: ' in format_run(one)
