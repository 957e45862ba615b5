"""Monte Carlo studies: the design's draws, the rows against independent computations, the
tables, resuming, and the same table from one and from two Dask workers."""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from uav_comm_planner.core.optimizer import plan, throughput_upper_bound
from uav_comm_planner.core.scenario import SolverSettings
from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.tools import cli
from uav_comm_planner.tools.study import methods
from uav_comm_planner.tools.study.design import (Draw, row_settings, scenario_at, StudyDesign,
                                                 StudyError)
from uav_comm_planner.tools.study.runner import dask_client, Progress, run_study, worker_info
from uav_comm_planner.tools.study.tables import (columns, evaluate, open_table, plan_batch,
                                                 read_table, saved_design)

#: The quick study of the tests: 40 drops, N 2..4, M 20 (tens of milliseconds each).
QUICK = dict(cases=40, seed=7, draws={'nodes': '2:4', 'slots': '20', 'side_m': '800'})


def values_only(rows: list[dict]) -> list[dict]:
    """Rows without the wall times, which differ from run to run."""
    return [{k: v for k, v in row.items() if not k.endswith('_s') or k == 'horizon_s'}
            for row in rows]


def run_cli(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(['montecarlo', *argv])
    return code, out.getvalue(), err.getvalue()


# --- the design ------------------------------------------------------------------------------

@pytest.mark.parametrize('text, grid, low, high, log', [
    ('5', (5.0,), None, None, False),
    ('1,2,5', (1.0, 2.0, 5.0), None, None, False),
    ('4:12', (), 4.0, 12.0, False),
    ('0.5:20:log', (), 0.5, 20.0, True),
    ('-170:-160', (), -170.0, -160.0, False),
])
def test_draws_read_values_grids_and_ranges(text, grid, low, high, log):
    draw = Draw.parse(text)
    assert draw.grid == grid and draw.log == log
    if low is not None:
        assert (draw.low, draw.high) == (low, high)
    assert Draw.parse(draw.text) == draw


@pytest.mark.parametrize('text, integer, match', [
    ('12:4', True, 'low < high'), ('a:b', False, 'expected a value'),
    ('1:2:3', False, 'expected a value'), ('2.5:6', True, 'integer bounds'),
    ('0:5:log', False, 'positive bounds'), ('4:8:log', True, 'real setting'),
    ('1,1', False, 'repeated'), ('nan', False, 'finite'), ('2.5', True, 'integers'),
])
def test_bad_draws_are_refused_with_a_reason(text, integer, match):
    with pytest.raises(InvalidScenarioError, match=match):
        Draw.parse(text, integer=integer)


def test_integer_ranges_reach_both_ends_and_log_ranges_are_uniform_in_log():
    rng = np.random.default_rng(0)
    whole = Draw.parse('4:12', integer=True)
    assert {whole.sample(rng) for _ in range(400)} == set(range(4, 13))
    log = Draw.parse('1:10000:log')
    exponents = np.log10([log.sample(rng) for _ in range(4000)])
    assert exponents.min() >= 0 and exponents.max() <= 4
    # Uniform on [0, 4]: mean 2, a quarter in each unit.
    assert exponents.mean() == pytest.approx(2.0, abs=0.1)
    assert np.histogram(exponents, bins=4, range=(0, 4))[0] / 4000 == pytest.approx(
        [0.25] * 4, abs=0.03)


def test_a_row_is_drawn_from_the_study_seed_and_its_drop_alone():
    design = StudyDesign(cases=6, seed=11, draws={'nodes': '3:9', 'side_m': '1000'})
    scenario = scenario_at(design, 4)
    # Independently: drop 4's three streams; nodes from the second, N from the first.
    settings_rng, nodes_rng, _ = (np.random.default_rng(s) for s in
                                  np.random.SeedSequence(11, spawn_key=(4,)).spawn(3))
    n = int(settings_rng.integers(3, 9, endpoint=True))
    assert scenario.num_nodes == n
    np.testing.assert_array_equal(scenario.nodes, nodes_rng.uniform(0.0, 1000.0, size=(n, 2)))
    # The same whatever was drawn before, and different for another drop.
    assert [row_settings(design, i)[0] for i in (5, 4, 3)][1] == row_settings(design, 4)[0]
    assert scenario_at(design, 4) == scenario and scenario_at(design, 3) != scenario


def test_grid_points_share_the_drops_of_their_rows():
    design = StudyDesign(cases=3, seed=2, draws={'nodes': '3,6', 'power_budget_w': '1,5'})
    assert design.total_rows == 12 and len(design.grid_points) == 4
    rows = [row_settings(design, i)[0] for i in range(12)]
    assert [(r['drop'], r['nodes'], r['power_budget_w']) for r in rows[:4]] == [
        (0, 3, 1.0), (0, 3, 5.0), (0, 6, 1.0), (0, 6, 5.0)]
    assert [r['drop'] for r in rows] == [0] * 4 + [1] * 4 + [2] * 4
    for drop in range(3):
        three, _, six, _ = (scenario_at(design, 4 * drop + k) for k in range(4))
        np.testing.assert_array_equal(three.nodes, six.nodes[:3])


def test_the_disc_the_square_and_the_endpoint_rules():
    for area in ('square', 'disc'):
        for endpoints in ('diagonal', 'across', 'centre', 'random'):
            design = StudyDesign(cases=5, seed=1, area=area, endpoints=endpoints,
                                 draws={'nodes': '20', 'side_m': '1000', 'slots': '40'})
            for index in range(5):
                scenario = scenario_at(design, index)
                w = scenario.nodes
                assert np.all((w >= 0) & (w <= 1000))
                if area == 'disc':
                    assert np.all(np.linalg.norm(w - 500.0, axis=1) <= 500.0)
                if endpoints == 'diagonal':
                    assert (scenario.start_m, scenario.goal_m) == ((0, 0), (1000, 1000))
                elif endpoints == 'across':
                    assert (scenario.start_m, scenario.goal_m) == ((0, 500), (1000, 500))
                elif endpoints == 'centre':
                    assert scenario.start_m == scenario.goal_m == (500, 500)
                elif area == 'disc':
                    for point in (scenario.start_m, scenario.goal_m):
                        assert math.dist(point, (500, 500)) <= 500
    # The disc's nodes fill it: a quarter of them within half the radius.
    w = scenario_at(StudyDesign(cases=1, area='disc', draws={'nodes': '4000',
                                                             'side_m': '1000'}), 0).nodes
    assert np.mean(np.linalg.norm(w - 500.0, axis=1) <= 250.0) == pytest.approx(0.25, abs=0.03)


def test_designs_refuse_unknown_settings_and_methods():
    with pytest.raises(InvalidScenarioError, match='unknown settings'):
        StudyDesign(cases=1, draws={'speed': '3'})
    with pytest.raises(InvalidScenarioError, match='methods must name'):
        StudyDesign(cases=1, methods=('default', 'magic'))
    with pytest.raises(InvalidScenarioError, match='cases'):
        StudyDesign(cases=0)
    with pytest.raises(InvalidScenarioError, match='area'):
        StudyDesign(cases=1, area='hexagon')


# --- rows ------------------------------------------------------------------------------------

def test_a_row_holds_every_method_computed_as_plan_computes_it():
    design = StudyDesign(cases=3, seed=5, draws={'nodes': '3:5', 'slots': '30',
                                                 'side_m': '1000'})
    row = evaluate(design, 2)
    scenario = scenario_at(design, 2)
    assert row['nodes'] == scenario.num_nodes and row['status'] == 'ok' and row['error'] == ''
    default = plan(scenario, SolverSettings())
    letter = plan(scenario, SolverSettings.letter(compute_baselines=False))
    assert row['default_bps'] == default.min_throughput
    assert row['default_iterations'] == default.outer_iterations
    assert row['default_sca_steps'] == default.trajectory_steps
    assert row['letter_bps'] == letter.min_throughput
    # The baselines through another path of the optimizer: plan's own baseline_rates.
    assert row['straight_bps'] == pytest.approx(default.baselines['straight'], rel=1e-12)
    assert row['static_bps'] == pytest.approx(default.baselines['static'], rel=1e-12)
    assert row['bound_bps'] == throughput_upper_bound(scenario)
    assert max(row['default_bps'], row['letter_bps']) <= row['bound_bps']
    # The dual bound at the hover start's multipliers: above both plans, below the old bound.
    assert max(row['default_bps'], row['letter_bps']) <= row['dual_bound_bps']
    assert row['dual_bound_bps'] <= row['bound_bps']
    assert row['dual_bound_status'] == 'bound'
    assert [name for name, _ in columns(design)] == list(row)


def test_a_refused_scenario_and_a_failing_method_become_rows_with_their_error(monkeypatch):
    far = StudyDesign(cases=2, draws={'slots': '5', 'side_m': '5000'})
    row = evaluate(far, 0)
    assert row['status'] == 'invalid' and 'goal unreachable' in row['error']
    assert row['default_bps'] is None and row['default_status'] == 'skipped'

    def broken(scenario):
        raise ZeroDivisionError('solver exploded')

    monkeypatch.setitem(methods.METHODS, 'letter', methods.Method('broken', broken))
    row = evaluate(StudyDesign(cases=1, draws={'nodes': '3', 'slots': '20',
                                               'side_m': '800'}), 0)
    assert row['status'] == 'failed'
    assert row['error'] == 'letter: ZeroDivisionError: solver exploded'
    assert row['letter_bps'] is None and row['letter_status'] == 'error'
    assert row['default_status'] == 'converged' and row['bound_bps'] > 0


# --- tables ----------------------------------------------------------------------------------

@pytest.mark.parametrize('suffix', ['.parquet', '.csv'])
def test_tables_keep_rows_types_and_missing_values(tmp_path, suffix):
    design = StudyDesign(cases=2, draws={'nodes': '3', 'slots': '10,40', 'side_m': '2000'})
    rows = plan_batch(design, [0, 1, 2, 3])
    assert [row['status'] for row in rows] == ['invalid', 'ok'] * 2
    table, done = open_table(tmp_path / f't{suffix}', design)
    assert done == set()
    table.append(rows[:2])
    table.append(rows[2:])
    _, back = read_table(tmp_path / f't{suffix}')
    assert back == rows
    assert open_table(tmp_path / f't{suffix}', design)[1] == {0, 1, 2, 3}


def test_a_csv_line_cut_by_a_crash_is_dropped_on_resume(tmp_path):
    design = StudyDesign(**QUICK)
    table, _ = open_table(tmp_path / 't.csv', design)
    table.append(plan_batch(design, [0, 1]))
    with open(tmp_path / 't.csv', 'a') as handle:
        handle.write('2,0,7,square,diag')
    assert open_table(tmp_path / 't.csv', design)[1] == {0, 1}
    assert (tmp_path / 't.csv').read_text().endswith('\n')


def test_a_table_of_another_study_is_refused(tmp_path):
    open_table(tmp_path / 't.parquet', StudyDesign(**QUICK))
    other = StudyDesign(**{**QUICK, 'seed': 8, 'draws': {**QUICK['draws'], 'slots': '30'}})
    with pytest.raises(StudyError, match='differs in seed, slots'):
        open_table(tmp_path / 't.parquet', other)
    more = StudyDesign(**{**QUICK, 'cases': 80})
    assert open_table(tmp_path / 't.parquet', more)[1] == set()
    assert saved_design(tmp_path / 't.parquet').cases == 80


# --- on Dask ---------------------------------------------------------------------------------

@pytest.fixture(scope='module')
def scheduler():
    """An embedded cluster of two workers, started while the caller asks for four BLAS
    threads: its address stands for a cluster started by hand."""
    saved = os.environ.get('OMP_NUM_THREADS')
    os.environ['OMP_NUM_THREADS'] = '4'
    try:
        with dask_client(workers=2) as client:
            threads = {info['omp_num_threads'] for info in client.run(worker_info).values()}
            assert os.environ['OMP_NUM_THREADS'] == '4'
            yield client.scheduler.address, threads, client.nthreads()
    finally:
        if saved is None:
            os.environ.pop('OMP_NUM_THREADS')
        else:
            os.environ['OMP_NUM_THREADS'] = saved


def test_the_embedded_cluster_has_single_threaded_workers_with_one_blas_thread(scheduler):
    _, threads, nthreads = scheduler
    assert threads == {'1'}
    assert sorted(nthreads.values()) == [1, 1]


@pytest.fixture(scope='module')
def quick_tables(tmp_path_factory, scheduler):
    folder = tmp_path_factory.mktemp('quick')
    design = StudyDesign(**QUICK)
    one = run_study(design, folder / 'one.parquet', workers=1)
    two = run_study(design, folder / 'two.parquet', scheduler=scheduler[0])
    print(f'\nquick study: 1 worker {one.rate:.1f} scenarios/s, 2 workers {two.rate:.1f} '
          f'scenarios/s ({two.rate / one.rate:.2f}x; tiny scenarios, so task overhead shows)')
    return design, folder, one, two


def test_one_and_two_workers_give_the_same_table_row_for_row(quick_tables):
    design, folder, one, two = quick_tables
    assert (one.planned, one.workers, two.planned, two.workers) == (40, 1, 40, 2)
    _, rows_one = read_table(folder / 'one.parquet')
    _, rows_two = read_table(folder / 'two.parquet')
    assert [row['index'] for row in rows_one] == list(range(40))
    assert values_only(rows_one) == values_only(rows_two)
    # And the rows planned in this process, without Dask.
    assert values_only(rows_one[::9]) == values_only(plan_batch(design, range(0, 40, 9)))
    assert all(row['status'] == 'ok' for row in rows_one)
    parts = list((folder / 'two.parquet').glob('part-*.parquet'))
    assert len(parts) == math.ceil(40 / two.batch_size)


@pytest.mark.parametrize('suffix', ['.parquet', '.csv'])
def test_a_stopped_study_resumes_without_losing_or_repeating_rows(
        tmp_path, scheduler, quick_tables, suffix):
    design, folder, _, _ = quick_tables
    out = tmp_path / f'study{suffix}'
    first = run_study(design, out, scheduler=scheduler[0], limit=13, batch_size=4)
    assert (first.planned, first.in_table) == (13, 13)
    _, rows = read_table(out)
    assert [row['index'] for row in rows] == list(range(13))
    # Through the command line, with the table's own design (no design option given).
    code, printed, _ = run_cli('--out', str(out), '--scheduler', scheduler[0], '--quiet')
    assert code == 0, printed
    assert 'planned 27 scenarios' in printed and '40 of 40 rows in the table' in printed
    _, rows = read_table(out)
    assert [row['index'] for row in rows] == list(range(40))
    _, reference = read_table(folder / 'one.parquet')
    assert values_only(rows) == values_only(reference)
    code, printed, _ = run_cli('--out', str(out), '--scheduler', scheduler[0])
    assert code == 0 and 'nothing to plan: 40 of 40 rows' in printed


@pytest.mark.slow
def test_ctrl_c_stops_the_study_and_the_same_command_goes_on(tmp_path, scheduler):
    """The command in its own process group, interrupted as a terminal's Ctrl-C does."""
    out = tmp_path / 'study.parquet'
    command = [sys.executable, '-m', 'uav_comm_planner.tools.study', '--cases', '400',
               '--nodes', '2:4', '--slots', '20', '--side', '800', '--seed', '3',
               '--out', str(out), '--workers', '1', '--batch', '5']
    process = subprocess.Popen(command, start_new_session=True, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    began = time.monotonic()
    while len(list(out.glob('part-*.parquet'))) < 2 and time.monotonic() - began < 60:
        assert process.poll() is None, process.communicate()
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGINT)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130, err
    assert 'interrupted: ' in err and 'run the same command to go on' in err
    design, kept = read_table(out)
    assert 10 <= len(kept) < 400
    assert sorted(row['index'] for row in kept) == [row['index'] for row in kept]
    done = {row['index'] for row in kept}
    assert len(done) == len(kept)
    rest = run_study(design, out, scheduler=scheduler[0])
    assert rest.planned == 400 - len(kept)
    _, rows = read_table(out)
    assert [row['index'] for row in rows] == list(range(400))
    assert values_only(rows[::37]) == values_only(plan_batch(design, range(0, 400, 37)))


def test_progress_shows_the_rows_the_rate_and_the_time_left():
    class Terminal(io.StringIO):
        def isatty(self):
            return True

    terminal = Terminal()
    bar = Progress(100, 20, terminal)
    bar.began -= 2.0
    bar.update(10, 1)
    line = terminal.getvalue()
    assert line.startswith('\rmontecarlo 30/100 rows [' + '#' * 7 + ' ' * 17 + ']  30% ')
    rate, left = re.search(r'([\d.]+) scenarios/s, (\d+) s left, 1 failed$', line).groups()
    assert float(rate) == pytest.approx(5.0, rel=0.05)
    assert int(left) == pytest.approx(14, abs=1)
    log = io.StringIO()
    bar = Progress(10, 0, log, every_s=3600.0)
    bar.update(3, 0)
    bar.update(3, 0)
    bar.show(final=True)
    assert [line.split(' [')[0] for line in log.getvalue().splitlines()] == [
        'montecarlo 3/10 rows', 'montecarlo 6/10 rows']


# --- command line ----------------------------------------------------------------------------

def test_without_dask_the_command_says_how_to_install_it(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, 'distributed', None)
    code, _, err = run_cli('--quick', '--out', str(tmp_path / 's.parquet'))
    assert code == 2
    assert err.count('\n') == 1 and "pip install 'uav_comm_planner[study]'" in err
    assert not (tmp_path / 's.parquet').exists()


@pytest.mark.parametrize('argv, match', [
    (['--nodes', '12:4'], 'low < high'),
    (['--out', 'study.txt'], 'name a .parquet folder or a .csv file'),
    (['--out', 'missing/s.csv'], 'does not exist'),
    (['--figure', 'cdf.svg'], 'name a .pdf or .png'),
    (['--methods', 'default,oracle'], 'methods must name'),
    (['--limit', '0'], '--limit must be >= 1'),
    (['--workers', '0'], '--workers must be >= 1'),
])
def test_bad_options_end_with_one_line_and_status_2(tmp_path, monkeypatch, argv, match):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli('--quick', *argv)
    assert code == 2 and err.count('\n') == 1 and match in err, err


# --- figures ---------------------------------------------------------------------------------

def test_mean_interval_uses_student_t():
    from uav_comm_planner.tools.study.plots import mean_interval
    mean, half = mean_interval(np.array([1.0, 3.0]))
    # t_{0.975, 1} = 12.706; s = sqrt(2), s / sqrt(2) = 1.
    assert (mean, half) == (2.0, pytest.approx(12.7062, abs=1e-4))
    values = np.arange(10.0)
    mean, half = mean_interval(values)
    assert half == pytest.approx(2.2622 * values.std(ddof=1) / np.sqrt(10), rel=1e-4)


def test_a_drawn_real_setting_is_grouped_into_equal_count_bins():
    from uav_comm_planner.tools.study.plots import groups
    x = np.random.default_rng(1).uniform(1.0, 10.0, 100)
    bins = groups(x)
    assert len(bins) == 8 and sorted(np.concatenate(bins).tolist()) == list(range(100))
    assert {b.size for b in bins} == {12, 13}
    assert all(x[a].max() <= x[b].min() for a, b in zip(bins, bins[1:]))
    few = np.array([3.0, 1.0, 3.0])
    assert [few[b].tolist() for b in groups(few)] == [[1.0], [3.0, 3.0]]


def test_gain_table_groups_rows_by_the_setting(quick_tables):
    from uav_comm_planner.tools.study.plots import gain_table
    design, folder, _, _ = quick_tables
    _, rows = read_table(folder / 'one.parquet')
    table = gain_table(design, rows, 'nodes')
    assert set(table) == {(m, b) for m in ('default', 'letter') for b in ('straight', 'static')}
    points = table[('default', 'straight')]
    assert [x for x, *_ in points] == [2.0, 3.0, 4.0]
    assert sum(n for *_, n in points) == 40
    three = [100 * (r['default_bps'] / r['straight_bps'] - 1) for r in rows if r['nodes'] == 3]
    assert points[1][1] == pytest.approx(np.mean(three)) and points[1][3] == len(three)


def test_the_command_draws_the_figures_from_the_table(quick_tables, tmp_path, scheduler):
    """Into folders it makes when they are missing."""
    design, folder, _, _ = quick_tables
    figures = tmp_path / 'figures' / 'png'
    code, printed, _ = run_cli('--out', str(folder / 'one.parquet'), '--figure',
                               str(tmp_path / 'cdf' / 'cdf.pdf'), '--figures-dir', str(figures),
                               '--figure-format', 'png', '--scheduler', scheduler[0])
    assert code == 0, printed
    assert (tmp_path / 'cdf' / 'cdf.pdf').read_bytes().startswith(b'%PDF')
    for name in ('cdf.png', 'gain_vs_nodes.png', 'time_vs_slots.png'):
        assert (figures / name).read_bytes().startswith(b'\x89PNG'), name
    assert 'default over straight: mean gain' in printed
    assert re.search(r'default over static: mean gain -?\d+\.\d % \(the static point ignores '
                     r'launch and landing\)', printed)


def test_a_figure_folder_that_cannot_be_made_fails_before_the_study(tmp_path):
    (tmp_path / 'taken').write_text('')
    code, _, err = run_cli('--quick', '--out', str(tmp_path / 's.csv'), '--figures-dir',
                           str(tmp_path / 'taken' / 'figs'))
    assert code == 2 and err.count('\n') == 1 and 'cannot make the figure folder' in err
    assert not (tmp_path / 's.csv').exists()
