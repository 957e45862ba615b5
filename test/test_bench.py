"""The benchmark's smallest run, through its command line (``make bench`` runs it), read back
from its printed tables."""

import math
import os
from pathlib import Path
import re
import subprocess
import sys

import pytest

from devtools import bench
from devtools.bench import peak_memory_mib, share_lower_bound
from uav_comm_planner.core.drops import random_scenario


@pytest.fixture(scope='module')
def output():
    import contextlib
    import io

    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        # The flights are test_sitl_flight.py's: here only the solver's sections.
        assert bench.main(['--quick', '--no-flights']) == 0
    return buffer.getvalue()


def section(text: str, title: str) -> list[str]:
    """The lines of the section whose heading starts with ``title``."""
    body = text.split(f'\n== {title}', 1)[1]
    return body.split('\n== ', 1)[0].strip().splitlines()[1:]


def test_make_bench_runs_the_benchmark_from_devtools_not_the_installed_command(capsys):
    """``make bench`` runs ``python -m devtools.bench`` from the checkout (devtools/ is not
    installed), and the installed command has no ``bench`` any more."""
    checkout = Path(__file__).resolve().parents[1]
    done = subprocess.run(['make', '--no-print-directory', '--dry-run', '--always-make', 'bench',
                           'SITL=', f'VENV={sys.prefix}'], cwd=checkout, capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert f'{sys.prefix}/bin/python -m devtools.bench' in done.stdout.splitlines()[-1]
    helped = subprocess.run([sys.executable, '-m', 'devtools.bench', '--help'], cwd=checkout,
                            capture_output=True, text=True, timeout=60)
    assert helped.returncode == 0, helped.stderr
    assert helped.stdout.startswith('usage: python -m devtools.bench')
    from uav_comm_planner.tools import cli

    assert cli.main(['bench', '--quick']) == 2
    assert "invalid choice: 'bench'" in capsys.readouterr().err


def test_every_section_is_printed(output):
    assert output.startswith('uav_comm_planner benchmark (quick): Python 3.')
    for title in ('Speed:', 'Scaling:', 'Quality:', 'Quality, low SNR:'):
        assert f'\n== {title}' in output
    assert output.count('\n== Scaling:') == 2
    assert output.count('\n== Speed:') == 2
    assert output.count('\n== Energy:') == 1


def test_the_energy_table_keeps_the_budget_it_states(output):
    # The budgeted plan within its budget, below the free plan's energy, and within 5 % of its
    # throughput.
    rows = section(output, 'Energy:')[2:]
    free, kept = ([float(value) for value in row.split()[-3:]] for row in rows)
    budget = float(rows[1].split()[1])
    assert kept[2] <= budget + 1e-2 < free[2]
    assert kept[1] >= 0.95 * free[1]
    assert '\n== Flown:' not in output


def test_speed_table_shows_both_paths_reaching_the_same_objective(output):
    header, *rows = section(output, 'Speed:')
    assert header.split() == ['case', 'runs', 'reference_s', 'fast_s', 'ratio', 'fast_cold_s',
                              'cold_ratio', 'reference_bps', 'fast_bps', 'rel_diff', 'ref_MiB',
                              'fast_MiB', 'outer/sca_steps(ref', 'fast)']
    labels = [row[:15].strip() for row in rows]
    assert labels == ['letter case I', 'N=10, M=200']
    for row in rows:
        runs, reference_s, fast_s, ratio, cold_s, cold_ratio, reference, fast, difference, \
            *memory, steps_reference, steps_fast = row[15:].split()
        assert re.fullmatch(r'\d+/\d+', steps_fast) and re.fullmatch(r'\d+/\d+', steps_reference)
        assert int(runs) >= 1
        assert float(ratio.rstrip('x')) == pytest.approx(
            float(reference_s) / float(fast_s), rel=0.1, abs=0.1)
        assert float(cold_ratio.rstrip('x')) == pytest.approx(
            float(reference_s) / float(cold_s), rel=0.1, abs=0.1)
        assert float(fast) == pytest.approx(float(reference), rel=1e-6)
        assert float(difference) <= 1e-6
        assert all(float(mib) >= 0.0 for mib in memory)


@pytest.mark.parametrize('design', ['slots of 1 s', 'one 200 s flight'])
def test_scaling_tables_fit_an_exponent(output, design):
    header, *rows = section(output, f"Scaling: fast path, letter's settings, N = 20, {design}")
    assert header.split() == ['M', 'fast_s', 'sca_steps', 'us_per_slot_and_step']
    assert [int(row.split()[0]) for row in rows[:-1]] == [50, 100, 200]
    exponent = float(re.fullmatch(r'fitted exponent of M \(least squares, log-log\): (\S+)',
                                  rows[-1]).group(1))
    assert math.isfinite(exponent)


def test_the_default_speed_table_times_both_paths_on_the_same_plan(output):
    header, *rows = section(output, 'Speed: the default plan')
    assert header.split() == ['case', 'runs', 'reference_s', 'default_s', 'ratio', 'cold_s',
                              'reference_bps', 'default_bps']
    assert [row[:15].strip() for row in rows] == ['letter case I', 'N=10, M=200']
    for row in rows:
        runs, reference_s, default_s, ratio, cold_s, reference, default = row[15:].split()
        assert float(ratio.rstrip('x')) == pytest.approx(
            float(reference_s) / float(default_s), rel=0.1, abs=0.1)
        # The fast path's loose steps end where the stopping rule (relative 1e-4) stops.
        assert float(default) == pytest.approx(float(reference), rel=1e-3)


@pytest.mark.parametrize('title', ['Quality:', 'Quality, low SNR:'])
def test_quality_tables_compare_the_default_with_the_letter_the_best_known_and_the_bound(
        output, title):
    header, *rows = section(output, title)
    assert header.split() == ['N', 'M', 'letter_bps', 'default_bps', 'best_bps', 'bound_bps',
                              'default/letter', 'gap_to_best', 'gap_to_bound', 'old_gap',
                              'letter_s', 'default_s', 'start', 'best_from']
    cases = rows[:-2]
    assert len(cases) == 3
    within = 0
    for row in cases:
        n, m, letter, default, best, bound, ratio, gap_best, gap_bound, *_, source = row.split()
        assert 3 <= int(n) <= 20 and 51 <= int(m) <= 80
        assert float(ratio) == pytest.approx(float(default) / float(letter), rel=1e-5)
        assert float(letter) <= float(default) <= float(best) <= float(bound)
        gap = float(gap_best.rstrip('%'))
        assert gap == pytest.approx(100 * (1 - float(default) / float(best)), abs=1e-3)
        assert source in ('default', 'letter', 'tours')
        if source != 'tours':     # the default holds the letter's run: never below it
            assert gap == 0.0
        within += gap <= 0.1
    summary = re.match(r'default below the letter in (\d+) of (\d+) drops .*; within 0.1 % of '
                       r'the best known in (\d+) of (\d+) \((\d+)%, target 95%: (met|not met); '
                       r'90 % lower confidence bound (\d+)%\)', rows[-2])
    assert summary is not None and summary.group(1) == '0'
    assert int(summary.group(3)) == within and int(summary.group(4)) == len(cases)
    assert summary.group(6) == ('met' if within >= 0.95 * len(cases) else 'not met')
    assert int(summary.group(7)) <= int(summary.group(5))
    assert rows[-1].startswith('gap of the default to the dual bound: median ')


@pytest.mark.parametrize('hits, total', [(0, 5), (1, 1), (11, 12), (38, 40), (40, 40)])
def test_the_share_lower_bound_leaves_the_stated_chance_of_seeing_as_many_hits(hits, total):
    bound = share_lower_bound(hits, total)
    if hits == 0:
        assert bound == 0.0
        return

    def chance_of_at_least_hits(p):
        return sum(math.comb(total, k) * p ** k * (1 - p) ** (total - k)
                   for k in range(hits, total + 1))

    assert 0.0 < bound <= hits / total
    assert chance_of_at_least_hits(bound) == pytest.approx(0.1, abs=1e-9)


def test_peak_memory_counts_what_the_call_allocates():
    grown = peak_memory_mib(os.urandom, 64 * 1024 * 1024)
    assert 60.0 <= grown <= 200.0


def test_random_scenarios_are_reproducible_and_reachable():
    first = random_scenario(10, 200, 3, side_m=1500.0)
    assert first == random_scenario(10, 200, 3, side_m=1500.0)
    assert first != random_scenario(10, 200, 4, side_m=1500.0)
    assert first.slot_s == 1.0 and first.goal_m == (1500.0, 1500.0)


def test_a_cold_plan_builds_the_cone_structure_again_and_a_warm_one_reuses_it():
    from devtools.bench import FAST, timed_plan
    from uav_comm_planner.core.scenario import SolverSettings
    from uav_comm_planner.core.sca.block import Frame
    from uav_comm_planner.core.sca.program import cone_program, step_blocks

    scenario = random_scenario(3, 30, 1, side_m=800.0)
    settings = SolverSettings.letter(compute_baselines=False)

    def program():
        return cone_program(step_blocks(Frame.of(scenario)))

    timed_plan(scenario, settings, FAST)
    warm = program()
    timed_plan(scenario, settings, FAST)
    assert program() is warm
    timed_plan(scenario, settings, FAST, cold=True)
    assert program() is not warm


@pytest.mark.parametrize('title', ['Replans in flight: ', 'Replans in flight for PX4'])
def test_the_replans_sections_time_the_node_s_replan_warm_and_in_full(output, title):
    lines = section(output, title)
    assert lines[0].split() == ['seed', 'flown', 'off_m', 'full_s', 'warm_s', 'speed-up',
                                'full_bps', 'warm_bps', 'change']
    rows = [line.split() for line in lines[1:] if line[:1] == ' ']
    assert rows
    for seed, flown, off, full_s, warm_s, speedup, full_bps, warm_bps, change in rows:
        assert float(full_s) > 0 and float(warm_s) > 0
        # The speed-up is full_s / warm_s before the three columns were rounded: within the
        # ratios their printed digits allow (half a unit of the last digit each).
        full, warm, half = float(full_s), float(warm_s), 0.0005
        assert (full - half) / (warm + half) - 0.05 <= float(speedup[:-1]) \
            <= (full + half) / (warm - half) + 0.05
        assert float(change[:-1]) / 100 == pytest.approx(
            float(warm_bps) / float(full_bps) - 1, abs=2e-5)
    assert any(line.startswith('warm replan: median') and 'under 150 ms in' in line
               for line in lines)
    if 'PX4' in title:
        return
    summary = next(line for line in lines if 'random replans' in line)
    assert re.match(r'3 random replans: warm median \d+\.\d+ s, full search \d+\.\d+ s; warm '
                    r'more than 0\.1 % below the full search in \d', summary)


def test_the_fleet_section_plans_one_two_and_three_uavs(output):
    rows = [line.split() for line in section(output, 'Fleets')[1:]]
    assert [row[0] for row in rows] == ['1', '2', '3']
    for row in rows[1:]:
        assert float(row[3]) >= float(row[5])         # at least the best single-UAV plan
        assert float(row[6]) >= 100.0                  # d_min kept
