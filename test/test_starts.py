"""The hover-and-fly start, the two-start default plan and the throughput upper bound."""

import math

from helpers import random_scenario
import numpy as np
import pytest

from uav_comm_planner import (InvalidScenarioError, paper_scenario, plan, Scenario, SolverSettings)
from uav_comm_planner.core.initial import (even_hovers, fly_legs, hover_and_fly,
                                           nearest_neighbour_order, spare_legs, straight_line,
                                           tour_legs, tour_order, TourFlier, two_opt)
from uav_comm_planner.core.model import average_rates, leg_lengths, snr_per_watt
from uav_comm_planner.core.optimizer import throughput_upper_bound
from uav_comm_planner.core.search import RESPLIT
from uav_comm_planner.core.power import conic_power
from uav_comm_planner.core.tours import random_tours


def distance_to_path(q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Distance from each node (N,) to the closest waypoint."""
    return np.linalg.norm(q[None, :, :] - w[:, None, :], axis=-1).min(axis=1)


def assert_flyable(q: np.ndarray, scenario: Scenario) -> None:
    assert q.shape == (scenario.num_slots, 2)
    assert np.all(np.isfinite(q))
    legs = leg_lengths(q, scenario)   # includes q0 -> q[1] and q[M] -> qF
    assert legs.max() <= scenario.max_step_m * (1 + 1e-9), legs.max() / scenario.max_step_m


@pytest.mark.parametrize('scenario', [
    paper_scenario('I'), paper_scenario('II'),
    *[random_scenario(s, nodes=3 + s, slots=120) for s in range(6)]])
def test_hover_and_fly_visits_every_node_within_the_speed_limit(scenario):
    q = hover_and_fly(scenario)
    assert_flyable(q, scenario)
    assert distance_to_path(q, scenario.nodes).max() < 1e-6
    # The spare legs all became hovers: every leg is either flown or held over a node.
    legs = leg_lengths(q, scenario)
    hovering = legs < 1e-9
    path = np.vstack([scenario.start_m, q, scenario.goal_m])
    held_at = path[1:][hovering]
    assert np.sum(hovering) >= scenario.num_nodes
    assert distance_to_path(held_at, scenario.nodes).max() < 1e-9   # each node gets a hover
    assert np.all(np.linalg.norm(held_at[:, None, :] - scenario.nodes[None], axis=-1)
                  .min(axis=1) < 1e-9)


def test_hovers_are_split_evenly_over_the_nodes():
    scenario = random_scenario(3, nodes=5, slots=120)
    q = hover_and_fly(scenario)
    path = np.vstack([scenario.start_m, q, scenario.goal_m])
    held = np.linalg.norm(np.diff(path, axis=0), axis=1) < 1e-9
    counts = [int(np.sum(held & (np.linalg.norm(path[1:] - w, axis=1) < 1e-9)))
              for w in scenario.nodes]
    assert max(counts) - min(counts) <= 1 and min(counts) >= 1
    np.testing.assert_array_equal(even_hovers(11, 4), [3, 3, 3, 2])


def test_a_horizon_too_short_for_the_tour_drops_nodes_but_stays_flyable():
    scenario = random_scenario(4, nodes=10, slots=36)
    full_tour = np.vstack([scenario.start_m, scenario.nodes[tour_order(scenario)],
                           scenario.goal_m])
    assert np.linalg.norm(np.diff(full_tour, axis=0), axis=1).sum() > (
        scenario.num_slots + 1) * scenario.max_step_m
    q = hover_and_fly(scenario)
    assert_flyable(q, scenario)
    visited = int(np.sum(distance_to_path(q, scenario.nodes) < 1e-6))
    assert 1 <= visited < scenario.num_nodes


def test_a_horizon_that_only_fits_the_straight_line_gives_the_straight_line():
    # Start to goal is 2828 m; 29 legs of 100 m leave no time for a detour to (2000, 0).
    scenario = Scenario(ground_nodes_m=[(2000.0, 0.0), (0.0, 2000.0)], goal_m=(2000.0, 2000.0),
                        num_slots=28, horizon_s=28.0, max_speed_mps=100.0)
    q = hover_and_fly(scenario)
    assert_flyable(q, scenario)
    np.testing.assert_allclose(q, straight_line(scenario))


def test_two_opt_never_lengthens_the_nearest_neighbour_order():
    rng = np.random.default_rng(11)
    for _ in range(10):
        w = rng.uniform(0.0, 1000.0, size=(12, 2))
        start, goal = np.zeros(2), np.array([1000.0, 0.0])
        greedy = nearest_neighbour_order(start, w)
        better = two_opt(start, goal, w, greedy)
        assert sorted(better) == list(range(12))

        def length(order):
            points = np.vstack([start, w[order], goal])
            return np.linalg.norm(np.diff(points, axis=0), axis=1).sum()

        assert length(better) <= length(greedy) + 1e-9


def test_two_opt_untangles_nodes_on_a_line():
    w = np.array([[300.0, 0.0], [100.0, 0.0], [400.0, 0.0], [200.0, 0.0]])
    assert two_opt(np.zeros(2), np.array([500.0, 0.0]), w, [0, 1, 2, 3]) == [1, 3, 0, 2]


@pytest.mark.parametrize('seed', range(3))
def test_default_plan_is_never_worse_than_the_letters_algorithm(seed):
    scenario = random_scenario(100 + seed, nodes=4 + 2 * seed, slots=60)
    letter = plan(scenario, SolverSettings.letter(compute_baselines=False))
    default = plan(scenario, SolverSettings(compute_baselines=False))
    assert letter.start == 'straight'
    assert default.start in default.start_throughputs
    assert {'straight', 'hover'} <= set(default.start_throughputs)
    tours = set(random_tours(scenario, SolverSettings().screened_tours))
    others = set(default.start_throughputs) - {'straight', 'hover'}
    # The screened tours, and the best RESPLIT of them again with their splits searched.
    assert {name.removesuffix(' resplit') for name in others} <= tours
    assert len(others - tours) <= RESPLIT
    assert default.min_throughput == max(default.start_throughputs.values())
    # The letter's own run is one of the default's: never below it, not even by round-off.
    assert default.start_throughputs['straight'] >= letter.min_throughput
    assert default.min_throughput >= letter.min_throughput


def test_each_start_alone_is_what_the_two_start_plan_chooses_from():
    scenario = random_scenario(7, nodes=5)
    unscreened = dict(screened_tours=0, fast_steps=False, compute_baselines=False)
    both = plan(scenario, SolverSettings(**unscreened))
    for name in ('straight', 'hover'):
        alone = plan(scenario, SolverSettings(starts=(name,), **unscreened))
        assert alone.start == name
        assert alone.min_throughput == pytest.approx(both.start_throughputs[name], rel=1e-9)


@pytest.mark.parametrize('scenario', [
    paper_scenario('I'), paper_scenario('II'), paper_scenario('I', power_budget_w=0.5),
    random_scenario(1), random_scenario(2, bandwidth_hz=1e6, reference_gain=1e-6),
    random_scenario(3, nodes=10, slots=40)])
def test_upper_bound_is_above_every_plan(scenario):
    result = plan(scenario)
    letter = plan(scenario, SolverSettings.letter())
    bound = result.upper_bound
    assert bound == throughput_upper_bound(scenario)
    values = [result.min_throughput, letter.min_throughput, *result.baselines.values(),
              *result.start_throughputs.values()]
    assert all(value < bound for value in values)
    assert 0.0 < result.gap_to_upper_bound < 1.0


def test_upper_bound_is_reached_by_one_node_served_from_right_above():
    # N = 1, hovering over the node the whole time with the budget spread evenly: both
    # inequalities of the bound (best channel, Jensen) hold with equality.
    node = (500.0, 300.0)
    scenario = Scenario(ground_nodes_m=[node], start_m=node, goal_m=node, num_slots=20,
                        horizon_s=20.0, bandwidth_hz=2.0, power_budget_w=3.0)
    q = np.repeat(np.array([node]), 20, axis=0)
    p = np.full((1, 20), 3.0 / 20)
    achieved = average_rates(q, p, scenario)[0]
    assert throughput_upper_bound(scenario) == pytest.approx(achieved, rel=1e-12)
    snr = 1 * 1e-3 / (100.0 ** 2 * 2.0 * 10 ** ((-169.0 - 30.0) / 10.0))
    assert throughput_upper_bound(scenario) == pytest.approx(
        2.0 * math.log2(1 + snr * 3.0 / 20), rel=1e-12)


def test_letter_settings_are_the_letters_algorithm():
    letter = SolverSettings.letter()
    assert (letter.tolerance_bps, letter.relative_tolerance, letter.starts) == (
        0.01, 0.0, ('straight',))
    assert SolverSettings.letter(max_outer_iterations=3).max_outer_iterations == 3
    assert SolverSettings().starts == ('straight', 'hover')


@pytest.mark.parametrize('starts', [(), ('spiral',), ('straight', 'zigzag')])
def test_unknown_starts_are_refused(starts):
    with pytest.raises(InvalidScenarioError, match='starts must name one or more of'):
        SolverSettings(starts=starts)


def test_starts_may_be_given_as_a_list_and_repeats_are_dropped():
    assert SolverSettings(starts=['hover', 'hover']).starts == ('hover',)


def test_an_extra_start_of_a_builtin_name_replaces_it():
    """Starts are objects, not names looked up twice: an extra start called 'straight' is the
    trajectory given, and the plan from it alone is Algorithm 1 from that trajectory."""
    scenario = random_scenario(5, nodes=4, slots=40)
    settings = SolverSettings(starts=('straight',), compute_baselines=False, screened_tours=0)
    hover = hover_and_fly(scenario)
    given = plan(scenario, settings, extra_starts={'straight': hover})
    from_hover = plan(scenario, SolverSettings(starts=('hover',), compute_baselines=False,
                                               screened_tours=0))
    assert set(given.start_throughputs) == {'straight'}
    assert given.min_throughput == from_hover.min_throughput
    np.testing.assert_array_equal(given.trajectory, from_hover.trajectory)
    # The array handed in is neither kept writable nor changed.
    before = hover.copy()
    plan(scenario, settings, extra_starts={'mine': hover})
    np.testing.assert_array_equal(hover, before)


@pytest.mark.parametrize('seed', range(6))
def test_the_default_is_never_below_the_letter_on_seeded_drops(seed):
    # Drops like the benchmark's (N 3-20, slots of 0.5-2 s, V 20-100 m/s), both radios: the
    # letter's own run is the default's straight start, so not even round-off puts it below.
    from devtools.bench import quality_drop

    scenario = quality_drop(2000 + seed, low_snr=seed % 3 == 2, max_slots=90)
    letter = plan(scenario, SolverSettings.letter(compute_baselines=False))
    default = plan(scenario, SolverSettings(compute_baselines=False))
    assert default.start_throughputs['straight'] >= letter.min_throughput
    assert default.min_throughput >= letter.min_throughput
    assert default.power.sum() <= scenario.power_budget_w


def test_screened_tours_are_flyable_and_the_same_for_the_same_scenario():
    scenario = random_scenario(8, nodes=7, slots=50)
    tours = random_tours(scenario, 20)
    again = random_tours(random_scenario(8, nodes=7, slots=50), 20)
    assert list(tours) == list(again) and 5 <= len(tours) <= 20
    for name, q in tours.items():
        np.testing.assert_array_equal(q, again[name])
        assert q.shape == (scenario.num_slots, 2)
        assert leg_lengths(q, scenario).max() <= scenario.max_step_m * (1 + 1e-9)
    assert len({q.tobytes() for q in tours.values()}) == len(tours)     # no tour twice
    other = random_tours(random_scenario(9, nodes=7, slots=50), 20)
    assert any(not np.array_equal(tours[k], other.get(k)) for k in tours if k in other)
    first = plan(scenario, SolverSettings(compute_baselines=False))
    second = plan(scenario, SolverSettings(compute_baselines=False))
    assert first.start == second.start
    np.testing.assert_array_equal(first.trajectory, second.trajectory)


def _visits(q: np.ndarray, nodes: np.ndarray) -> tuple[list[int], list[int]]:
    """The nodes a tour start stops at, in order, and the hover slots at each (the slots of q
    at a node after the one it arrives in)."""
    at = [np.flatnonzero(np.all(np.isclose(q, w, rtol=0.0, atol=1e-9), axis=1)) for w in nodes]
    order = sorted((slots[0], n) for n, slots in enumerate(at) if slots.size)
    return [n for _, n in order], [at[n].size - 1 for _, n in order]


def test_screened_tours_hover_in_random_shares_and_mostly_keep_the_order_drawn():
    # Slots to spare, so every tour visits every node: the tours, read back from their slots.
    scenario = random_scenario(12, nodes=7, slots=140)
    start, goal = np.asarray(scenario.start_m), np.asarray(scenario.goal_m)
    tours = random_tours(scenario, 24)
    assert len(tours) == 24
    visits = {name: _visits(q, scenario.nodes) for name, q in tours.items()}
    spare = {sum(hovers) for _, hovers in visits.values()}
    assert all(sorted(order) == list(range(7)) for order, _ in visits.values())
    # The spare slots go to the nodes in shares that differ from tour to tour, seldom evenly.
    uneven = [name for name, (_, hovers) in visits.items() if max(hovers) - min(hovers) > 1]
    assert len(uneven) >= 20 and len({tuple(h) for _, h in visits.values()}) >= 20
    assert len(spare) > 1     # orders of other lengths leave other numbers of slots to spare
    # Every fourth order is a 2-opt local optimum of the tour length; the others as drawn.
    shortest = {name: two_opt(start, goal, scenario.nodes, order) == order
                for name, (order, _) in visits.items()}
    assert all(shortest[f'tour {k}'] for k in range(4, 25, 4))
    assert sum(not shortest[f'tour {k}'] for k in range(1, 25) if k % 4) >= 12


@pytest.mark.parametrize('shortlist', [1, 2, 4])
def test_the_shortlist_is_the_starts_best_by_one_power_step(shortlist):
    """Screened, every start but the letter's gets one power step; only the best
    ``shortlist`` of them by it get an SCA step, and the plan continues one of those."""
    scenario = random_scenario(8, nodes=6, slots=60)
    tours = random_tours(scenario, 4)
    settings = SolverSettings(starts=('hover',), screened_tours=0, compute_baselines=False,
                              shortlist=shortlist)
    result = plan(scenario, settings, extra_starts=tours)
    starts = {'hover': hover_and_fly(scenario), **tours}
    # The power step alone on each start, by an independent (conic) solver.
    powered = {}
    for name, q in starts.items():
        p = conic_power(snr_per_watt(q, scenario), scenario.power_budget_w).p
        powered[name] = float(average_rates(q, p, scenario).min())
    ranked = sorted(powered, key=powered.get, reverse=True)
    assert set(result.start_throughputs) == set(starts)
    moved = {name for name in starts
             if result.start_throughputs[name] > powered[name] * (1 + 1e-6)}
    assert moved == set(ranked[:shortlist])
    assert result.start in moved
    for name in set(starts) - moved:
        assert result.start_throughputs[name] == pytest.approx(powered[name], rel=1e-6)


def plain_flight(tour, hovers: np.ndarray) -> np.ndarray:
    """A tour flown slot by slot: each stretch's legs, then its hovers at the stretch's end."""
    _, points, legs = tour
    rows = []
    for k in range(len(legs)):
        here, there = points[k], points[k + 1]
        rows += [here + ((i + 1) / legs[k]) * (there - here) for i in range(legs[k])]
        rows += [there] * (int(hovers[k]) if k < len(hovers) else 0)
    return np.array(rows)[:-1]


@pytest.mark.parametrize('seed', range(6))
def test_a_tour_flown_with_any_split_is_its_legs_then_its_hovers(seed):
    # A node at q0: a stretch of no leg at all when the tour starts with it.
    scenario = random_scenario(seed, nodes=3 + 3 * seed, slots=40 + 60 * seed)
    scenario = scenario.replace(ground_nodes_m=[*scenario.ground_nodes_m, scenario.start_m])
    rng = np.random.default_rng(seed)
    at_start = scenario.num_nodes - 1
    orders = [[at_start, *range(at_start)]] + [[int(i) for i in rng.permutation(at_start + 1)]
                                                for _ in range(4)]
    for order in orders:
        tour = tour_legs(scenario, order)
        flier = TourFlier(tour)
        for _ in range(5):
            hovers = rng.multinomial(spare_legs(scenario, tour),
                                     np.ones(len(tour[0])) / len(tour[0]))
            q = flier(hovers)
            np.testing.assert_array_equal(q, plain_flight(tour, hovers))
            np.testing.assert_array_equal(q, fly_legs(scenario, tour, lambda *_: hovers))
            assert q.shape == (scenario.num_slots, 2)
    assert tour_legs(scenario, orders[0])[2][0] == 0     # its first stretch has no leg


def test_the_nearest_neighbour_order_is_the_closest_unvisited_node_each_time():
    """Against the rule written out in Python, with ties (repeated nodes: the first of equal
    distances)."""
    rng = np.random.default_rng(11)
    w = rng.uniform(-1000.0, 1000.0, size=(60, 2))
    w[30:40] = w[0:10]
    start = np.array([0.0, 0.0])
    expected, here, left = [], start, list(range(len(w)))
    while left:
        nearest = min(left, key=lambda i: float(np.linalg.norm(w[i] - here)))
        expected.append(nearest)
        left.remove(nearest)
        here = w[nearest]
    assert nearest_neighbour_order(start, w) == expected


def test_two_opt_of_a_tour_past_its_bound_is_the_tour_given_without_its_tables():
    """Its (N + 2)^2 tables took 1.5 GB at 10 000 nodes (a MemoryError under a 3 GB cap)."""
    import tracemalloc

    from uav_comm_planner.core.initial import TWO_OPT_MAX_NODES

    rng = np.random.default_rng(3)
    w = rng.uniform(-1000.0, 1000.0, size=(3 * TWO_OPT_MAX_NODES, 2))
    order = list(range(len(w)))
    tracemalloc.start()
    try:
        kept = two_opt(np.zeros(2), np.ones(2), w, order)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert kept == order
    assert peak < 10e6, peak
    # At the bound it still improves.
    small = w[:TWO_OPT_MAX_NODES // 10]
    improved = two_opt(np.zeros(2), np.ones(2), small, list(range(len(small))))
    assert improved != list(range(len(small)))


def drop_one_by_one(scenario, order):
    """The tour's nodes left out as the rule says, the whole tour worked out at every drop: the
    node whose detour costs most (the first of equal ones) until it fits M + 1 legs."""
    from uav_comm_planner.core.initial import _legs_needed

    start, goal = np.asarray(scenario.start_m), np.asarray(scenario.goal_m)
    order = list(order)
    while order:
        points = np.vstack([start, scenario.nodes[order], goal])
        if _legs_needed(points, scenario).sum() <= scenario.num_slots + 1:
            break
        detour = (np.linalg.norm(points[1:-1] - points[:-2], axis=1)
                  + np.linalg.norm(points[2:] - points[1:-1], axis=1)
                  - np.linalg.norm(points[2:] - points[:-2], axis=1))
        del order[int(np.argmax(detour))]
    return order


@pytest.mark.parametrize('seed', range(8))
def test_the_nodes_left_out_of_a_tour_are_those_of_the_one_by_one_rule(seed):
    rng = np.random.default_rng(seed)
    nodes = rng.uniform(-500.0, 2500.0, size=(int(rng.integers(2, 120)), 2))
    scenario = paper_scenario('I', ground_nodes_m=[tuple(p) for p in nodes],
                              num_slots=int(rng.integers(5, 60)), horizon_s=200.0,
                              max_speed_mps=20.0,
                              wind_speed_mps=float(rng.choice([0.0, 6.0])), wind_from_deg=70.0)
    order = [int(i) for i in rng.permutation(scenario.num_nodes)]
    kept = tour_legs(scenario, order)[0]
    assert kept == drop_one_by_one(scenario, order)
    if len(order) > scenario.num_slots + 1:     # more nodes than legs: some are left out
        assert len(kept) < len(order)
