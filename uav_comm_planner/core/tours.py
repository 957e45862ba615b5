"""Screened tours: random visiting orders and hover splits that start Algorithm 1, drawn from
a generator seeded by the scenario itself, so that one scenario always gets the same tours
(and the same plan).

The hover start (:func:`~uav_comm_planner.core.initial.hover_and_fly`) flies one short tour
with an even split of the spare slots; the max-min optimum often visits the nodes in another
order (a longer tour can serve the far nodes better, and a tour too long for the horizon
leaves out other nodes) or hovers longer over some nodes. :func:`random_tours` gives other
tours: each visits the nodes in a random order, as drawn or, every fourth, improved by 2-opt
(a local optimum of the tour length), and splits the spare slots in random shares.

Why this mix: the plan's worth is decided by which nodes the UAV passes close to and how long
it stays there, which Algorithm 1 changes only slowly (most at low SNR, where a node's rate
comes almost only from the slots close to it). Short tours with even hovers are what the hover
start already tries. Run to convergence from the hover start and 100 tours (50 of 2-opt orders
with an even split, 25 of drawn orders and 25 of 2-opt orders with random shares) on 140
seeded drops of the benchmark (100 at low SNR), the best plan came from a drawn order with
random shares in 86 drops, from a 2-opt order with random shares in 40, from a 2-opt order
with an even split in 8 and from the hover start in 6.
"""

from __future__ import annotations

import zlib

import numpy as np

from uav_comm_planner.core import initial
from uav_comm_planner.core.scenario import Scenario


def scenario_seed(scenario: Scenario) -> int:
    """A 32-bit seed from the scenario's geometry (nodes, start, goal, slots, step length)."""
    numbers = np.concatenate([scenario.nodes.ravel(), np.asarray(scenario.start_m, float),
                              np.asarray(scenario.goal_m, float),
                              [scenario.num_slots, scenario.max_step_m]])
    return zlib.crc32(np.ascontiguousarray(numbers, dtype=np.float64).tobytes())


def random_split(rng: np.random.Generator):
    """A hover split of ``spare`` legs over ``stops`` nodes in random shares (Dirichlet with
    unit weights, rounded so that the integers add up to ``spare``)."""
    def split(spare: int, stops: int) -> np.ndarray:
        shares = rng.dirichlet(np.ones(stops)) * spare
        hovers = np.floor(shares).astype(int)
        left = spare - int(hovers.sum())
        hovers[np.argsort(hovers - shares)[:left]] += 1
        return hovers
    return split


def tour_draws(scenario: Scenario, count: int,
               seed: int | None = None) -> dict[str, tuple[tuple, np.ndarray]]:
    """The tours of :func:`random_tours` before they are flown: by name, the tour's legs
    (:func:`~uav_comm_planner.core.initial.tour_legs`) and its hover split (integers, one per
    visited node), as drawn."""
    rng = np.random.default_rng(scenario_seed(scenario) if seed is None else seed)
    start, goal = np.asarray(scenario.start_m, float), np.asarray(scenario.goal_m, float)
    draws: dict[str, tuple[tuple, np.ndarray]] = {}
    legs: dict[tuple[int, ...], tuple] = {}     # the legs of each order, worked out once
    improved: dict[tuple[int, ...], list[int]] = {}     # 2-opt of each order drawn, once
    for k in range(1, count + 1):
        order = [int(i) for i in rng.permutation(scenario.num_nodes)]
        if k % 4 == 0:
            drawn = tuple(order)
            if drawn not in improved:
                improved[drawn] = initial.two_opt(start, goal, scenario.nodes, order)
            order = improved[drawn]
        key = tuple(order)
        if key not in legs:
            legs[key] = initial.tour_legs(scenario, order)
        tour = legs[key]
        # A tour that visits no node is the straight line, and draws no split.
        hovers = (random_split(rng)(initial.spare_legs(scenario, tour), len(tour[0]))
                  if tour[0] else np.zeros(0, int))
        draws[f'tour {k}'] = (tour, np.asarray(hovers))
    return draws


def fly_draw(scenario: Scenario, draw: tuple[tuple, np.ndarray],
             fliers: dict[int, initial.TourFlier] | None = None) -> np.ndarray:
    """q (M, 2) metres of a :func:`tour_draws` tour with its hover split; ``fliers`` keeps
    each tour's :class:`~uav_comm_planner.core.initial.TourFlier` by the tour's identity
    (draws of one order share their tour) for the draws after."""
    tour, hovers = draw
    flier = None
    if fliers is not None and tour[0]:
        if id(tour) not in fliers:
            fliers[id(tour)] = initial.TourFlier(tour)
        flier = fliers[id(tour)]
    return initial.fly_legs(scenario, tour, lambda spare, stops: hovers, flier)


def random_tours(scenario: Scenario, count: int,
                 seed: int | None = None) -> dict[str, np.ndarray]:
    """Up to ``count`` tour starts q (M, 2) metres by name ('tour 1', ...; a tour that repeats
    an earlier one is left out), reproducible for the scenario: each a random visiting order
    (tours 4, 8, ... improved by 2-opt, the others as drawn) with the spare slots split in
    random shares (:func:`random_split`). ``seed`` draws other tours (:func:`scenario_seed`
    when None)."""
    return distinct_tours(scenario, tour_draws(scenario, count, seed))


def distinct_tours(scenario: Scenario,
                   draws: dict[str, tuple[tuple, np.ndarray]]) -> dict[str, np.ndarray]:
    """The :func:`tour_draws` flown, by name, a tour that repeats an earlier one left out."""
    tours: dict[str, np.ndarray] = {}
    drawn: set[bytes] = set()                   # the tours so far, as bytes: a repeat is one
    fliers: dict[int, initial.TourFlier] = {}
    for name, draw in draws.items():
        q = fly_draw(scenario, draw, fliers)
        if q.tobytes() not in drawn:
            drawn.add(q.tobytes())
            tours[name] = q
    return tours


__all__ = ['distinct_tours', 'fly_draw', 'random_split', 'random_tours', 'scenario_seed',
           'tour_draws']
