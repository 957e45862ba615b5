"""Zones that scale: the paths round the zones found on a visibility graph of only the corner
pairs tangent at both ends, tested against every zone edge at once with bounding boxes, give
the same shortest paths as the graph of every corner pair (the earlier algorithm, kept here
as the reference), at a fraction of the cost; and the polygons' self-crossing check is
vectorised."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from uav_comm_planner.core.detour import (CHUNK_PAIRS, CIRCLE_SIDES, corner_graph,
                                          GRAPH_CLEARANCE_M, graph_corners, GRAPHS,
                                          MAX_ARC_STEP_RAD, segments_clear, shortest_path)
from uav_comm_planner.core.zone_hulls import wrapped_hulls, zones_holding
from uav_comm_planner.core.zones import (_first_crossing, _segment_meets_edges, _segments_cross,
                                         closest_on_segments,
                                         inside_polygon, KeepOutCircle, KeepOutPolygon,
                                         OperatingArea, Zones)
from uav_comm_planner.errors import InvalidScenarioError

# The reference: the graph as it was built before, every corner pair tested against every
# zone one by one.


def _old_arc(vertex: np.ndarray, first: np.ndarray, second: np.ndarray,
             radius: float) -> list[np.ndarray]:
    """Corners of the polygon circumscribed about the arc of ``radius`` round ``vertex`` from
    the unit direction ``first`` to ``second`` (the shorter way): each of its edges is tangent
    to the arc, so the polygon holds it."""
    start = math.atan2(first[1], first[0])
    turn = (math.atan2(second[1], second[0]) - start + math.pi) % (2 * math.pi) - math.pi
    count = max(1, math.ceil(abs(turn) / MAX_ARC_STEP_RAD))
    step = turn / count
    reach = radius / math.cos(step / 2)
    return [vertex + reach * np.array([math.cos(start + (i + 0.5) * step),
                                       math.sin(start + (i + 0.5) * step)])
            for i in range(count)]


def _old_polygon_corners(vertices: np.ndarray, radius: float,
                         outside: bool) -> list[np.ndarray]:
    """Corners round a CCW polygon's convex vertices (``outside``: a keep-out polygon) or
    round its reflex vertices on the inside (an operating area)."""
    corners = []
    count = len(vertices)
    for i in range(count):
        before, here, after = vertices[i - 1], vertices[i], vertices[(i + 1) % count]
        incoming, outgoing = here - before, after - here
        turn = incoming[0] * outgoing[1] - incoming[1] * outgoing[0]     # > 0: convex corner
        if (turn > 0) != outside or turn == 0:
            continue
        side = 1.0 if outside else -1.0      # outward normals (right of a CCW edge), or inward
        normals = [side * np.array([v[1], -v[0]]) / np.linalg.norm(v)
                   for v in (incoming, outgoing)]
        corners += _old_arc(here, normals[0], normals[1], radius)
    return corners


def old_graph_corners(zones: Zones) -> np.ndarray:
    """The visibility graph's corners (K, 2) metres that keep the margin."""
    radius = zones.margin_m + GRAPH_CLEARANCE_M
    corners: list[np.ndarray] = []
    for zone in zones.keep_out:
        if isinstance(zone, KeepOutCircle):
            centre = np.array(zone.center_m)
            corners += _old_arc_circle(centre, zone.radius_m + radius)
        else:
            corners += _old_polygon_corners(zone.vertices_m, radius, outside=True)
    if zones.area is not None:
        corners += _old_polygon_corners(zones.area.vertices_m, radius, outside=False)
    if not corners:
        return np.zeros((0, 2))
    corners = np.array(corners)
    return corners[zones.clearance(corners) >= zones.margin_m]


def _old_arc_circle(centre: np.ndarray, radius: float) -> list[np.ndarray]:
    reach = radius / math.cos(math.pi / CIRCLE_SIDES)
    angles = 2 * math.pi * (np.arange(CIRCLE_SIDES) + 0.5) / CIRCLE_SIDES
    return list(centre + reach * np.stack([np.cos(angles), np.sin(angles)], axis=1))


def _old_orient(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) \
        - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])


def _old_point_segment(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances of points to segments ab, broadcasting over leading axes."""
    return np.linalg.norm(points - closest_on_segments(points, a, b), axis=-1)


def _old_against_polygon(a: np.ndarray, b: np.ndarray,
                         vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For segments ab (S, 2) and a polygon (V, 2): whether each meets its boundary, whether
    its end a is inside, and its distance to the boundary when they do not meet (0 where a
    segment crosses it: the distances are measured only for the others)."""
    c, d = vertices[None], np.roll(vertices, -1, axis=0)[None]
    a2, b2 = a[:, None], b[:, None]
    o1, o2 = _old_orient(a2, b2, c), _old_orient(a2, b2, d)
    o3, o4 = _old_orient(c, d, a2), _old_orient(c, d, b2)
    crossing = ((o1 * o2 < 0) & (o3 * o4 < 0)).any(axis=1)
    distance = np.zeros(len(a))
    rest = ~crossing
    if rest.any():
        a3, b3 = a2[rest], b2[rest]
        distance[rest] = np.minimum.reduce([_old_point_segment(a3, c, d).min(axis=1),
                                            _old_point_segment(b3, c, d).min(axis=1),
                                            _old_point_segment(vertices[None], a3,
                                                               b3).min(axis=1)])
    # A proper crossing, or touching (distance 0: a margin of 0 then still keeps off the
    # boundary). Orientations alone would count any segment on the line through an edge,
    # however far from it, and any hover (a zero-length leg) on such a line.
    meets = crossing | (distance <= 0.0)
    return meets, inside_polygon(a, vertices), distance


def old_segments_clear(zones: Zones, a: np.ndarray, b: np.ndarray, *,
                       margin_m: float | None = None) -> np.ndarray:
    """Whether each segment a[s] b[s] ((S, 2) each) keeps the margin (``margin_m``, the
    zones' own by default) from every zone: exact distances, vectorised (the zones'
    :meth:`~uav_comm_planner.core.zones.Zones.path_clearance` is the slower reference the
    tests use)."""
    a, b = np.atleast_2d(np.asarray(a, float)), np.atleast_2d(np.asarray(b, float))
    margin = zones.margin_m if margin_m is None else margin_m
    edges = max([len(zone.vertices_m) for zone in (*zones.keep_out, zones.area)
                 if zone is not None and not isinstance(zone, KeepOutCircle)], default=1)
    chunk = max(1, CHUNK_PAIRS // edges)
    if len(a) > chunk:
        return np.concatenate([old_segments_clear(zones, a[i:i + chunk], b[i:i + chunk],
                                                  margin_m=margin)
                               for i in range(0, len(a), chunk)])
    ok = np.ones(len(a), dtype=bool)
    for zone in zones.keep_out:
        if isinstance(zone, KeepOutCircle):
            centre = np.array(zone.center_m)[None]
            ok &= _old_point_segment(centre, a, b) >= zone.radius_m + margin
        else:
            meets, inside, distance = _old_against_polygon(a, b, zone.vertices_m)
            ok &= ~meets & ~inside & (distance >= margin)
    if zones.area is not None:
        meets, inside, distance = _old_against_polygon(a, b, zones.area.vertices_m)
        ok &= ~meets & inside & (distance >= margin)
    return ok


def old_shortest_length(zones: Zones, start: np.ndarray, goal: np.ndarray,
                        corners: np.ndarray | None = None) -> float:
    """The length of the shortest path through the reference graph, every pair of
    ``corners`` (the reference's own by default) tested zone by zone (inf: none)."""
    if old_segments_clear(zones, start[None], goal[None])[0]:
        return float(np.linalg.norm(goal - start))
    if corners is None:
        corners = old_graph_corners(zones)
    i, j = np.triu_indices(len(corners), k=1)
    count = len(corners) + 2
    lengths = np.zeros((count, count))
    visible = old_segments_clear(zones, corners[i], corners[j]) if len(i) else \
        np.zeros(0, dtype=bool)
    lengths[2 + i[visible], 2 + j[visible]] = np.linalg.norm(
        corners[j[visible]] - corners[i[visible]], axis=1)
    for row, end in ((0, start), (1, goal)):
        seen = old_segments_clear(zones, np.repeat(end[None], len(corners), axis=0), corners)
        lengths[row, 2:] = np.where(seen, np.linalg.norm(corners - end, axis=1), 0.0)
    return float(dijkstra(csr_matrix(lengths), directed=False, indices=0)[1])


def boxes(count: int, seed: int) -> list[KeepOutPolygon]:
    rng = np.random.default_rng(seed)
    zones = []
    for _ in range(count):
        x, y = rng.uniform(100.0, 1900.0), rng.uniform(-1000.0, 1000.0)
        w, h = rng.uniform(10.0, 120.0, 2)
        zones.append(KeepOutPolygon([(x, y), (x + w, y), (x + w, y + h), (x, y + h)]))
    return zones


def star(points: int, centre=(1000.0, 0.0), outer: float = 300.0,
         inner: float = 150.0) -> KeepOutPolygon:
    angles = np.arange(2 * points) * math.pi / points
    radii = np.where(np.arange(2 * points) % 2 == 0, outer, inner)
    return KeepOutPolygon(np.column_stack([centre[0] + radii * np.cos(angles),
                                           centre[1] + radii * np.sin(angles)]))


def random_zones(seed: int) -> Zones:
    rng = np.random.default_rng(seed + 100)
    zones: list = boxes(int(rng.integers(2, 12)), seed)
    if seed % 3 == 0:
        zones.append(KeepOutCircle((rng.uniform(300, 1700), rng.uniform(-500, 500)),
                                   rng.uniform(20, 200)))
    if seed % 4 == 0:
        zones.append(star(int(rng.integers(3, 9)), (rng.uniform(500, 1500),
                                                    rng.uniform(-300, 300)), 200.0, 80.0))
    area = OperatingArea([(-100, -1200), (2100, -1200), (2100, 1200), (1000, 300),
                          (-100, 1200)]) if seed % 2 else None
    return Zones(area, tuple(zones), margin_m=float(rng.uniform(0.0, 20.0)))


def compare_paths(seed: int, zones: Zones | None = None) -> tuple[int, int, float]:
    """Shortest paths between random points round ``random_zones(seed)`` (or ``zones``), by
    the package and by the reference graph of every pair of the package's corners (the
    reference's own where no zone is wrapped by its hull), never longer than the reference's
    own corners give: (paths compared, paths of equal length, the largest relative excess)."""
    zones = random_zones(seed) if zones is None else zones
    rng = np.random.default_rng(seed)
    compared = equal = 0
    worst = 0.0
    for _ in range(12):
        start, goal = rng.uniform([-50.0, -1000.0], [2050.0, 1000.0], (2, 2))
        if min(zones.clearance([start])[0], zones.clearance([goal])[0]) < zones.margin_m:
            continue
        reference = old_shortest_length(zones, start, goal)
        corners = graph_corners(zones, zones_holding(
            zones, zones.margin_m + GRAPH_CLEARANCE_M, np.array([start, goal])))
        expected = old_shortest_length(zones, start, goal, corners)
        path = shortest_path(zones, start, goal)
        if math.isinf(expected):
            assert path is None and math.isinf(reference)
            continue
        compared += 1
        length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
        assert zones.path_clearance(path) >= zones.margin_m - 1e-9
        # The tangent graph is part of the graph of every pair: never shorter; and its
        # corners (round the hulls of the wrapped zones) give no longer paths than the
        # reference's own.
        assert length >= expected * (1 - 1e-12)
        assert length <= reference * (1 + 2e-5)
        if not wrapped_hulls(zones, zones.margin_m + GRAPH_CLEARANCE_M):
            np.testing.assert_array_equal(corners, old_graph_corners(zones))
        equal += length <= expected * (1 + 1e-12)
        worst = max(worst, length / expected - 1)
    return compared, equal, worst


def test_the_tangent_graph_finds_the_paths_of_the_graph_of_every_pair():
    """Equal where the reference's path wraps round the zones at every bend; where it bends at
    a corner by pushing off it (a graph of discrete corners allows that, shorter by about a
    millimetre or so), at most 2e-5 longer (1e-5 the most seen in 1341 paths)."""
    compared = equal = 0
    worst = 0.0
    for seed in range(40):
        more, same, excess = compare_paths(seed)
        compared, equal, worst = compared + more, equal + same, max(worst, excess)
    print(f'{compared} paths, {equal} of equal length, the others at most {worst:.2e} longer')
    assert compared > 200 and equal >= 0.97 * compared
    assert worst < 2e-5


@pytest.mark.parametrize('make', [lambda: Zones(keep_out=tuple(boxes(12, 5))),
                                  lambda: Zones(keep_out=(star(12),), margin_m=3.0),
                                  lambda: random_zones(1)])
def test_the_visibility_tests_are_the_references(make):
    """Every pair of corners (tangent or not) and random segments: the vectorised test is the
    zone-by-zone reference."""
    zones = make()
    # Every zone with its own corners (none wrapped by its hull): the reference's corners.
    corners = graph_corners(zones, frozenset(range(len(zones.keep_out))))
    np.testing.assert_array_equal(corners, old_graph_corners(zones))
    i, j = np.triu_indices(len(corners), k=1)
    rng = np.random.default_rng(0)
    a = np.vstack([corners[i], rng.uniform([-100, -1100], [2100, 1100], (3000, 2))])
    b = np.vstack([corners[j], rng.uniform([-100, -1100], [2100, 1100], (3000, 2))])
    np.testing.assert_array_equal(segments_clear(zones, a, b), old_segments_clear(zones, a, b))


def graph_seconds(zones: Zones) -> tuple[float, int]:
    """Processor time to build the graph of ``zones`` afresh (the machine is shared: wall time
    counts the other processes too), and its corners."""
    GRAPHS.clear()
    began = time.process_time()
    corners, _ = corner_graph(zones)
    return time.process_time() - began, len(corners)


def test_a_hundred_boxes_and_a_400_vertex_star_build_their_graphs_in_well_under_a_second():
    """400 zone vertices either way: 100 four-vertex boxes took 203 s with the graph of every
    pair, a 400-vertex zone 6.6 s."""
    for zones in (Zones(keep_out=tuple(boxes(100, 1))), Zones(keep_out=(star(200),))):
        seconds, corners = graph_seconds(zones)
        print(f'{sum(len(z.vertices_m) for z in zones.keep_out)} vertices, {corners} corners: '
              f'{seconds:.3f} s')
        assert seconds < 1.0


def test_the_graph_of_many_zones_stops_when_asked_between_chunks():
    zones = Zones(keep_out=tuple(boxes(100, 2)))
    asked = []

    class Stop(Exception):
        pass

    def check() -> None:
        asked.append(time.perf_counter())
        if len(asked) == 3:
            raise Stop
    GRAPHS.clear()
    with pytest.raises(Stop):
        corner_graph(zones, check)
    assert len(asked) == 3 and zones not in GRAPHS


def test_a_thousand_vertex_polygon_is_validated_well_under_a_second():
    angles = np.linspace(0.0, 2 * math.pi, 1000, endpoint=False)
    radii = 300.0 + 60.0 * np.sin(37 * angles)
    ring = np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])
    began = time.process_time()
    KeepOutPolygon(ring)
    assert time.process_time() - began < 0.5
    crossed = ring.copy()
    crossed[[100, 600]] = crossed[[600, 100]]
    with pytest.raises(InvalidScenarioError, match='crosses itself: edges 100 and 601 meet'):
        KeepOutPolygon(crossed)


def old_first_crossing(points: np.ndarray) -> tuple[int, int] | None:
    """The reference: every pair of edges that are not neighbours, one by one."""
    count = len(points)
    for i in range(count):
        for j in range(i + 2, count):
            if i == 0 and j == count - 1:
                continue
            if _segments_cross(points[i], points[(i + 1) % count],
                               points[j], points[(j + 1) % count]):
                return i, j
    return None


def test_the_vectorised_self_crossing_check_finds_the_references_first_crossing():
    rng = np.random.default_rng(0)
    found = 0
    for k in range(300):
        count = int(rng.integers(3, 30))
        # Integer vertices often put vertices on edges and edges on one line.
        points = rng.integers(0, 6, (count, 2)).astype(float) if k % 2 else \
            rng.uniform(0.0, 10.0, (count, 2))
        expected = old_first_crossing(points)
        assert _first_crossing(points) == expected
        found += expected is not None
    assert 100 < found < 300


def old_path_clearance(zones: Zones, path: np.ndarray) -> float:
    """The reference: every segment against every zone, one by one."""
    least = float(np.min(zones.clearance(path)))
    for a, b in zip(path[:-1], path[1:]):
        for zone in (*((zones.area,) if zones.area is not None else ()), *zones.keep_out):
            least = min(least, zone.segment_clearance(a, b))
    return least


@pytest.mark.parametrize('seed', range(0, 24, 3))
def test_a_paths_clearance_is_the_references_measuring_only_the_near_zones(seed):
    zones = random_zones(seed)
    rng = np.random.default_rng(seed)
    for _ in range(6):
        path = rng.uniform([-50.0, -1000.0], [2050.0, 1000.0], (int(rng.integers(2, 12)), 2))
        assert zones.path_clearance(path) == old_path_clearance(zones, path)


def test_a_segment_meets_a_polygons_edges_as_the_pairwise_test_finds():
    rng = np.random.default_rng(1)
    polygon = star(9).vertices_m
    edges = np.roll(polygon, -1, axis=0)
    for _ in range(400):
        a, b = rng.uniform(600.0, 1400.0, (2, 2))
        if rng.random() < 0.3:      # along an edge's line, and through vertices
            k = int(rng.integers(len(polygon)))
            a, b = polygon[k] + rng.uniform(-1, 2) * (edges[k] - polygon[k]), polygon[k]
        expected = any(_segments_cross(a, b, c, d) for c, d in zip(polygon, edges))
        assert _segment_meets_edges(a, b, polygon, edges) == expected
