"""A plan's path as waypoints (``vehicle/waypoints.py``): its hover runs, Douglas-Peucker and
the short steps dropped, each held to the letter of its definition, written out here the
plain way (a point at a time, every distance from
:func:`~uav_comm_planner.vehicle.evaluation.distance_to_polyline`), on paths like the plans'
(legs of a few metres, hovers, turns, and exact ties)."""

from __future__ import annotations

import numpy as np
import pytest

from uav_comm_planner.vehicle.evaluation import distance_to_polyline
from uav_comm_planner.vehicle.waypoints import drop_short_steps, hover_runs, simplify


def plain_hover_runs(points: np.ndarray, radius: float) -> list[tuple[int, int]]:
    runs, first = [], 0
    for index in range(1, len(points) + 1):
        if index < len(points) and np.linalg.norm(points[first:index] - points[index],
                                                  axis=1).max() <= radius:
            continue
        runs.append((first, index - 1))
        first = index
    return runs


def plain_simplify(points: np.ndarray, tolerance: float) -> list[int]:
    def split(first: int, last: int) -> set[int]:
        if last - first < 2:
            return set()
        gaps = distance_to_polyline(points[first + 1:last], points[[first, last]])
        worst = int(np.argmax(gaps))
        if gaps[worst] <= tolerance:
            return set()
        middle = first + 1 + worst
        return {middle} | split(first, middle) | split(middle, last)
    return sorted({0, len(points) - 1} | split(0, len(points) - 1))


def plain_drop_short_steps(points: np.ndarray, kept: list[int], min_step: float) -> list[int]:
    kept = list(kept)
    while len(kept) > 2:
        steps = np.linalg.norm(np.diff(points[kept], axis=0), axis=1)
        if steps.min() >= min_step:
            break
        short = int(np.argmin(steps))
        candidates = [i for i in (short, short + 1) if 0 < i < len(kept) - 1]
        cost = [distance_to_polyline(points[kept[i - 1]:kept[i + 1] + 1],
                                     points[[kept[i - 1], kept[i + 1]]]).max()
                for i in candidates]
        del kept[candidates[int(np.argmin(cost))]]
    return kept


def plan_like_path(seed: int) -> np.ndarray:
    """Legs of 0-20 m with random turns, hovers of a few slots (points within 1 m), a straight
    stretch with exactly equal steps and a point repeated exactly."""
    rng = np.random.default_rng(seed)
    points, position, heading = [], np.zeros(2), 0.0
    for _ in range(int(rng.integers(40, 400))):
        kind = rng.uniform()
        if kind < 0.15:
            for _ in range(int(rng.integers(2, 8))):
                points.append(position + rng.normal(0.0, 0.3, 2))
        elif kind < 0.2:
            points += [position.copy(), position.copy()]
        else:
            heading += rng.normal(0.0, 0.4 if kind < 0.9 else 2.0)
            step = 20.0 if kind > 0.95 else rng.uniform(0.0, 20.0)
            position = position + step * np.array([np.cos(heading), np.sin(heading)])
            points.append(position.copy())
    return np.array(points)


@pytest.mark.parametrize('seed', range(12))
def test_the_waypoints_are_those_of_the_plain_definitions(seed):
    points = plan_like_path(seed)
    for radius in (0.5, 2.0):
        assert hover_runs(points, radius) == plain_hover_runs(points, radius)
    for tolerance in (0.01, 1.0, 5.0):
        kept = simplify(points, tolerance)
        assert kept == plain_simplify(points, tolerance)
        assert distance_to_polyline(points, points[kept]).max() <= tolerance
        for min_step in (10.0, 70.0):
            dropped = drop_short_steps(points, kept, min_step)
            assert dropped == plain_drop_short_steps(points, kept, min_step)
            assert set(dropped) <= set(kept) and dropped[0] == 0 and dropped[-1] == kept[-1]


def test_a_straight_run_of_equal_steps_keeps_its_ends_and_ties_go_to_the_first():
    points = np.column_stack([np.arange(11) * 10.0, np.zeros(11)])
    assert simplify(points, 1e-9) == [0, 10]
    points[4, 1] = points[7, 1] = 3.0          # two farthest points, equally far
    assert simplify(points, 2.0) == plain_simplify(points, 2.0)
    assert 4 in simplify(points, 2.0)
    # Every step equally short: the first is dropped first, down to the two ends.
    assert drop_short_steps(points, list(range(11)), 1000.0) == [0, 10]


def test_a_point_exactly_the_radius_away_is_in_the_run():
    points = np.array([[0.0, 0.0], [2.0, 0.0], [4.0, 0.0], [4.0, 2.0]])
    assert hover_runs(points, 2.0) == plain_hover_runs(points, 2.0) == [(0, 1), (2, 3)]
    assert hover_runs(points, 4.0) == [(0, 2), (3, 3)]
