"""A constraint added as one block: a box geofence, written once, held by both trajectory paths.

``BoxFence`` is what docs/extending.md asks a user to write: one class, its cvxpy constraints,
its cone rows and its part of the dual certificate; the tests hold the reference step and the
fast step to the same answer with it, and plans on both paths inside it.
"""

from __future__ import annotations

from typing import Any, Sequence

import clarabel
import cvxpy as cp
import numpy as np
import pytest

from uav_comm_planner import paper_scenario, plan, SolverSettings
from uav_comm_planner.core.initial import straight_line
from uav_comm_planner.core.model import snr_per_watt
from uav_comm_planner.core.power import waterfilling_power
from uav_comm_planner.core.sca.block import (Block, Columns, DualBound, Entries, Expansion,
                                             Frame, Variables)
from uav_comm_planner.core.sca.fast import trajectory_step_clarabel
from uav_comm_planner.core.sca.program import cone_program, step_blocks
from uav_comm_planner.core.sca.reference import certify, trajectory_step_cvxpy
from uav_comm_planner.errors import InvalidScenarioError


class BoxFence(Block):
    """lower <= q[m] <= upper for every slot point (x and y, metres): 4 M linear rows.

    Cone rows, per slot m: upper_x - z_x, upper_y - z_y, z_x - lower_x, z_y - lower_y >= 0
    (s = b - A x: A = +1 on z with b = upper, A = -1 with b = -lower, in the frame's km).
    Certificate: eta >= 0 per row adds eta . slack, supergradient -eta_upper + eta_lower.
    """

    def __init__(self, frame: Frame, lower_m: tuple[float, float],
                 upper_m: tuple[float, float]):
        super().__init__(frame)
        self.lower, self.upper = frame.km(lower_m), frame.km(upper_m)
        self.lower_m, self.upper_m = np.asarray(lower_m, float), np.asarray(upper_m, float)
        self.num_slots = frame.scenario.num_slots

    @property
    def form(self) -> tuple:
        return ('box fence', self.num_slots)

    def cones(self) -> tuple:
        return (clarabel.NonnegativeConeT(4 * self.num_slots),)

    def pattern(self, columns: Columns) -> Entries:
        rows = np.arange(4 * self.num_slots).reshape(-1, 4)
        return Entries(rows=rows.ravel(),
                       cols=np.concatenate([columns.z, columns.z], axis=1).ravel(),
                       values=np.tile([1.0, 1.0, -1.0, -1.0], self.num_slots))

    def right_hand_side(self) -> np.ndarray:
        return np.tile(np.concatenate([self.upper, -self.lower]), self.num_slots)

    def constraints(self, v: Variables, data: Any) -> list[cp.Constraint]:
        return [v.z <= self.upper[None, :], v.z >= self.lower[None, :]]

    def certificate(self, z: np.ndarray, data: Any, duals: Sequence,
                    bound: DualBound) -> DualBound | None:
        upper, lower = self.upper - z, z - self.lower
        if min(upper.min(), lower.min()) < -1e-7:
            return None
        eta_upper, eta_lower = (np.maximum(np.asarray(d, dtype=float), 0.0) for d in duals)
        return bound.plus(float((eta_upper * upper).sum() + (eta_lower * lower).sum()),
                          eta_lower - eta_upper)

    def holds(self, q: np.ndarray, data: Any, slack: float) -> bool:
        scale = slack * max(1.0, float(np.abs(q).max()))
        return bool(np.all(q <= self.upper_m + scale) and np.all(q >= self.lower_m - scale))

    def admits(self, q: np.ndarray) -> bool:
        return self.holds(q, None, 0.0)


def fence(lower_m=(-50.0, -50.0), upper_m=(2050.0, 250.0)):
    """Case I's start (0, 0) and goal (2000, 0) inside; its nodes at y = 400 and 200 outside
    or on the edge, so the unconstrained plan leaves the box."""
    return lambda frame: BoxFence(frame, lower_m, upper_m)


CASES = {'I': dict(), 'I-low-snr': dict(bandwidth_hz=1e6, reference_gain=1e-6, power_budget_w=0.5)}


def expansion(scenario):
    q = straight_line(scenario)
    return q, waterfilling_power(snr_per_watt(q, scenario), scenario.power_budget_w).p


def inside(q, lower=(-50.0, -50.0), upper=(2050.0, 250.0), tolerance=1e-6):
    return bool(np.all(q >= np.array(lower) - tolerance)
                and np.all(q <= np.array(upper) + tolerance))


@pytest.mark.parametrize('case', sorted(CASES))
def test_both_steps_keep_the_fence_and_agree(case):
    scenario = paper_scenario('I', **CASES[case])
    q_k, p = expansion(scenario)
    free = trajectory_step_clarabel(q_k, p, scenario)
    assert not inside(free.q), 'the fence must cut the unconstrained step, or the test is idle'
    reference = trajectory_step_cvxpy(q_k, p, scenario, blocks=[fence()])
    fast = trajectory_step_clarabel(q_k, p, scenario, blocks=[fence()])
    assert inside(reference.q) and inside(fast.q)
    assert fast.bound == pytest.approx(reference.bound, rel=1e-6)
    np.testing.assert_allclose(fast.q / 1000.0, reference.q / 1000.0, atol=1e-4)
    assert reference.bound < free.bound


def test_the_fence_s_rows_sit_after_the_built_in_blocks_and_its_certificate_refuses_a_breach():
    scenario = paper_scenario('I')
    frame = Frame.of(scenario)
    blocks = step_blocks(frame, extra=[fence()])
    assert [type(b).__name__ for b in blocks] == ['NodeRates', 'LegLimits', 'BoxFence']
    program = cone_program(blocks)
    m = scenario.num_slots
    assert program.first_rows[2] == blocks[0].num_rows + blocks[1].num_rows
    assert program.num_rows == program.first_rows[2] + 4 * m
    # b - A x on the fence's rows is the slack of each side, for any z.
    q_k, p = expansion(scenario)
    data = [block.at(Expansion(q_k, p)) for block in blocks]
    values = program.values.copy()
    b = np.concatenate([block.right_hand_side() for block in blocks])
    z = frame.km(q_k + np.random.default_rng(1).normal(scale=300.0, size=q_k.shape))
    x = np.zeros(program.num_columns)
    x[1:1 + 2 * m] = z.ravel()
    rows = slice(program.first_rows[2], program.num_rows)
    slack = (b - program.matrix(values) @ x)[rows].reshape(m, 4)
    np.testing.assert_allclose(slack[:, :2], blocks[2].upper - z, atol=1e-12)
    np.testing.assert_allclose(slack[:, 2:], z - blocks[2].lower, atol=1e-12)
    # The certificate: a point beyond the fence is refused, one within it bounded.
    duals = [np.ones(scenario.num_nodes), [np.zeros(m + 1)], [np.zeros((m, 2))] * 2]
    beyond = frame.km(q_k)
    beyond[5, 1] = blocks[2].upper[1] + 0.01
    assert certify(blocks, beyond, data, duals) is None
    assert certify(blocks, frame.km(q_k), data, duals) is not None


@pytest.mark.parametrize('case', sorted(CASES))
def test_plans_on_both_paths_keep_the_fence_and_agree(case):
    scenario = paper_scenario('I', **CASES[case])
    settings = SolverSettings.letter(compute_baselines=False)
    free = plan(scenario, settings)
    assert not inside(free.trajectory)
    fast = plan(scenario, settings, blocks=[fence()])
    reference = plan(scenario, settings, power_method='conic', trajectory_method='cvxpy',
                     blocks=[fence()])
    assert inside(fast.trajectory) and inside(reference.trajectory)
    assert fast.min_throughput == pytest.approx(reference.min_throughput, rel=1e-6)
    assert fast.min_throughput < free.min_throughput
    history = [step.min_throughput for step in fast.history]
    assert all(later >= earlier - 1e-9 for earlier, later in zip(history, history[1:]))


def test_the_default_search_keeps_only_starts_the_fence_admits():
    scenario = paper_scenario('I')
    result = plan(scenario, SolverSettings(compute_baselines=False), blocks=[fence()])
    assert inside(result.trajectory)
    assert result.start_throughputs, 'some start was admitted'


def test_a_fence_no_start_keeps_is_refused():
    scenario = paper_scenario('I')
    with pytest.raises(InvalidScenarioError, match='no start keeps the extra blocks'):
        plan(scenario, SolverSettings.letter(compute_baselines=False),
             blocks=[fence(lower_m=(500.0, 500.0), upper_m=(600.0, 600.0))])
