"""The plan's path as the vehicle's waypoints: where it hovers, and which of its points a leg
flies through.

A leg between two stops keeps as few of the plan's points as keep it within a tolerance of the
plan (Douglas-Peucker, :func:`simplify`), then drops those that leave a step too short for the
vehicle to reach its speed (:func:`drop_short_steps`). With zones, every segment that replaces
the plan between two kept points must keep their margin (:func:`zone_check`).
"""

from __future__ import annotations

import math
from typing import Callable, Optional

import numpy as np

from uav_comm_planner.core.detour import segments_clear
from uav_comm_planner.core.model import vector_lengths
from uav_comm_planner.core.zones import Zones


def hover_runs(points: np.ndarray, merge_radius_m: float) -> list[tuple[int, int]]:
    """Split points (K, 2) into maximal runs [i, j] whose points are all within the radius."""
    # A point farther than the radius from the one before it starts a run at once.
    steps = vector_lengths(np.diff(points, axis=0), axis=1).tolist()
    runs = []
    first = 0
    for index in range(1, len(points) + 1):
        if index < len(points) and steps[index - 1] <= merge_radius_m:
            gaps = vector_lengths(points[first:index] - points[index], axis=1)
            if gaps.max() <= merge_radius_m:
                continue
        runs.append((first, index - 1))
        first = index
    return runs


#: Whether a straight segment from a to b may replace the plan between them (the zones).
SegmentCheck = Optional[Callable[[np.ndarray, np.ndarray], bool]]


def zone_check(zones: Zones | None) -> SegmentCheck:
    """With zones, the check that a segment keeps their margin (exact); None without."""
    if zones is None or zones.empty:
        return None
    return lambda a, b: bool(segments_clear(zones, a, b)[0])


def simplify(points: np.ndarray, tolerance_m: float, keeps: SegmentCheck = None) -> list[int]:
    """Douglas-Peucker: indices of the points kept so every point is within the tolerance
    and, with ``keeps``, every segment between kept points passes it (a segment of two
    neighbours is the plan's own leg, which keeps the zones). The segments still to split are
    taken a generation at a time, their points' distances in one computation."""
    keep = {0, len(points) - 1}
    pending = [(0, len(points) - 1)]
    while pending:
        pending = [(first, last) for first, last in pending if last - first >= 2]
        if not pending:
            break
        farthest, gaps = _farthest_points(points, pending)
        split_up = []
        for (first, last), split, gap in zip(pending, farthest, gaps):
            if gap > tolerance_m or (keeps is not None
                                     and not keeps(points[first], points[last])):
                keep.add(split)
                split_up += [(first, split), (split, last)]
        pending = split_up
    return sorted(keep)


def _farthest_points(points: np.ndarray, segments: list[tuple[int, int]]) -> tuple[list, list]:
    """For each segment (first, last), last - first >= 2, of the polyline ``points`` (K, 2):
    the index of the point between them farthest from the segment points[first] ->
    points[last] (the first of equals) and its distance, as
    :func:`~uav_comm_planner.vehicle.evaluation.distance_to_polyline` gives it."""
    firsts, lasts = np.array(segments).T
    counts = lasts - firsts - 1
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    segment = np.repeat(np.arange(len(segments)), counts)
    inner = np.arange(counts.sum()) - starts[segment] + firsts[segment] + 1
    a = points[firsts]
    ab = points[lasts] - a
    length2 = np.maximum((ab * ab).sum(axis=1), 1e-300)
    a, ab = a[segment], ab[segment]
    t = np.minimum(np.maximum(((points[inner] - a) * ab).sum(axis=1) / length2[segment], 0.0),
                   1.0)
    gaps = vector_lengths(points[inner] - (a + t[:, None] * ab), axis=1)
    largest = np.maximum.reduceat(gaps, starts)
    at = np.minimum.reduceat(np.where(gaps == largest[segment], np.arange(len(gaps)),
                                      len(gaps)), starts)
    return inner[at].tolist(), largest.tolist()


def _span_gap(xy: list[tuple[float, float]], first: int, last: int) -> float:
    """The largest distance of the points xy[first:last + 1] from the segment xy[first] ->
    xy[last]: :func:`~uav_comm_planner.vehicle.evaluation.distance_to_polyline`'s arithmetic,
    operation for operation, on Python floats (the spans :func:`drop_short_steps` asks about
    are a few points long, where an array's overhead is most of the time)."""
    (ax, ay), (bx, by) = xy[first], xy[last]
    abx, aby = bx - ax, by - ay
    length2 = max(abx * abx + aby * aby, 1e-300)
    largest = 0.0
    for px, py in xy[first:last + 1]:
        t = min(max(((px - ax) * abx + (py - ay) * aby) / length2, 0.0), 1.0)
        ex, ey = px - (ax + t * abx), py - (ay + t * aby)
        largest = max(largest, math.sqrt(ex * ex + ey * ey))
    return largest


def drop_short_steps(points: np.ndarray, kept: list[int], min_step_m: float,
                     keeps: SegmentCheck = None) -> list[int]:
    """Remove fly-through waypoints that leave a step shorter than ``min_step_m``, the one
    whose removal moves the line least first; with ``keeps``, only those whose removal leaves
    a segment that passes it."""
    kept = list(kept)
    xy = [tuple(point) for point in points.tolist()]
    steps = [_step(xy[before], xy[after]) for before, after in zip(kept, kept[1:])]
    costs: dict[tuple[int, int], float] = {}     # by the two waypoints the line joins

    def cost(before: int, after: int) -> float:
        if (before, after) not in costs:
            costs[before, after] = _span_gap(xy, before, after)
        return costs[before, after]

    while len(kept) > 2:
        shortest = min(steps)
        if shortest >= min_step_m:
            break
        short = steps.index(shortest)
        candidates = [i for i in (short, short + 1) if 0 < i < len(kept) - 1]
        if keeps is not None:
            candidates = [i for i in candidates
                          if keeps(points[kept[i - 1]], points[kept[i + 1]])]
            if not candidates:
                break
        dropped = min(candidates, key=lambda i: cost(kept[i - 1], kept[i + 1]))
        del kept[dropped]
        del steps[dropped]
        steps[dropped - 1] = _step(xy[kept[dropped - 1]], xy[kept[dropped]])
    return kept


def _step(a: tuple[float, float], b: tuple[float, float]) -> float:
    """The length of the step from a to b, as :func:`numpy.linalg.norm` computes it."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    return math.sqrt(dx * dx + dy * dy)


def turn_angles_deg(vertices: np.ndarray) -> np.ndarray:
    """The heading change at each inner vertex of a polyline (V, 2), degrees (V - 2,)."""
    steps = np.diff(vertices, axis=0)
    headings = np.arctan2(steps[:, 1], steps[:, 0])
    return np.degrees(np.abs((np.diff(headings) + np.pi) % (2 * np.pi) - np.pi))


__all__ = ['SegmentCheck', 'drop_short_steps', 'hover_runs', 'simplify', 'turn_angles_deg',
           'zone_check']
