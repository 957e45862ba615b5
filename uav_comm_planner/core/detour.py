"""Starts and baselines that keep out of the zones: paths around them and points outside them.

With zones (:attr:`~uav_comm_planner.core.scenario.Scenario.zones`) the straight line q0 -> qF
may cross one. :func:`straight_start` replaces it by the shortest path around the zones: a
visibility graph over corners placed around every zone at the margin (and
:data:`GRAPH_CLEARANCE_M` more), circles by their circumscribed polygons of
:data:`CIRCLE_SIDES` sides, polygons by arcs of the same kind around their convex corners, the
operating area around its reflex ones; two corners are joined when the segment between them
keeps the margin by the zones' exact clearance, and Dijkstra finds the shortest way. That
polyline is flown at as uniform a speed as its corners allow, every corner a waypoint (a leg
that cut a corner could enter the zone). :func:`hover_start` flies a tour of the nodes' best
points outside the zones (a node inside a zone is served from the nearest point that keeps
the margin) along such paths and hovers there. Without zones both are
:mod:`~uav_comm_planner.core.initial`'s trajectories, unchanged.

A request with no path around the zones, or none that fits the horizon at V, is refused with
:class:`~uav_comm_planner.errors.InfeasibleHorizonError` and the numbers.
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
import math
from typing import Callable, Iterator

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from uav_comm_planner.core import initial
from uav_comm_planner.core.edge_tree import against_edges, EdgeTree, point_segment_distance
from uav_comm_planner.core.recent import RecentlyUsed
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.core.zone_hulls import wrapped_hulls, zones_holding
from uav_comm_planner.core.zones import (closest_on_segments, inside_polygon, KeepOutCircle,
                                         Zones)
from uav_comm_planner.errors import InfeasibleHorizonError, WalledInError

#: Sides of the polygon that stands for a keep-out circle (circumscribed, so it holds the
#: circle grown by the margin): its perimeter is 1 % longer than the circle's.
CIRCLE_SIDES = 16
#: The graph's corners stand this much beyond the margin, so that round-off never puts a
#: corner-to-corner edge inside it.
GRAPH_CLEARANCE_M = 0.05
#: Segment-edge pairs tested at once (bounds the work arrays' memory).
CHUNK_PAIRS = 500_000
#: Corner pairs of the visibility graph tested between two asks of :func:`corner_graph`'s
#: check.
GRAPH_CHUNK = 2000
#: Visibility graphs kept (the most recently used), by their zones.
GRAPHS_KEPT = 16
#: A line counts as tangent at a corner when a neighbour on the wrong side is within this
#: (the sine of the angle) of it.
TANGENT_SLACK = math.sin(0.01)
#: An arc of a circumscribed polygon turns at most this much per corner.
MAX_ARC_STEP_RAD = math.pi / 8


def _arc_chain(vertex: np.ndarray, first: np.ndarray, second: np.ndarray,
               radius: float) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Corners of the polygon circumscribed about the arc of ``radius`` round ``vertex`` from
    the unit direction ``first`` to ``second`` (the shorter way; each of its edges is tangent
    to the arc, so the polygon holds it), each with the unit directions along that polygon to
    the corner before it and to the one after it; the ends' outer directions are along the
    tangents at the arc's ends (the zone's edges)."""
    start = math.atan2(first[1], first[0])
    turn = (math.atan2(second[1], second[0]) - start + math.pi) % (2 * math.pi) - math.pi
    count = max(1, math.ceil(abs(turn) / MAX_ARC_STEP_RAD))
    step = turn / count
    reach = radius / math.cos(step / 2)
    corners = [vertex + reach * np.array([math.cos(start + (i + 0.5) * step),
                                          math.sin(start + (i + 0.5) * step)])
               for i in range(count)]
    sense = 1.0 if step >= 0 else -1.0

    def along(angle: float) -> np.ndarray:   # the tangent at ``angle``, in the arc's sense
        return sense * np.array([-math.sin(angle), math.cos(angle)])
    chain = []
    for i, corner in enumerate(corners):
        back = (corners[i - 1] - corner) if i > 0 else -along(start)
        ahead = (corners[i + 1] - corner) if i + 1 < count else along(start + turn)
        chain.append((corner, back / math.hypot(*back), ahead / math.hypot(*ahead)))
    return chain


def _polygon_chain(vertices: np.ndarray, radius: float,
                   outside: bool) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Corners round a CCW polygon's convex vertices (``outside``: a keep-out polygon) or round
    its reflex vertices on the inside (an operating area), each with its directions back and
    ahead (:func:`_arc_chain`)."""
    corners = []
    count = len(vertices)
    for i in range(count):
        before, here, after = vertices[i - 1], vertices[i], vertices[(i + 1) % count]
        incoming, outgoing = here - before, after - here
        turn = incoming[0] * outgoing[1] - incoming[1] * outgoing[0]     # > 0: convex corner
        if (turn > 0) != outside or turn == 0:
            continue
        side = 1.0 if outside else -1.0      # outward normals (right of a CCW edge), or inward
        normals = [side * np.array([v[1], -v[0]]) / math.hypot(*v)
                   for v in (incoming, outgoing)]
        corners += _arc_chain(here, normals[0], normals[1], radius)
    return corners


def graph_corners(zones: Zones, whole: frozenset[int] = frozenset()) -> np.ndarray:
    """The visibility graph's corners (K, 2) metres that keep the margin."""
    return _placed_corners(zones, whole)[0]


@functools.lru_cache(maxsize=16)
def _own_corners(zones: Zones) -> np.ndarray:
    """The corners round every zone's own vertices, none wrapped by its hull (K, 2)."""
    radius = zones.margin_m + GRAPH_CLEARANCE_M
    corners = graph_corners(zones, frozenset(wrapped_hulls(zones, radius)))
    corners.setflags(write=False)
    return corners


def _graph_chain(zones: Zones, whole: frozenset[int] = frozenset()
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The graph's corners (K, 2) that keep the margin; for each the unit directions (K, 2)
    along the polygon of corners round its zone to its neighbours, back and ahead; and whether
    its zone is the only one near it (K,): no other zone comes within
    :func:`_alone_distance` of it. A zone wrapped by its hull
    (:func:`~uav_comm_planner.core.zone_hulls.wrapped_hulls`) has the corners round its hull,
    unless its place is in ``whole``."""
    corners, back, ahead, owner = _placed_corners(zones, whole)
    alone = np.ones(len(corners), dtype=bool)
    reach = _alone_distance(zones)
    for number, zone in enumerate((*zones.keep_out, *(() if zones.area is None
                                                      else (zones.area,)))):
        others = owner != number
        if others.any():
            alone[others] &= zone.clearance(corners[others]) >= reach
    return corners, back, ahead, alone


def _placed_corners(zones: Zones, whole: frozenset[int]
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_graph_chain`'s corners, directions back and ahead, and each one's zone (K,):
    its place in ``zones.keep_out``, or after them the area."""
    radius = zones.margin_m + GRAPH_CLEARANCE_M
    hulls = wrapped_hulls(zones, radius)
    chain: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    owners: list[int] = []
    for number, zone in enumerate(zones.keep_out):
        if isinstance(zone, KeepOutCircle):
            centre = np.array(zone.center_m)
            more = _circle_chain(centre, zone.radius_m + radius)
        else:
            outline = hulls[number] if number in hulls and number not in whole \
                else zone.vertices_m
            more = _polygon_chain(outline, radius, outside=True)
        chain += more
        owners += [number] * len(more)
    if zones.area is not None:
        more = _polygon_chain(zones.area.vertices_m, radius, outside=False)
        chain += more
        owners += [len(zones.keep_out)] * len(more)
    if not chain:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, dtype=int)
    corners, back, ahead = (np.array(part) for part in zip(*chain))
    # Each corner as a segment of no length: it keeps the margin (it is never on an edge).
    keep = segments_clear(zones, corners, corners)
    return corners[keep], back[keep], ahead[keep], np.array(owners)[keep]


def _alone_distance(zones: Zones) -> float:
    """How far (m) the other zones keep from a corner for the tangent rule to prune its
    pairs: twice the corners' distance from their zone and a metre. Where zones come closer
    (they overlap, or meet within their margins) the shortest path may bend round the union's
    corners, which are no zone's own: there every pair of the corner is tested."""
    return 2.0 * (zones.margin_m + GRAPH_CLEARANCE_M) + 1.0


def _circle_chain(centre: np.ndarray,
                  radius: float) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The corners of the :data:`CIRCLE_SIDES`-gon circumscribed about a circle, each with its
    directions back and ahead."""
    reach = radius / math.cos(math.pi / CIRCLE_SIDES)
    angles = 2 * math.pi * (np.arange(CIRCLE_SIDES) + 0.5) / CIRCLE_SIDES
    corners = centre + reach * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    back = np.roll(corners, 1, axis=0) - corners
    ahead = np.roll(corners, -1, axis=0) - corners
    back /= np.linalg.norm(back, axis=1)[:, None]
    ahead /= np.linalg.norm(ahead, axis=1)[:, None]
    return list(zip(corners, back, ahead))


def tangent_pairs(corners: np.ndarray, back: np.ndarray, ahead: np.ndarray,
                  alone: np.ndarray, rows: slice) -> tuple[np.ndarray, np.ndarray]:
    """The corner pairs (i, j), i in ``rows`` and j > i, whose line is tangent at both corners
    to the polygon of corners round each one's zone: its neighbours there (``back``,
    ``ahead``: unit directions) lie on one side of the line, or within
    :data:`TANGENT_SLACK` of it. A shortest path round the zones bends only where it wraps
    round a zone, and there both its segments are tangent (Lee's reduced visibility graph):
    the other pairs need no visibility test. A corner not ``alone`` (another zone near it) is
    taken as tangent to every line."""
    first = np.arange(len(corners))[rows]
    direction = corners[None, :] - corners[first, None]            # (R, K, 2)
    tolerance = TANGENT_SLACK * np.hypot(direction[..., 0], direction[..., 1])

    def tangent(before: np.ndarray, after: np.ndarray) -> np.ndarray:
        one = direction[..., 0] * before[..., 1] - direction[..., 1] * before[..., 0]
        two = direction[..., 0] * after[..., 1] - direction[..., 1] * after[..., 0]
        return (one * two >= 0) | (np.abs(one) <= tolerance) | (np.abs(two) <= tolerance)
    both = (tangent(back[first, None], ahead[first, None]) | ~alone[first, None]) \
        & (tangent(back[None], ahead[None]) | ~alone[None])
    both &= np.arange(len(corners))[None, :] > first[:, None]
    i, j = np.nonzero(both)
    return first[i], j


def _inside_any(points: np.ndarray, polygons: tuple[np.ndarray, ...]) -> np.ndarray:
    """Whether each point (S, 2) is inside any of the polygons (only those whose bounding box
    holds it are tested)."""
    inside = np.zeros(len(points), dtype=bool)
    for vertices in polygons:
        low, high = vertices.min(axis=0), vertices.max(axis=0)
        boxed = np.nonzero(((points >= low) & (points <= high)).all(axis=1) & ~inside)[0]
        if len(boxed):
            inside[boxed] = inside_polygon(points[boxed], vertices)
    return inside


@functools.lru_cache(maxsize=16)
def _zone_edges(zones: Zones) -> tuple[np.ndarray, np.ndarray, EdgeTree, EdgeTree | None,
                                       tuple[np.ndarray, ...]]:
    """The keep-out zones as arrays: circles' centres (C, 2) and radii (C,); the trees of
    every keep-out polygon's edges and of the operating area's (None without one); the
    polygons."""
    circles = [zone for zone in zones.keep_out if isinstance(zone, KeepOutCircle)]
    polygons = tuple(zone.vertices_m for zone in zones.keep_out
                     if not isinstance(zone, KeepOutCircle))
    centres = np.array([zone.center_m for zone in circles]).reshape(-1, 2)
    radii = np.array([zone.radius_m for zone in circles])
    area = None if zones.area is None else EdgeTree.of_rings([zones.area.vertices_m])
    return centres, radii, EdgeTree.of_rings(polygons), area, polygons


def segments_clear(zones: Zones, a: np.ndarray, b: np.ndarray, *,
                   margin_m: float | None = None) -> np.ndarray:
    """Whether each segment a[s] b[s] ((S, 2) each) keeps the margin (``margin_m``, the
    zones' own by default) from every zone: exact distances, vectorised over the segments and
    every zone's edges at once, only the segment-edge pairs whose bounding boxes come within
    the margin measured (the zones'
    :meth:`~uav_comm_planner.core.zones.Zones.path_clearance` is the slower reference the
    tests use)."""
    a, b = np.atleast_2d(np.asarray(a, float)), np.atleast_2d(np.asarray(b, float))
    margin = zones.margin_m if margin_m is None else margin_m
    centres, radii, edges, area_edges, polygons = _zone_edges(zones)
    ok = np.ones(len(a), dtype=bool)
    if len(radii):
        rows = max(1, CHUNK_PAIRS // len(radii))
        for first in range(0, len(a), rows):
            part = slice(first, first + rows)
            reach = point_segment_distance(centres[None], a[part, None], b[part, None])
            ok[part] &= (reach >= radii + margin).all(axis=1)
    # A segment that meets no edge is wholly inside or wholly outside each polygon: its end a
    # tells which (asked only of the segments still clear).
    if polygons:
        meets, distance = against_edges(a, b, edges, margin)
        ok &= ~meets & (distance >= margin)
        ok[ok] = ~_inside_any(a[ok], polygons)
    if area_edges is not None:
        meets, distance = against_edges(a, b, area_edges, margin)
        ok &= ~meets & (distance >= margin)
        ok[ok] = _inside_any(a[ok], (zones.area.vertices_m,))
    return ok


def clear(zones: Zones, a: np.ndarray, b: np.ndarray) -> bool:
    """Whether the segment ab keeps the margin from every zone (exact)."""
    return bool(segments_clear(zones, a, b)[0])


#: The check a plan asks while it works round the zones (:func:`asking`); None: none.
_CHECK: contextvars.ContextVar[Callable[[], None] | None] = contextvars.ContextVar(
    'zone_check', default=None)


@contextlib.contextmanager
def asking(check: Callable[[], None]) -> Iterator[None]:
    """Within it, every visibility graph built and every path searched round the zones (in
    this thread) asks ``check``, which raises to give up (a plan being cancelled): the graph
    between its chunks, :func:`shortest_path` before it searches. The starts round the zones
    are made in it without a check of their own."""
    token = _CHECK.set(check)
    try:
        yield
    finally:
        _CHECK.reset(token)


def _ask(check: Callable[[], None] | None) -> None:
    """``check``, or the one :func:`asking` set, if any."""
    check = check if check is not None else _CHECK.get()
    if check is not None:
        check()


#: The visibility graphs built, by their zones (:func:`corner_graph`).
GRAPHS: RecentlyUsed[tuple[np.ndarray, np.ndarray]] = RecentlyUsed(GRAPHS_KEPT)


def corner_graph(zones: Zones, check: Callable[[], None] | None = None,
                 whole: frozenset[int] = frozenset()) -> tuple[np.ndarray, np.ndarray]:
    """The graph's corners (K, 2) and their visibility (K, K), lengths or 0 (none), built
    once per zones and kept: only corner pairs tangent at both ends (:func:`tangent_pairs`)
    are tested and joined, in chunks of :data:`GRAPH_CHUNK` pairs. The building is the work
    that grows with the zones' corners (cubed): ``check`` is asked between its chunks (and
    between the rows of pairs the tangents are found for) and raises to give up (a plan being
    cancelled), nothing being kept then. A planner given a way to be cancelled builds the
    graph first with it (:func:`~uav_comm_planner.core.optimizer.plan`); the paths and starts
    then use the graph kept. The zones wrapped by their hulls whose places are in ``whole``
    have their own corners (a path from inside such a hull, :func:`shortest_path`)."""
    key = zones if not whole else (zones, whole)
    graph = GRAPHS.get(key)
    if graph is not None:
        return graph
    _ask(check)
    corners, back, ahead, alone = _graph_chain(zones, whole)
    count = len(corners)
    candidates = [(np.zeros(0, dtype=int), np.zeros(0, dtype=int))]
    rows_per_chunk = max(1, GRAPH_CHUNK * 50 // max(count, 1))
    for first in range(0, count, rows_per_chunk):
        _ask(check)
        candidates.append(tangent_pairs(corners, back, ahead, alone,
                                        slice(first, first + rows_per_chunk)))
    i = np.concatenate([pair[0] for pair in candidates])
    j = np.concatenate([pair[1] for pair in candidates])
    visible = np.zeros(len(i), dtype=bool)
    for first in range(0, len(i), GRAPH_CHUNK):
        _ask(check)
        pairs = slice(first, first + GRAPH_CHUNK)
        visible[pairs] = segments_clear(zones, corners[i[pairs]], corners[j[pairs]])
    lengths = np.zeros((count, count))
    i, j = i[visible], j[visible]
    lengths[i, j] = np.linalg.norm(corners[j] - corners[i], axis=1)
    for array in (corners, lengths):
        array.setflags(write=False)
    GRAPHS.put(key, (corners, lengths))
    return corners, lengths


def shortest_path(zones: Zones, start: np.ndarray, goal: np.ndarray,
                  check: Callable[[], None] | None = None) -> np.ndarray | None:
    """The shortest polyline (K, 2) from ``start`` to ``goal`` through the graph's corners
    whose every segment keeps the margin; None when there is none. ``check`` is asked as in
    :func:`corner_graph` before the search and while a graph is built for it."""
    _ask(check)
    start, goal = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
    if clear(zones, start, goal):
        return np.array([start, goal])
    whole = zones_holding(zones, zones.margin_m + GRAPH_CLEARANCE_M, np.array([start, goal]))
    corners, corner_lengths = corner_graph(zones, check, whole)
    count = len(corners) + 2
    lengths = np.zeros((count, count))
    lengths[2:, 2:] = corner_lengths
    for row, end in ((0, start), (1, goal)):
        ends = np.repeat(end[None], len(corners), axis=0)
        seen = segments_clear(zones, ends, corners)
        lengths[row, 2:] = np.where(seen, np.linalg.norm(corners - end, axis=1), 0.0)
    points = np.vstack([start, goal, corners])
    distances, previous = dijkstra(csr_matrix(lengths), directed=False, indices=0,
                                   return_predecessors=True)
    if not math.isfinite(distances[1]):
        return None
    order = [1]
    while order[-1] != 0:
        order.append(int(previous[order[-1]]))
    return points[order[::-1]]


def path_length(path: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


def _no_path(scenario: Scenario, what: str) -> WalledInError:
    return WalledInError(
        f'no path from {what} keeps the margin of {scenario.zones.margin_m:g} m from the zones '
        f'(the goal or the start is walled in); move it or the zones')


def _stretch_legs(path: np.ndarray, scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """The stretches of ``path`` (zero-length ones dropped) and the fewest legs each needs at
    the fastest ground speed along it (a share of 1e-9 below it, so no leg is over a limit)."""
    steps = np.diff(path, axis=0)
    lengths = np.linalg.norm(steps, axis=1)
    keep = np.concatenate([[True], lengths > 0])
    path = path[keep]
    steps = np.diff(path, axis=0)
    lengths = np.linalg.norm(steps, axis=1)
    fastest = np.array([scenario.fastest_ground_speed_mps(step / length)
                        for step, length in zip(steps, lengths)])
    needed = np.ceil(lengths / (fastest * scenario.slot_s * (1 - 1e-9))).astype(int)
    return path, needed


def _too_long(scenario: Scenario, path: np.ndarray, needed: int) -> InfeasibleHorizonError:
    legs = scenario.num_slots + 1
    return InfeasibleHorizonError(
        f'goal unreachable around the zones: the shortest path that keeps their margin of '
        f'{scenario.zones.margin_m:g} m is {path_length(path):.1f} m with {len(path) - 2} '
        f'corners and needs {needed} legs of {scenario.slot_s:g} s at {scenario.max_speed_mps:g}'
        f' m/s, the horizon has {legs}; {_remedy(path, scenario)}')


def _remedy(path: np.ndarray, scenario: Scenario) -> str:
    """What lets the slots fly ``path``: a longer horizon, or, when its corners alone (each a
    slot point) outnumber the slots, more slots, since no horizon is long enough then."""
    stretches = int((np.linalg.norm(np.diff(path, axis=0), axis=1) > 0).sum())
    if stretches > scenario.num_slots + 1:
        return (f'its {stretches} stretches need num_slots {stretches - 1} or more (every '
                f'corner is a slot point), or move the zones')
    return (f'raise horizon_s to {horizon_needed_s(path, scenario):.1f} s or more, or '
            f'max_speed_mps, or move the zones')


def horizon_needed_s(path: np.ndarray, scenario: Scenario) -> float:
    """The shortest horizon T, rounded up to 0.1 s, in which M slots fly ``path`` with every
    corner a slot point: sum_k ceil(L_k M / (g_k T)) <= M + 1 (bisection: the sum only falls
    as T grows)."""
    steps = np.diff(path, axis=0)
    lengths = np.linalg.norm(steps, axis=1)
    steps, lengths = steps[lengths > 0], lengths[lengths > 0]
    fastest = np.array([scenario.fastest_ground_speed_mps(step / length)
                        for step, length in zip(steps, lengths)])
    m = scenario.num_slots

    def fits(horizon_s: float) -> bool:
        return int(np.ceil(lengths * m / (fastest * horizon_s * (1 - 1e-9))).sum()) <= m + 1

    low = float((lengths / fastest).sum()) * m / (m + 1)
    high = max(low, 1e-9) * 2.0
    while not fits(high):
        high *= 2.0
    for _ in range(100):
        middle = 0.5 * (low + high)
        low, high = (low, middle) if fits(middle) else (middle, high)
    return math.ceil(high * 10.0) / 10.0


def around_zones(scenario: Scenario) -> np.ndarray:
    """The shortest path around the zones from q0 to qF at as uniform a speed as its corners
    allow: q (M, 2) metres. Each stretch between corners gets legs in proportion to its
    length, but never fewer than the speed limits need; every corner is a slot point."""
    path = shortest_path(scenario.zones, scenario.start_m, scenario.goal_m)
    if path is None:
        raise _no_path(scenario, 'q0 to qF')
    path, needed = _stretch_legs(path, scenario)
    legs = scenario.num_slots + 1
    if needed.sum() > legs:
        raise _too_long(scenario, path, int(needed.sum()))
    if len(needed) == 0:
        return np.repeat(path[:1], scenario.num_slots, axis=0)
    counts = needed.copy()
    lengths = np.linalg.norm(np.diff(path, axis=0), axis=1)
    ideal = legs * lengths / lengths.sum()
    for _ in range(legs - int(counts.sum())):
        counts[int(np.argmax(ideal - counts))] += 1
    return _waypoints(path, counts, np.zeros(len(path), dtype=int))[1:-1]


def _waypoints(path: np.ndarray, counts: np.ndarray, hovers: np.ndarray) -> np.ndarray:
    """q0, hovers[0] slots at q0, then stretch k of ``path`` in counts[k] equal legs and
    hovers[k + 1] slots at its end, ..., qF."""
    waypoints = [path[0]]
    waypoints.extend([path[0]] * int(hovers[0]))     # a stop at q0 hovers there
    for k, count in enumerate(counts):
        fractions = np.arange(1, count + 1) / count
        waypoints.extend(path[k] + fractions[:, None] * (path[k + 1] - path[k]))
        waypoints.extend([path[k + 1]] * int(hovers[k + 1]))
    return np.asarray(waypoints)


def outside_point(zones: Zones, point: np.ndarray) -> np.ndarray | None:
    """``point`` if it keeps the margin, else the nearest point found that does: the point
    pushed out of each zone it is too close to, along the way to that zone's nearest edge
    (radially for a circle), to the margin and :data:`GRAPH_CLEARANCE_M` beyond, or a corner
    round a zone's own vertices (a zone's pockets' too, where the graph wraps it by its hull);
    None when none keeps the margin."""
    point = np.asarray(point, dtype=float)
    if zones.clearance([point])[0] >= zones.margin_m:
        return point
    reach = zones.margin_m + GRAPH_CLEARANCE_M
    candidates = [_own_corners(zones)]     # the pockets' corners too, as ever
    for zone in (*zones.keep_out, *(() if zones.area is None else (zones.area,))):
        if zone.clearance([point])[0] >= zones.margin_m:
            continue
        if isinstance(zone, KeepOutCircle):
            centre = np.array(zone.center_m)
            away = _unit_or_east(point - centre)
            candidates.append((centre + (zone.radius_m + reach) * away)[None])
            continue
        # On the wrong side of the edge (in a keep-out polygon, out of the area): cross it;
        # on the right side but too close: move away from it.
        edge = _nearest_boundary(point, zone.vertices_m)
        wrong_side = zone.clearance([point])[0] < 0
        direction = _unit_or_east(edge - point if wrong_side else point - edge)
        candidates.append((edge + reach * direction)[None])
    candidates = np.vstack(candidates)
    candidates = candidates[zones.clearance(candidates) >= zones.margin_m]
    if not len(candidates):
        return None
    return candidates[int(np.argmin(np.linalg.norm(candidates - point, axis=1)))]


def _unit_or_east(vector: np.ndarray) -> np.ndarray:
    length = float(np.linalg.norm(vector))
    return vector / length if length > 0 else np.array([1.0, 0.0])


def _nearest_boundary(point: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    closest = closest_on_segments(point[None], vertices, np.roll(vertices, -1, axis=0))
    return closest[int(np.argmin(np.linalg.norm(closest - point, axis=1)))]


def straight_start(scenario: Scenario) -> np.ndarray:
    """The straight line q0 -> qF at uniform speed, or with zones the path around them."""
    if scenario.zones is None or scenario.zones.empty:
        return initial.straight_line(scenario)
    return around_zones(scenario)


def static_start(scenario: Scenario) -> np.ndarray:
    """The static access point above the nodes' centroid, or the nearest point outside the
    zones (the path to it is not flown: the baseline ignores q0 and qF, as in the letter)."""
    q = initial.static_point(scenario)
    if scenario.zones is None or scenario.zones.empty:
        return q
    point = outside_point(scenario.zones, q[0])
    if point is None:
        raise _no_path(scenario, 'the nodes\' centroid')
    return np.repeat(point[None], scenario.num_slots, axis=0)


def hover_start(scenario: Scenario) -> np.ndarray:
    """:func:`~uav_comm_planner.core.initial.hover_and_fly`, or with zones a tour of the
    nodes' points outside them (:func:`outside_point`) flown around the zones, the slots left
    over hovered evenly at the points; the nodes whose detours cost most are left out until it
    fits, and with none left it is :func:`around_zones`."""
    if scenario.zones is None or scenario.zones.empty:
        return initial.hover_and_fly(scenario)
    zones = scenario.zones
    start, goal = np.asarray(scenario.start_m), np.asarray(scenario.goal_m)
    stops = [outside_point(zones, w) for w in scenario.nodes]
    reachable = [i for i, stop in enumerate(stops)
                 if stop is not None and shortest_path(zones, start, stop) is not None]
    if not reachable:
        return around_zones(scenario)
    points = np.array([stops[i] for i in reachable])
    order = initial.two_opt(start, goal, points, initial.nearest_neighbour_order(start, points))
    legs = scenario.num_slots + 1
    while order:
        tour = [start, *points[order], goal]
        pieces = [shortest_path(zones, a, b) for a, b in zip(tour[:-1], tour[1:])]
        if all(piece is not None for piece in pieces):
            path, counts, hover_at = _joined(pieces, scenario)
            if counts.sum() <= legs:
                hovers = np.zeros(len(path), dtype=int)
                # Two stops at one point (a node's nearest point shared) hover there for both.
                np.add.at(hovers, hover_at,
                          initial.even_hovers(legs - int(counts.sum()), len(order)))
                return _waypoints(path, counts, hovers)[1:-1]
        # Leave out the stop whose detour costs most (straight-line lengths, as initial does).
        tour = np.array(tour)
        detour = (np.linalg.norm(tour[1:-1] - tour[:-2], axis=1)
                  + np.linalg.norm(tour[2:] - tour[1:-1], axis=1)
                  - np.linalg.norm(tour[2:] - tour[:-2], axis=1))
        del order[int(np.argmax(detour))]
    return around_zones(scenario)


def _joined(pieces: list[np.ndarray],
            scenario: Scenario) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """The tour's polyline, the legs each stretch needs, and the path indices of the stops."""
    path = [pieces[0][:1]]
    counts = []
    stops = []
    for piece in pieces:
        piece, needed = _stretch_legs(piece, scenario)
        path.append(piece[1:])
        counts.append(needed)
        stops.append(sum(len(p) for p in path) - 1)
    return np.vstack(path), np.concatenate(counts), stops[:-1]


__all__ = ['GRAPHS', 'around_zones', 'asking', 'corner_graph', 'graph_corners',
           'hover_start', 'outside_point', 'shortest_path',
           'static_start', 'straight_start']
