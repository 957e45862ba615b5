"""The letter's Section IV claims, for both of its cases, as this package computes them."""

from pathlib import Path

import numpy as np
import pytest

from uav_comm_planner import paper_scenario, plan, SolverSettings
from uav_comm_planner.core.model import speeds

SWEEP_BUDGETS_W = (0.5, 1.0, 2.0, 5.0, 10.0, 20.0)


@pytest.fixture(scope='module', params=['I', 'II'])
def letter_plan(request):
    return plan(paper_scenario(request.param))


def test_path_passes_within_20_m_of_every_node(letter_plan):
    q, w = letter_plan.trajectory, letter_plan.scenario.nodes
    closest = np.linalg.norm(q[None, :, :] - w[:, None, :], axis=-1).min(axis=1)
    assert closest.max() < 20.0, closest


def test_uav_hovers_somewhere(letter_plan):
    assert speeds(letter_plan.trajectory, letter_plan.scenario).min() < 1.0


def test_node_2_gets_the_least_total_power(letter_plan):
    totals = letter_plan.power.sum(axis=1)
    assert np.argmin(totals) == 1, totals


def test_node_2_gets_the_least_power_in_every_slot(letter_plan):
    # The letter: "the transmit power for node 2 is always lower than other nodes".
    p = letter_plan.power
    assert np.all(p[1] < p[0]) and np.all(p[1] < p[2])


@pytest.mark.parametrize('case', ['I', 'II'])
def test_proposed_beats_both_baselines_at_every_budget(case):
    for budget in SWEEP_BUDGETS_W:
        result = plan(paper_scenario(case, power_budget_w=budget))
        assert result.min_throughput > result.baselines['straight'], budget
        assert result.min_throughput > result.baselines['static'], budget


README = Path(__file__).resolve().parents[1] / 'README.md'
MODEL_DOC = Path(__file__).resolve().parents[1] / 'docs' / 'model.md'
#: The published table (docs/model.md), bit/s to 4 decimals: case -> (letter, default,
#: straight line, static point, upper bound).
PUBLISHED = {'I': (11.5533, 11.5728, 11.2315, 11.3511, 13.1770),
             'II': (11.5700, 11.5917, 11.4049, 11.3511, 13.1770)}


@pytest.mark.parametrize('case', ['I', 'II'])
def test_the_published_figures_are_what_the_planner_computes(case):
    letter = plan(paper_scenario(case), SolverSettings.letter())
    default = plan(paper_scenario(case))
    computed = (letter.min_throughput, default.min_throughput, default.baselines['straight'],
                default.baselines['static'], default.upper_bound)
    assert [round(value, 4) for value in computed] == list(PUBLISHED[case])


def test_the_readme_and_the_model_page_state_those_figures():
    joint, straight, static = (f'{value:.4f}' for value in PUBLISHED['I'][1:4])
    readme = ' '.join(README.read_text(encoding='utf-8').split())
    assert (f'prints {joint} bit/s for the joint design against {straight} for the straight '
            f'line and {static} for a static access point') in readme
    rows = [line for line in MODEL_DOC.read_text(encoding='utf-8').splitlines()
            if line.startswith('| ') and '|' in line[2:]]
    for column, case in ((1, 'I'), (2, 'II')):
        cells = {row.split('|')[1].strip(): row.split('|')[1 + column].strip() for row in rows}
        figures = [cells[label] for label in (
            "Algorithm 1 from the straight line, epsilon = 0.01 (`--letter`)",
            "default: the best of the letter's run, the hover-and-fly start and screened tours, "
            'relative tolerance 1e-4',
            'straight line at uniform speed, optimal power',
            'static access point above the centroid, optimal power',
            'upper bound: every channel at its best (beta0 / H^2), budget split evenly')]
        assert figures == [f'{value:.4f}' for value in PUBLISHED[case]], case
