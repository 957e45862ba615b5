"""The letter's Section IV claims, for both of its cases, as this package computes them."""

import numpy as np
import pytest

from uav_comm_planner import paper_scenario, plan
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
