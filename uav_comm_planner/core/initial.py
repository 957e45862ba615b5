"""Trajectories that start Algorithm 1 or serve as its baselines: (M, 2) metres each."""

from __future__ import annotations

import heapq
import math
from typing import Callable

import numpy as np

from uav_comm_planner.core.scenario import Scenario


def straight_line(scenario: Scenario) -> np.ndarray:
    """q0 -> qF along a straight line at uniform speed: q[m] = q0 + m (qF - q0) / (M + 1)."""
    fraction = np.arange(1, scenario.num_slots + 1) / (scenario.num_slots + 1)
    start = np.asarray(scenario.start_m)
    return start + fraction[:, None] * (np.asarray(scenario.goal_m) - start)


def static_point(scenario: Scenario) -> np.ndarray:
    """A static access point above the nodes' centroid for the whole horizon.

    This baseline ignores the launch and landing points, as in the letter's comparison.
    """
    centroid = scenario.nodes.mean(axis=0)
    return np.repeat(centroid[None, :], scenario.num_slots, axis=0)


def nearest_neighbour_order(start: np.ndarray, w: np.ndarray) -> list[int]:
    """Visit order of the nodes w (N, 2): always the closest unvisited node next (the first
    of equal distances). One pass of N distances per node: O(N^2) in NumPy, O(N) memory."""
    w = np.asarray(w, dtype=float)
    visited = np.zeros(len(w), dtype=bool)
    order: list[int] = []
    here = np.asarray(start, dtype=float)
    for _ in range(len(w)):
        distance = np.where(visited, np.inf, np.linalg.norm(w - here, axis=1))
        nearest = int(np.argmin(distance))
        order.append(nearest)
        visited[nearest] = True
        here = w[nearest]
    return order


#: The most nodes :func:`two_opt` improves a tour of: its tables are (N + 2)^2 (0.7 MB each at
#: this bound, 0.8 GB at 10 000 nodes) and each move costs as much (0.7 s of processor time
#: from a random order of 300 nodes, over a minute at 1000); a longer tour is kept as given.
TWO_OPT_MAX_NODES = 300


def two_opt(start: np.ndarray, goal: np.ndarray, w: np.ndarray,
            order: list[int]) -> list[int]:
    """Improve the open path start -> w[order] -> goal by 2-opt moves (endpoints fixed); a
    path of more than :data:`TWO_OPT_MAX_NODES` nodes is returned as given.

    Reversing the stretch i..j replaces the edges (i-1, i) and (j, j+1) by (i-1, j) and
    (i, j+1); moves are made while one shortens the path by more than round-off.
    """
    order = list(order)
    n = len(order)
    if n < 2 or n > TWO_OPT_MAX_NODES:
        return order
    # Distances between the points start (0), w (1..N) and goal (N + 1), computed once.
    points = np.vstack([start, w, goal])
    distance = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=-1)
    # Every move at once: entry (i - 1, j - 1) is the stretch i..j, i < j (the others masked).
    # The move made is the loop's over i = 1..N: the first i whose best j (the first of equal
    # gains) shortens the path by more than round-off, that j.
    movable = np.triu(np.ones((n, n), dtype=bool), k=1)
    rows = np.arange(n)
    while True:
        path = np.array([0, *(k + 1 for k in order), len(w) + 1])
        d = distance[np.ix_(path, path)]
        edge = np.diagonal(d, offset=-1)                   # edge[k]: path[k] to path[k + 1]
        old = edge[:n, None] + edge[None, 1:]              # (i - 1, i) and (j, j + 1)
        new = d[1:n + 1, :n].T + d[2:, 1:n + 1].T          # (i - 1, j) and (i, j + 1)
        gain = np.where(movable, old - new, -np.inf)
        best = np.argmax(gain, axis=1)
        shortens = gain[rows, best] > 1e-9 * (1.0 + old[rows, best])
        if not shortens.any():
            return order
        row = int(np.argmax(shortens))
        last = int(best[row]) + 1
        order[row:last] = order[row:last][::-1]


def tour_order(scenario: Scenario) -> list[int]:
    """A short visit order of all nodes from q0 to qF: nearest neighbour, then 2-opt."""
    start, goal = np.asarray(scenario.start_m), np.asarray(scenario.goal_m)
    order = nearest_neighbour_order(start, scenario.nodes)
    return two_opt(start, goal, scenario.nodes, order)


def _legs_needed(points: np.ndarray, scenario: Scenario) -> np.ndarray:
    """The legs each straight stretch of ``points`` needs at the fastest ground speed along it
    (V, or less against the wind: :meth:`Scenario.fastest_ground_speed_mps`)."""
    steps = np.diff(points, axis=0)
    lengths = np.linalg.norm(steps, axis=1)
    if not scenario.airspeed_limited:       # V along every stretch
        return np.ceil(lengths / (scenario.max_speed_mps * scenario.slot_s)).astype(int)
    fastest = np.array([scenario.fastest_ground_speed_mps(step / length) if length > 0 else 1.0
                        for step, length in zip(steps, lengths)])
    return np.ceil(lengths / (fastest * scenario.slot_s)).astype(int)


def _drop_until_flyable(scenario: Scenario, order: list[int]) -> list[int]:
    """Leave out the node whose detour costs most (the first in the tour of equal ones), one by
    one, until the tour fits M + 1 legs. Each drop changes only its neighbours' detours and one
    stretch's legs, so those are updated in place (a heap of detours, links between the points
    left): O(N log N), where working the whole tour out again at each drop was O(N^2)."""
    order = list(order)
    points = np.vstack([scenario.start_m, scenario.nodes[order], scenario.goal_m])
    legs = [int(k) for k in _legs_needed(points, scenario)]     # legs[p]: p to its next
    total, room = sum(legs), scenario.num_slots + 1
    if total <= room:
        return order
    last = len(points) - 1
    before, after = list(range(-1, last)), list(range(1, last + 2))
    gone = [False] * len(points)
    xy = points.tolist()

    def distance(a: int, b: int) -> float:      # as np.linalg.norm works it out, in floats
        dx, dy = xy[b][0] - xy[a][0], xy[b][1] - xy[a][1]
        return math.sqrt(dx * dx + dy * dy)

    def detour(p: int) -> float:
        a, b = before[p], after[p]
        return distance(a, p) + distance(p, b) - distance(a, b)

    heap = [(-detour(p), p) for p in range(1, last)]
    heapq.heapify(heap)
    while total > room and heap:
        cost, p = heapq.heappop(heap)
        if gone[p] or cost != -detour(p):
            continue        # dropped already, or its detour changed since: a newer entry holds
        a, b = before[p], after[p]
        gone[p] = True
        after[a], before[b] = b, a
        total -= legs[a] + legs[p]
        legs[a] = int(_legs_needed(points[[a, b]], scenario)[0])
        total += legs[a]
        for neighbour in (a, b):
            if 0 < neighbour < last:
                heapq.heappush(heap, (-detour(neighbour), neighbour))
    return [node for p, node in enumerate(order, start=1) if not gone[p]]


def even_hovers(spare_legs: int, stops: int) -> np.ndarray:
    """Split ``spare_legs`` hover slots over ``stops`` nodes as evenly as integers allow."""
    hovers = np.full(stops, spare_legs // stops)
    hovers[:spare_legs % stops] += 1
    return hovers


def hover_and_fly(scenario: Scenario) -> np.ndarray:
    """Fly a short tour of the nodes at speed V and hover over each one: q (M, 2) metres.

    The nodes are visited in :func:`tour_order`. Stretch k of the tour (length L_k) is flown
    in ceil(L_k / (g_k delta)) equal legs, g_k the fastest ground speed along it (V in still
    air), so every leg keeps the speed limits; the M + 1 legs left
    over become hover slots (zero-length legs) split evenly over the visited nodes. An even
    split is the max-min choice before any rate is known: with equal bandwidth, each node's
    rate grows with the time the UAV spends close to it, and no node is favoured a priori;
    Algorithm 1 then moves time between nodes. If the whole tour does not fit in the horizon,
    the nodes whose detours cost most are left out until it does; with none left, the start
    is the straight line.
    """
    return fly_tour(scenario, tour_order(scenario))


def fly_tour(scenario: Scenario, order: list[int],
             split: Callable[[int, int], np.ndarray] = even_hovers) -> np.ndarray:
    """:func:`hover_and_fly` along the visit ``order`` given: q (M, 2) metres, with the spare
    legs split over the visited nodes by ``split(spare_legs, stops)`` (integers in order)."""
    return fly_legs(scenario, tour_legs(scenario, order), split)


def tour_legs(scenario: Scenario, order: list[int]) -> tuple[list[int], np.ndarray, np.ndarray]:
    """The part of the visit ``order`` that fits the horizon (:func:`hover_and_fly`), the points
    q0, its nodes, qF, and the legs each stretch between them needs."""
    order = _drop_until_flyable(scenario, order)
    points = np.vstack([scenario.start_m, scenario.nodes[order], scenario.goal_m])
    return order, points, _legs_needed(points, scenario)


def spare_legs(scenario: Scenario, tour: tuple[list[int], np.ndarray, np.ndarray]) -> int:
    """The legs of the M + 1 a :func:`tour_legs` answer leaves to hover."""
    return scenario.num_slots + 1 - int(tour[2].sum())


def fly_legs(scenario: Scenario, tour: tuple[list[int], np.ndarray, np.ndarray],
             split: Callable[[int, int], np.ndarray] = even_hovers,
             flier: 'TourFlier | None' = None) -> np.ndarray:
    """q (M, 2) metres along a :func:`tour_legs` answer, the spare legs split by ``split``;
    the straight line when the tour visits no node. ``flier``: the tour's :class:`TourFlier`,
    if one was made already."""
    if not tour[0]:
        return straight_line(scenario)
    return (flier or TourFlier(tour))(split(spare_legs(scenario, tour), len(tour[0])))


class TourFlier:
    """A :func:`tour_legs` answer flown with any hover split: what does not depend on the split
    (the points of its legs) worked out once, for the many splits a tour is flown with."""

    def __init__(self, tour: tuple[list[int], np.ndarray, np.ndarray]):
        _, points, legs = tour
        # Stretch k from points[k] to points[k + 1] gives legs[k] rows points[k] + (i / legs[k])
        # (points[k + 1] - points[k]), i = 1..legs[k], then its hovers at points[k + 1] (none
        # after the last): q0 left out, these are q[1], ..., q[M], qF.
        first = np.cumsum(legs) - legs               # each stretch's first leg point
        stretch = np.repeat(np.arange(len(legs)), legs)
        within = np.arange(int(legs.sum())) - first[stretch]
        fraction = (within + 1) / legs[stretch]
        here, there = points[stretch], points[stretch + 1]
        # The rows to pick from: every leg's points, then the stops points[1:].
        self.rows = np.vstack([here + fraction[:, None] * (there - here), points[1:]])
        stops = len(legs)
        # Row k of the pattern: stretch k's leg points, each once, then stop k + 1 as often
        # as it is hovered over.
        self.hover_at = np.cumsum(legs + 1) - 1
        self.picked = np.empty(int(legs.sum()) + stops, dtype=int)
        in_stretch = np.ones(len(self.picked), dtype=bool)
        in_stretch[self.hover_at] = False
        self.picked[in_stretch] = np.arange(int(legs.sum()))
        self.picked[self.hover_at] = len(stretch) + np.arange(stops)
        self.counts = np.ones(len(self.picked), dtype=int)
        self.counts[self.hover_at[-1]] = 0           # no hover after the last stretch

    def slot_rows(self, hovers: np.ndarray) -> np.ndarray:
        """For ``hovers`` (integers, one per visited node) hover slots: the row of
        :attr:`rows` (every leg point of the tour, then its stops) each slot of q flies to,
        (M,) integers."""
        counts = self.counts.copy()
        counts[self.hover_at[:-1]] = hovers
        return np.repeat(self.picked, counts)[:-1]

    def __call__(self, hovers: np.ndarray) -> np.ndarray:
        """q (M, 2) metres with ``hovers`` (integers, one per visited node) hover slots."""
        return self.rows[self.slot_rows(hovers)]
