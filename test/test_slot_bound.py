"""A plan's slot count is bounded before any work: N = 1 and M = 100 000 are within the
compute budget N x M, but a plan that long took well over a minute of cone programmes; it is
refused at once with the bound named, through the API and on the command line."""

from __future__ import annotations

import dataclasses
import json

import pytest
from test_hardening import one_line_refusal, peak_bytes

from uav_comm_planner import ComputeBudgetError, paper_scenario, plan
from uav_comm_planner.core.scenario import MAX_SLOTS, SolverSettings


def one_node(slots: int):
    return dataclasses.replace(paper_scenario('I'), ground_nodes_m=((1000.0, 300.0),),
                               num_slots=slots, horizon_s=float(slots))


def test_a_plan_of_more_slots_than_the_bound_is_refused_before_any_work():
    scenario = one_node(100_000)
    assert scenario.num_nodes * scenario.num_slots <= SolverSettings().max_node_slots
    with pytest.raises(ComputeBudgetError, match=f'M = 100000 exceeds the most a plan takes, '
                                                 f'MAX_SLOTS = {MAX_SLOTS}'):
        plan(scenario)
    assert peak_bytes(lambda: plan(scenario)) < 1_000_000
    # One more than the bound is refused; the bound itself passes the check.
    with pytest.raises(ComputeBudgetError, match='MAX_SLOTS'):
        SolverSettings().check(one_node(MAX_SLOTS + 1))
    SolverSettings().check(one_node(MAX_SLOTS))


def test_the_command_line_refuses_it_in_one_line(tmp_path, capsys):
    folder = tmp_path / 'in'
    folder.mkdir()
    scenario = folder / 's.json'
    scenario.write_text(json.dumps({'ground_nodes_m': [[1000, 300]], 'num_slots': 100000,
                                    'horizon_s': 100000}))
    out = tmp_path / 'out'
    out.mkdir()
    err = one_line_refusal(capsys, out, ['plan', '--scenario', str(scenario),
                                         '--json', str(out / 'r.json')])
    assert f'MAX_SLOTS = {MAX_SLOTS}' in err
