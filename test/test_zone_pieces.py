"""The fast step imposes the rows of the zone pieces nearest each slot only, and solves again
with more (those nearest the answer among them) while its answer breaks a row left out: its
answers keep the whole restriction and reach its optimum, and its plans reach the same rates,
at a fraction of the rows. (The max-min step's optimum is seldom one point: slots that bind
no node may sit anywhere on the optimal face, and an interior-point solver's answer there
depends on the rows it has, so answers are compared by their value and their rows.)"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_hardening_scale import star

from uav_comm_planner import paper_scenario, plan
from uav_comm_planner.core.detour import straight_start
from uav_comm_planner.core.sca import fast
from uav_comm_planner.core.sca.fast import ClarabelTrajectoryStep
from uav_comm_planner.core.zone_rows import zone_model
from uav_comm_planner.core.zones import Zones

#: A 1000-vertex star round node 2 (1000, 200), the straight line q0 -> qF through it.
SCENARIO = dataclasses.replace(
    paper_scenario('I'), horizon_s=60.0,
    zones=Zones(keep_out=(star(1000, centre=(1000.0, 120.0)),), margin_m=5.0))


def stepper(pieces: int | None) -> ClarabelTrajectoryStep:
    step = ClarabelTrajectoryStep(SCENARIO, cache=None)
    step.zone_pieces = pieces
    step._configure()
    return step


@pytest.mark.parametrize('pieces', [1, 4, fast.NEAREST_PIECES])
def test_a_step_with_the_nearest_pieces_is_the_step_with_them_all(pieces):
    q_k = straight_start(SCENARIO)
    p = np.full((SCENARIO.num_nodes, SCENARIO.num_slots), SCENARIO.power_budget_w)
    every = stepper(None)(q_k, p, SCENARIO)
    some = stepper(pieces)
    nearest = some(q_k, p, SCENARIO)
    count = len(zone_model(SCENARIO.zones).polygons)
    print(f'{count} pieces; {pieces} per slot grew to {some.zone_pieces}')
    if pieces == 1:
        assert some.zone_pieces > 1        # an answer broke a row left out: solved again
    assert nearest.bound == pytest.approx(every.bound, rel=1e-7)
    path = np.vstack([SCENARIO.start_m, q_k, SCENARIO.goal_m])
    assert zone_model(SCENARIO.zones).rows(path).slack(nearest.q).min() >= -1e-6
    k_rows = zone_model(SCENARIO.zones).pieces_rows_per_slot(some.zone_pieces)
    assert some.zone_pieces >= count or k_rows < zone_model(SCENARIO.zones).rows_per_slot


def test_plans_with_the_nearest_pieces_are_the_plans_with_them_all(monkeypatch):
    nearest = plan(SCENARIO)
    monkeypatch.setattr(fast, 'NEAREST_PIECES', 10 ** 6)
    every = plan(SCENARIO)
    print(f'min rate {nearest.min_throughput:.6f} and {every.min_throughput:.6f}; '
          f'{nearest.trajectory_steps} and {every.trajectory_steps} steps')
    assert nearest.min_throughput == pytest.approx(every.min_throughput, rel=1e-6)
    assert SCENARIO.zones.path_clearance(np.vstack([SCENARIO.start_m, nearest.trajectory,
                                                    SCENARIO.goal_m])) >= 5.0 - 1e-6
