"""The SCA step on Clarabel directly against the cvxpy reference step and Algorithm 1."""

import types

import clarabel
from helpers import random_scenario
import numpy as np
import pytest
from scipy import sparse

from uav_comm_planner import paper_scenario, plan, Scenario, SolverError, SolverSettings
from uav_comm_planner.core.initial import straight_line
from uav_comm_planner.core.model import leg_lengths, snr_per_watt
from uav_comm_planner.core.power import waterfilling_power
from uav_comm_planner.core.sca.block import Expansion, Frame
from uav_comm_planner.core.sca.fast import (clarabel_settings, ClarabelTrajectoryStep,
                                            LOOSE_TOLERANCE, SolverCache, SOLVERS,
                                            trajectory_step_clarabel)
from uav_comm_planner.core.sca.program import cone_program, step_blocks
from uav_comm_planner.core.sca.reference import certify
from uav_comm_planner.core.sca.reference import trajectory_step_cvxpy
from uav_comm_planner.core.sca.surrogate import (kilometre_rows, KM, path_length_km,
                                                 sca_lower_bound, surrogate_coefficients)


def random_radio_scenario(seed: int) -> Scenario:
    """2-7 nodes in a square of 0.5-3 km flown corner to corner in 20-60 slots of 2 s at
    60 m/s, with a random budget and either radio (the letter's, or 1 MHz at beta0 1e-6)."""
    rng = np.random.default_rng(seed)
    nodes, slots = int(rng.integers(2, 8)), int(rng.integers(20, 60))
    side = float(rng.uniform(500.0, 3000.0))
    return random_scenario(rng, nodes, slots, side_m=side, start_m=(0.0, side),
                           goal_m=(side, 0.0), horizon_s=2.0 * slots, max_speed_mps=60.0,
                           power_budget_w=float(rng.uniform(0.5, 10.0)),
                           bandwidth_hz=float(rng.choice([1.0, 1e6])),
                           reference_gain=float(rng.choice([1e-3, 1e-6])))


@pytest.fixture(autouse=True)
def no_cached_solvers():
    """Tests that replace Clarabel's solver must not be handed a cached real one (nor leave
    theirs behind)."""
    SOLVERS.clear()
    yield
    SOLVERS.clear()


CASES = {'I': paper_scenario('I'), 'II': paper_scenario('II'),
         'I-150-slots': paper_scenario('I', num_slots=150, horizon_s=150.0),
         **{f'random-{seed}': random_radio_scenario(seed) for seed in range(4)}}


def expansion_point(scenario: Scenario, wiggle: float = 0.0, seed: int = 0):
    """A feasible q^k (the straight line, optionally shrunk towards a random feasible wiggle)
    and the optimal power for it."""
    q = straight_line(scenario)
    if wiggle:
        rng = np.random.default_rng(seed)
        q = q + wiggle * scenario.max_step_m * rng.uniform(-0.2, 0.2, size=q.shape)
    p = waterfilling_power(snr_per_watt(q, scenario), scenario.power_budget_w).p
    return q, p


@pytest.mark.parametrize('name', sorted(CASES))
@pytest.mark.parametrize('wiggle', [0.0, 1.0])
def test_fast_step_equals_the_cvxpy_step(name, wiggle):
    scenario = CASES[name]
    q_k, p = expansion_point(scenario, wiggle)
    reference = trajectory_step_cvxpy(q_k, p, scenario)
    fast = trajectory_step_clarabel(q_k, p, scenario)
    assert fast.bound == pytest.approx(reference.bound, rel=1e-6)
    # The optimum is unique (each node's bound is strictly concave in q), but a 1e-8 gap in t
    # pins q only through the bound's small curvature, so positions agree to centimetres.
    np.testing.assert_allclose(fast.q / KM, reference.q / KM, atol=1e-4)


@pytest.mark.parametrize('name', sorted(CASES))
def test_fast_step_meets_every_speed_limit_and_certifies_its_bound(name):
    scenario = CASES[name]
    q_k, p = expansion_point(scenario, 1.0, seed=7)
    step = ClarabelTrajectoryStep(scenario)(q_k, p, scenario)
    legs = leg_lengths(step.q, scenario)
    assert legs.shape == (scenario.num_slots + 1,)
    assert legs.max() <= scenario.max_step_m * (1 + 1e-6)
    independent = sca_lower_bound(step.q, q_k, p, scenario).mean(axis=1).min()
    assert step.bound == pytest.approx(independent, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize('name', sorted(CASES))
@pytest.mark.parametrize('wiggle', [0.2, 1.0])
def test_a_step_that_keeps_the_path_length_equals_the_cvxpy_step_and_keeps_it(name, wiggle):
    """The path budget (a warm replan's): the path no longer than at q^k, the same optimum on
    both paths (the cvxpy step certified by its duality gap with the budget's multiplier). The
    expansion points are longer than the straight line, so that some path is strictly within
    the budget."""
    scenario = CASES[name]
    q_k, p = expansion_point(scenario, wiggle)
    budget = path_length_km(q_k, scenario)
    reference = trajectory_step_cvxpy(q_k, p, scenario, keep_path_length=True)
    fast = trajectory_step_clarabel(q_k, p, scenario, keep_path_length=True)
    assert fast.bound == pytest.approx(reference.bound, rel=1e-6)
    np.testing.assert_allclose(fast.q / KM, reference.q / KM, atol=1e-4)
    assert path_length_km(fast.q, scenario) <= budget * (1 + 1e-7)
    assert leg_lengths(fast.q, scenario).max() <= scenario.max_step_m * (1 + 1e-6)
    assert fast.bound <= trajectory_step_clarabel(q_k, p, scenario).bound * (1 + 1e-9)


@pytest.mark.parametrize('name', ['I', 'II', 'random-1'])
def test_the_path_budget_binds_where_the_free_step_lengthens_the_path(name):
    scenario = CASES[name]
    q_k, p = expansion_point(scenario, 0.2)
    budget = path_length_km(q_k, scenario)
    free = trajectory_step_clarabel(q_k, p, scenario)
    kept = ClarabelTrajectoryStep(scenario, keep_path_length=True)(q_k, p, scenario)
    assert path_length_km(free.q, scenario) > budget * (1 + 1e-4)
    assert path_length_km(kept.q, scenario) <= budget * (1 + 1e-7)
    assert kept.bound < free.bound


def test_the_certificate_with_the_path_budget_bounds_the_optimum():
    """The blocks' certificate with the budget is an upper bound on the step's optimum for any
    multipliers, at any feasible point (weak duality): drawn at random (points between q^k and
    the optimum, both feasible), it never falls below the certified cvxpy optimum; a path over
    the budget is refused."""
    scenario = CASES['random-1']
    q_k, p = expansion_point(scenario, 0.2)
    step = trajectory_step_cvxpy(q_k, p, scenario, keep_path_length=True)
    optimum = step.bound
    weight, constant = kilometre_rows(surrogate_coefficients(q_k, p, scenario))
    frame = Frame.of(scenario)
    blocks = step_blocks(frame, keep_path_length=True)
    assert [type(b).__name__ for b in blocks] == ['NodeRates', 'LegLimits', 'PathBudget']
    data = [block.at(Expansion(q_k, p)) for block in blocks]
    rng = np.random.default_rng(3)
    discs = len(blocks[1].discs)
    for _ in range(30):
        share = rng.uniform()
        z = frame.km((1.0 - share) * q_k + share * step.q)
        # The value of the step's objective at z, from the letter's bound directly.
        f = sca_lower_bound(frame.metres(z), q_k, p, scenario).mean(axis=1).min()
        duals = [rng.exponential(1.0, scenario.num_nodes),
                 [rng.exponential(0.05, scenario.num_slots + 1) for _ in range(discs)],
                 [rng.exponential(5.0)]]
        bound = certify(blocks, z, data, duals)
        assert bound is not None and np.isfinite(bound.gap)
        assert bound.value == pytest.approx(f, rel=1e-12, abs=1e-12)
        assert bound.total >= optimum - 1e-9
    halved = data[:2] + [(q_k, 0.5 * data[2][1])]
    assert certify(blocks, frame.km(q_k), halved,
                   [np.ones(scenario.num_nodes), [np.zeros(scenario.num_slots + 1)] * discs,
                    [1.0]]) is None
    assert weight.shape == (scenario.num_nodes, scenario.num_slots) and constant.shape == (
        scenario.num_nodes,)


def test_the_path_budget_holds_exactly_at_the_loose_tolerance():
    """A solver meets the budget to its tolerance; the step blends its answer back within it,
    so that over a run the length never creeps up (at the loose 1e-4 each binding step came
    out a few 1e-4 over)."""
    scenario = CASES['I']
    q, p = expansion_point(scenario, 0.2)
    stepper = ClarabelTrajectoryStep(scenario, keep_path_length=True)
    stepper.set_tolerance(LOOSE_TOLERANCE)
    lengths = [path_length_km(q, scenario)]
    for _ in range(6):
        q = stepper(q, p, scenario).q
        lengths.append(path_length_km(q, scenario))
    assert all(later <= earlier for earlier, later in zip(lengths, lengths[1:]))


def test_cone_rows_are_the_bound_minus_t_when_u_is_the_squared_norm():
    # b - A x on the node rows must equal mean_m lbr_{n,m}(q) - t for any q, not only optima.
    scenario = CASES['I-150-slots']
    q_k, p = expansion_point(scenario, 1.0, seed=3)
    stepper = ClarabelTrajectoryStep(scenario)
    rates = stepper.blocks[0]
    assert rates.num_sums > 0
    values, b = stepper.cone_data([block.at(Expansion(q_k, p)) for block in stepper.blocks])
    a = stepper.program.matrix(values)
    rng = np.random.default_rng(5)
    q = q_k + rng.normal(scale=200.0, size=q_k.shape)
    z = (q - stepper.centre_m) / KM
    t = 1.7
    x = np.concatenate([[t], z.ravel(), (z ** 2).sum(axis=1), np.zeros(rates.num_sums)])
    # Each partial sum e_{n,k} set to its block's value leaves its block row with no slack.
    block_rows = slice(rates.num_nodes, rates.num_nodes + rates.num_sums)
    x[1 + 3 * scenario.num_slots:] = -(b - a @ x)[block_rows]
    np.testing.assert_allclose((b - a @ x)[block_rows], 0.0, atol=1e-12)
    slack = (b - a @ x)[:scenario.num_nodes]
    expected = sca_lower_bound(q, q_k, p, scenario).mean(axis=1) - t
    np.testing.assert_allclose(slack, expected, rtol=1e-9, atol=1e-9)


def test_the_program_has_one_entry_per_coefficient_and_is_cached():
    blocks = step_blocks(Frame.of(CASES['I-150-slots']))
    layout = cone_program(blocks)
    assert layout is cone_program(step_blocks(Frame.of(paper_scenario(
        'II', num_slots=150, horizon_s=150.0, power_budget_w=2.0))))
    rates = blocks[0]
    assert (rates.block_slots, rates.num_blocks, rates.num_sums) == (64, 3, 9)
    assert layout.first_rows == (0, 3 + 9 + 4 * 150)
    assert layout.first_columns == (1 + 2 * 150, 1 + 3 * 150 + 9)
    a = layout.matrix(np.arange(1.0, len(layout.values) + 1.0))
    assert a.shape == (3 + 9 + 3 * 151 + 4 * 150, 1 + 3 * 150 + 9)
    # node rows: t and 3 sums each; block rows: 3 per slot and node plus -e; cones: 4 + 4.
    assert a.nnz == 3 * 4 + (3 * 3 * 150 + 9) + 4 * 150 + 4 * 150
    assert not layout.values.flags.writeable
    # Every slot's coefficients sit in the block row of its own block.
    dense = a.toarray()
    for n in range(3):
        for k in range(3):
            columns = np.flatnonzero(dense[3 + 3 * n + k, 1:451]) + 1
            slots = np.concatenate([(columns[columns <= 300] - 1) // 2,
                                    columns[columns > 300] - 301])
            assert set(slots) == set(range(64 * k, min(64 * k + 64, 150)))


@pytest.mark.parametrize('name', ['I', 'I-150-slots'])
def test_clarabel_reads_the_list_matrices_as_the_scipy_ones(name):
    scenario = CASES[name]
    q_k, p = expansion_point(scenario, 1.0, seed=2)
    stepper = ClarabelTrajectoryStep(scenario)
    values, b = stepper.cone_data([block.at(Expansion(q_k, p)) for block in stepper.blocks])
    layout = stepper.program
    p_lists, a_lists = layout.clarabel_matrices(values)
    a = layout.matrix(values)
    np.testing.assert_array_equal(a_lists.data, a.data)
    np.testing.assert_array_equal(a_lists.indices, a.indices)
    np.testing.assert_array_equal(a_lists.indptr, a.indptr)
    assert a_lists.shape == a.shape and a.has_canonical_format
    assert p_lists.shape == (layout.num_columns, layout.num_columns) and not p_lists.data
    settings = clarabel_settings(refine=False)
    from_lists = clarabel.DefaultSolver(p_lists, stepper.objective.tolist(), a_lists, b.tolist(),
                                        list(layout.cones), settings).solve()
    from_scipy = clarabel.DefaultSolver(sparse.csc_matrix((layout.num_columns,) * 2),
                                        stepper.objective, a, b, list(layout.cones),
                                        settings).solve()
    assert from_lists.status == from_scipy.status == clarabel.SolverStatus.Solved
    assert from_lists.x == from_scipy.x


def test_a_single_block_puts_the_coefficients_in_the_node_rows():
    blocks = step_blocks(Frame.of(CASES['I']))
    layout = cone_program(blocks)
    assert (blocks[0].num_blocks, blocks[0].num_sums) == (1, 0)
    a = layout.matrix(np.arange(1.0, len(layout.values) + 1.0)).toarray()
    assert a.shape == (3 + 3 * 51 + 4 * 50, 1 + 3 * 50)
    assert np.all(a[:3] != 0.0)


class _FailingSolver:
    """Stands in for clarabel.DefaultSolver and reports ``status`` for every solve."""

    built = 0

    def __init__(self, *args, status=clarabel.SolverStatus.NumericalError):
        type(self).built += 1
        self.status = status

    def solve(self):
        return types.SimpleNamespace(status=self.status, x=None)


def test_a_failing_solve_raises_a_typed_error(monkeypatch):
    scenario = CASES['I']
    q_k, p = expansion_point(scenario)
    _FailingSolver.built = 0
    monkeypatch.setattr(clarabel, 'DefaultSolver', _FailingSolver)
    with pytest.raises(SolverError, match='Clarabel returned status NumericalError'):
        ClarabelTrajectoryStep(scenario)(q_k, p, scenario)
    assert _FailingSolver.built == 3   # every form of ATTEMPTS was tried first


def test_a_step_that_fails_without_refinement_is_solved_again_with_it(monkeypatch):
    scenario = CASES['II']
    q_k, p = expansion_point(scenario)
    reference = trajectory_step_cvxpy(q_k, p, scenario)   # before cvxpy's Clarabel is replaced
    real = clarabel.DefaultSolver
    made = []

    def first_fails(*args):
        settings = args[-1]
        made.append(settings.iterative_refinement_enable)
        if not settings.iterative_refinement_enable:
            return _FailingSolver(status=clarabel.SolverStatus.AlmostSolved)
        return real(*args)

    monkeypatch.setattr(clarabel, 'DefaultSolver', first_fails)
    stepper = ClarabelTrajectoryStep(scenario)
    step = stepper(q_k, p, scenario)
    assert made == [False, True] and stepper.refine
    assert step.bound == pytest.approx(reference.bound, rel=1e-6)
    stepper(step.q, p, scenario)
    assert made == [False, True], 'the refined solver serves the rest of the plan'


def test_a_step_that_fails_with_partial_sums_is_solved_without_them(monkeypatch):
    scenario = CASES['I-150-slots']
    q_k, p = expansion_point(scenario)
    reference = trajectory_step_cvxpy(q_k, p, scenario)
    real = clarabel.DefaultSolver
    columns = []

    def blocks_fail(*args):
        a = args[2]
        columns.append(a.shape[1])
        if a.shape[1] > 1 + 3 * scenario.num_slots:
            return _FailingSolver(status=clarabel.SolverStatus.AlmostSolved)
        return real(*args)

    monkeypatch.setattr(clarabel, 'DefaultSolver', blocks_fail)
    stepper = ClarabelTrajectoryStep(scenario)
    step = stepper(q_k, p, scenario)
    assert columns[:2] == [1 + 3 * 150 + 9] * 2 and columns[2] == 1 + 3 * 150
    assert stepper.blocks[0].num_sums == 0
    assert step.bound == pytest.approx(reference.bound, rel=1e-6)


def test_a_stepper_refuses_another_scenario():
    stepper = ClarabelTrajectoryStep(CASES['I'])
    q_k, p = expansion_point(CASES['II'])
    with pytest.raises(ValueError, match='another scenario'):
        stepper(q_k, p, CASES['II'])


def test_updated_solver_gives_the_same_step_as_a_fresh_one():
    scenario = CASES['random-2']
    stepper = ClarabelTrajectoryStep(scenario)
    q_k, p = expansion_point(scenario)
    first = stepper(q_k, p, scenario)
    q_next, p_next = first.q, p * 0.5
    updated = stepper(q_next, p_next, scenario)
    fresh = trajectory_step_clarabel(q_next, p_next, scenario)
    assert updated.bound == pytest.approx(fresh.bound, rel=1e-7)
    np.testing.assert_allclose(updated.q, fresh.q, atol=0.1)


@pytest.mark.parametrize('name', ['I', 'II', 'I-150-slots', 'random-0', 'random-3'])
def test_both_paths_reach_the_same_plan(name):
    scenario = CASES[name]
    settings = SolverSettings.letter(compute_baselines=False)
    reference = plan(scenario, settings, power_method='conic', trajectory_method='cvxpy')
    fast = plan(scenario, settings)
    assert fast.min_throughput == pytest.approx(reference.min_throughput, rel=1e-6)


class _AlmostSolver:
    """Stands in for clarabel.DefaultSolver: AlmostSolved, at a given position vector."""

    def __init__(self, x):
        self.x = x

    def solve(self):
        return types.SimpleNamespace(status=clarabel.SolverStatus.AlmostSolved, x=self.x)

    def update(self, **data):
        pass


def test_an_almost_solved_step_is_kept_only_within_the_speed_limits(monkeypatch):
    scenario = CASES['I']
    q_k, p = expansion_point(scenario)
    stepper = ClarabelTrajectoryStep(scenario)
    centred_km = (q_k - stepper.centre_m) / KM
    feasible = np.concatenate([[0.0], centred_km.ravel(), np.zeros(scenario.num_slots)])
    monkeypatch.setattr(clarabel, 'DefaultSolver', lambda *args: _AlmostSolver(feasible))
    np.testing.assert_allclose(stepper(q_k, p, scenario).q, q_k, atol=1e-9)

    too_fast = feasible.copy()
    too_fast[1:3] += 1.0   # q[1] one kilometre away from q0: a 100 m leg limit broken
    monkeypatch.setattr(clarabel, 'DefaultSolver', lambda *args: _AlmostSolver(too_fast))
    with pytest.raises(SolverError, match='Clarabel returned status AlmostSolved'):
        ClarabelTrajectoryStep(scenario, cache=None)(q_k, p, scenario)


def test_moderate_snr_plans_succeed_on_the_fast_path_and_match_the_reference():
    # B = 1 MHz, beta0 = -60 dB, P_T = 0.5 W: Clarabel's gap stalls at AlmostSolved there.
    scenario = paper_scenario('I', bandwidth_hz=1e6, reference_gain=1e-6, power_budget_w=0.5)
    for starts in (('straight',), ('hover',)):
        # The same steps on both paths: full SCA loops, the tight tolerance, no screening.
        settings = SolverSettings(starts=starts, screened_tours=0, fast_steps=False)
        fast = plan(scenario, settings)
        reference = plan(scenario, settings, power_method='conic', trajectory_method='cvxpy')
        assert fast.min_throughput == pytest.approx(reference.min_throughput, rel=1e-6)


def test_a_cached_solver_gives_the_step_a_fresh_solver_gives():
    # Same (N, M), another scenario first: the cached solver's every entry is replaced.
    scenario = CASES['II']
    other = paper_scenario('I', power_budget_w=1.0, goal_m=(1500.0, 300.0))
    q_k, p = expansion_point(scenario)
    cache = SolverCache()
    ClarabelTrajectoryStep(other, cache)(*expansion_point(other), other)
    reused = ClarabelTrajectoryStep(scenario, cache)
    step = reused(q_k, p, scenario)
    fresh = ClarabelTrajectoryStep(scenario, cache=None)(q_k, p, scenario)
    np.testing.assert_allclose(step.q, fresh.q, rtol=0, atol=1e-9)
    assert step.bound == pytest.approx(fresh.bound, rel=1e-12)
    # Handed back after the solve, for the next plan of this form.
    assert cache.take(reused._form) is not None and cache.take(reused._form) is None


def test_plans_on_reused_solvers_are_the_plans_of_fresh_ones():
    scenario = random_scenario(21, 6, 60)
    first = plan(scenario, SolverSettings(compute_baselines=False))
    plan(random_scenario(22, 6, 60), SolverSettings(compute_baselines=False))   # same form
    again = plan(scenario, SolverSettings(compute_baselines=False))
    SOLVERS.clear()
    fresh = plan(scenario, SolverSettings(compute_baselines=False))
    for result in (again, fresh):
        assert result.min_throughput == pytest.approx(first.min_throughput, rel=1e-12)
        np.testing.assert_allclose(result.trajectory, first.trajectory, rtol=0, atol=1e-6)
        assert result.start == first.start


@pytest.mark.parametrize('case', ['I', 'random-1', 'random-2'])
def test_a_loose_step_is_close_to_the_tight_one_and_the_tight_tolerance_comes_back(case):
    scenario = CASES[case]
    q_k, p = expansion_point(scenario)
    stepper = ClarabelTrajectoryStep(scenario)
    tight = stepper(q_k, p, scenario).bound
    stepper.set_tolerance(LOOSE_TOLERANCE)
    loose = stepper(q_k, p, scenario).bound
    assert loose == pytest.approx(tight, rel=10 * LOOSE_TOLERANCE, abs=1e-9)
    stepper.set_tolerance(None)
    assert stepper(q_k, p, scenario).bound == pytest.approx(tight, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize('case', ['random-0', 'random-1', 'random-3'])
def test_the_loose_steps_do_not_change_the_plan_beyond_the_stopping_rule(case):
    # The default's loose steps end with a tight one: its plan is the plan of tight steps
    # alone to the stopping rule, and no plan ends below the letter's.
    scenario = CASES[case]
    fast = plan(scenario, SolverSettings(compute_baselines=False))
    tight = plan(scenario, SolverSettings(compute_baselines=False, fast_steps=False))
    letter = plan(scenario, SolverSettings.letter(compute_baselines=False))
    assert fast.min_throughput == pytest.approx(tight.min_throughput, rel=1e-3)
    assert min(fast.min_throughput, tight.min_throughput) >= letter.min_throughput
    assert SOLVERS.take(ClarabelTrajectoryStep(scenario)._form)[2] is None   # left tight
