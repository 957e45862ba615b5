"""The dual upper bound over the flyable paths: above every plan, above the dual value of any
flyable trajectory computed independently, exact where the optimum is known."""

import subprocess
import sys

from helpers import random_scenario
import numpy as np
import pytest

from devtools.bench import LOW_SNR, quality_drop
from uav_comm_planner import plan, Scenario, SolverSettings
from uav_comm_planner.core import bound
from uav_comm_planner.core.feasibility import project_onto_speed_limit, within_speed_limit
from uav_comm_planner.core.initial import hover_and_fly
from uav_comm_planner.core.model import average_rates, snr_per_watt
from uav_comm_planner.core.optimizer import alternate
from uav_comm_planner.core.steps import step_solvers
from uav_comm_planner.core.power import power_dual_bound
from uav_comm_planner.core.tours import random_tours


def random_flight(scenario: Scenario, rng: np.random.Generator) -> np.ndarray:
    """A random flyable trajectory: random hops (most of them to within reach of a node),
    projected onto the speed limits."""
    m = scenario.num_slots
    targets = scenario.nodes[rng.integers(0, scenario.num_nodes, size=m)]
    q = targets + rng.normal(scale=40.0, size=(m, 2))
    q = project_onto_speed_limit(q, scenario)
    assert within_speed_limit(q, scenario)
    return q


DROPS = [random_scenario(1, nodes=5, slots=50), random_scenario(2, nodes=8, slots=70),
         random_scenario(3, nodes=4, slots=40, **LOW_SNR),
         quality_drop(11, low_snr=False, max_slots=80),
         quality_drop(12, low_snr=True, max_slots=80)]


@pytest.mark.parametrize('scenario', DROPS)
def test_the_trajectory_bound_is_above_the_dual_value_of_any_flyable_path(scenario):
    # nu P_T + sum_m G(q[m]) of a trajectory is power_dual_bound on its SNR (the power step's
    # own dual, computed independently of the grid); the grid's maximum must be above it for
    # every flyable q and any multipliers.
    rng = np.random.default_rng(5)
    geometry = bound._geometry(scenario)
    flights = [random_flight(scenario, rng) for _ in range(20)] + [hover_and_fly(scenario)]
    for _ in range(4):
        weights = rng.dirichlet(np.ones(scenario.num_nodes))
        a = snr_per_watt(flights[-1], scenario)
        _, nu = bound.power_multipliers(np.full(a.shape, scenario.power_budget_w / a.size), a)
        nu *= float(rng.uniform(0.3, 3.0))
        on_grid = nu * scenario.power_budget_w + bound.trajectory_bound(
            geometry, weights, nu, scenario.num_slots)
        for q in flights:
            value = power_dual_bound(snr_per_watt(q, scenario), scenario.power_budget_w,
                                     weights, nu)
            assert value <= on_grid * (1 + 1e-12)


@pytest.mark.parametrize('scenario', DROPS)
def test_the_dual_bound_is_above_every_plan_and_the_best_known(scenario):
    default = plan(scenario, SolverSettings(compute_baselines=False))
    letter = plan(scenario, SolverSettings.letter(compute_baselines=False))
    settings = SolverSettings(compute_baselines=False, screened_tours=0, fast_steps=False)
    power_solver, trajectory_solver = step_solvers(scenario, 'waterfilling', 'clarabel')
    tours = [alternate(scenario, q, settings, power_solver=power_solver,
                       trajectory_solver=trajectory_solver).min_throughput
             for q in random_tours(scenario, 5, seed=77).values()]
    best = max(default.min_throughput, letter.min_throughput, *tours)
    # A bound from any plan's multipliers holds for every plan, the letter's too.
    for source in (default, letter):
        dual = bound.dual_upper_bound(scenario, source.power,
                                      snr_per_watt(source.trajectory, scenario))
        assert best <= dual
    assert default.tight_upper_bound <= default.upper_bound
    assert best <= default.tight_upper_bound
    assert 0.0 <= default.gap_to_tight_bound < default.gap_to_upper_bound


def test_the_dual_bound_is_reached_by_one_node_served_from_right_above():
    # N = 1 and q0 = qF above the node: hovering there with the budget spread evenly is optimal,
    # the node's cell has its exact SNR, and the search over nu finds the optimal price.
    node = (500.0, 300.0)
    scenario = Scenario(ground_nodes_m=[node], start_m=node, goal_m=node, num_slots=20,
                        horizon_s=20.0, bandwidth_hz=2.0, power_budget_w=3.0)
    q = np.repeat(np.array([node]), 20, axis=0)
    p = np.full((1, 20), 3.0 / 20)
    achieved = average_rates(q, p, scenario)[0]
    assert bound.dual_upper_bound(scenario, p, snr_per_watt(q, scenario)) == pytest.approx(
        achieved, rel=1e-9)


def test_the_bound_on_the_letters_cases_is_within_two_percent_of_the_default_plan():
    from uav_comm_planner import paper_scenario

    for case in ('I', 'II'):
        result = plan(paper_scenario(case), SolverSettings(compute_baselines=False))
        assert 0.0 < result.gap_to_tight_bound < 0.02
        assert result.gap_to_upper_bound > 0.1


def test_a_replan_with_offsets_has_no_dual_bound():
    scenario = random_scenario(4, nodes=3, slots=30)
    result = plan(scenario, SolverSettings(compute_baselines=False),
                  offsets=np.array([0.5, 0.0, 0.2]))
    assert result.tight_upper_bound == np.inf


def test_a_leg_longer_than_the_grid_reaches_every_cell_and_its_footprint_stays_small():
    """Slots of hours make a leg billions of cells long: the footprint is capped at the grid
    (nx + ny + 2 cells), which reaches every cell from every cell, as the leg itself does."""
    rng = np.random.default_rng(4)
    values = rng.normal(size=(7, 5))
    capped = bound._footprint_rows(7 + 5 + 2.0)
    assert np.array_equal(bound._dilate(values, bound._footprint_rows(40.0)),
                          bound._dilate(values, capped))
    assert np.all(bound._dilate(values, capped) == values.max())     # every cell, one leg
    assert len(capped) < 40


def test_slots_of_a_billion_seconds_get_their_dual_bound_in_little_memory():
    """`plan --slots 6 --horizon 6061375163` (a Hypothesis draw) built a footprint of 2e9 rows
    for the dual bound and took 24 GB; under a 4 GB limit it now answers in a second."""
    script = ('import resource; resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30)); '
              'from uav_comm_planner import paper_scenario, plan, SolverSettings; '
              "r = plan(paper_scenario('I', num_slots=6, horizon_s=6061375163.0), "
              'SolverSettings(compute_baselines=False)); '
              'print(r.min_throughput, r.tight_upper_bound)')
    done = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    value, upper = map(float, done.stdout.split())
    assert 0.0 < value <= upper < float('inf')
