"""Where the UAV may fly: an operating area it stays inside and keep-out zones it stays out of.

All in the planning frame (east-north metres, like :class:`~uav_comm_planner.core.scenario.
Scenario`). An :class:`OperatingArea` is a simple polygon the whole flight stays inside; a
:class:`KeepOutCircle` and a :class:`KeepOutPolygon` are places it must not enter. A
:class:`Zones` holds them with the clearance ``margin_m`` every point of the flight keeps from
their edges. Polygons are given as their vertices in order (either orientation; stored
counter-clockwise), without repeating the first vertex.

This module holds the geometry only: validation, and the exact distance of a point or a
segment to each zone, which the planner's constraints and the tests that check its plans use.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Union

import numpy as np
from numpy.typing import ArrayLike

from uav_comm_planner.core.crossings import first_crossing as _first_crossing
from uav_comm_planner.core.crossings import segment_meets_edges as _segment_meets_edges
from uav_comm_planner.core.numbers import real_number
from uav_comm_planner.errors import InvalidScenarioError, SelfCrossingError

#: Vertices a polygon zone may have at most (a fence vertex is one MAVLink item).
MAX_POLYGON_VERTICES = 1000
#: Keep-out zones a set of zones may hold at most, and polygon vertices in all (the area's
#: included): the paths round them are built from every zone's corners.
MAX_KEEP_OUT_ZONES = 200
MAX_TOTAL_VERTICES = 4000
#: A zone's coordinates and a circle's radius, metres from the planning frame's origin, at most
#: (the scenario's own bound: beyond 10 000 km they leave the Earth).
MAX_ZONE_EXTENT_M = 1.0e7


def _numbers_only(value: ArrayLike) -> bool:
    """Whether every entry of ``value`` is a real number: an int or a float (numpy's too),
    never a bool or a string, which NumPy would read as 1.0 or parse (``True``, ``'12'``)."""
    if isinstance(value, np.ndarray) and value.dtype.kind in 'iuf':
        return True
    try:
        entries = np.array(value, dtype=object).ravel()
    except (TypeError, ValueError):
        return False
    return all(isinstance(v, (int, float, np.integer, np.floating))
               and not isinstance(v, (bool, np.bool_)) for v in entries)


def _finite_points(name: str, vertices: ArrayLike) -> np.ndarray:
    if not _numbers_only(vertices):
        raise InvalidScenarioError(f'{name} must be a list of (x, y) vertices in metres, '
                                   f'got {_short(vertices)}')
    try:
        points = np.array(vertices, dtype=float)
    except OverflowError:
        raise InvalidScenarioError(f'{name} has a vertex beyond a double: '
                                   f'{_short(vertices)}') from None
    except (TypeError, ValueError):
        raise InvalidScenarioError(f'{name} must be a list of (x, y) vertices in metres, '
                                   f'got {_short(vertices)}') from None
    if points.ndim != 2 or points.shape[1] != 2 or not 3 <= len(points) <= MAX_POLYGON_VERTICES:
        raise InvalidScenarioError(
            f'{name} must have 3 to {MAX_POLYGON_VERTICES} (x, y) vertices, got shape '
            f'{points.shape}')
    if not np.isfinite(points).all():
        raise InvalidScenarioError(f'{name} has a vertex that is not finite')
    if np.abs(points).max() > MAX_ZONE_EXTENT_M:
        raise InvalidScenarioError(
            f'{name} has a vertex {np.abs(points).max():g} m from the origin, farther than '
            f'{MAX_ZONE_EXTENT_M:g} m: zones are metres from a local origin')
    return points


def _short(value: object, limit: int = 80) -> str:
    """``repr(value)`` cut to ``limit`` characters, for a one-line error."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit] + '...'


def _segments_cross(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> bool:
    """Whether the closed segments ab and cd share a point."""
    def orient(p, q, r):
        return float((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]))

    def on(p, q, r):  # r on segment pq, given collinear
        return min(p[0], q[0]) <= r[0] <= max(p[0], q[0]) and \
            min(p[1], q[1]) <= r[1] <= max(p[1], q[1])

    o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
    if o1 * o2 < 0 and o3 * o4 < 0:
        return True
    return (o1 == 0 and on(a, b, c)) or (o2 == 0 and on(a, b, d)) or \
        (o3 == 0 and on(c, d, a)) or (o4 == 0 and on(c, d, b))


def crossing_message(name: str, first: int, second: int, numbering: str = '') -> str:
    """What a refusal of a polygon that crosses itself says: its 0-based edges ``first`` and
    ``second`` meet (``numbering``: how they are numbered, if not the polygon's own way)."""
    return (f'{name} crosses itself: edges {first + 1} and {second + 1} meet{numbering}; give '
            f'the vertices in order around the boundary')


def _simple_polygon(name: str, vertices: ArrayLike) -> np.ndarray:
    """The vertices, counter-clockwise, of a simple polygon with a positive area."""
    points = _finite_points(name, vertices)
    crossing = _first_crossing(points)
    if crossing is not None:
        raise SelfCrossingError(crossing_message(name, *crossing), crossing)
    area = 0.5 * float(np.sum(points[:, 0] * np.roll(points[:, 1], -1)
                              - np.roll(points[:, 0], -1) * points[:, 1]))
    scale = float(np.ptp(points, axis=0).max())
    if abs(area) <= 1e-12 * max(scale, 1.0) ** 2:
        raise InvalidScenarioError(f'{name} has no area: its vertices are collinear or repeated')
    if area < 0:
        points = points[::-1].copy()
    return points


def closest_on_segments(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The closest point of each segment a b to each point (arrays (..., 2), broadcasting)."""
    ab = b - a
    length2 = np.einsum('...j,...j->...', ab, ab)
    t = np.einsum('...j,...j->...', points - a, ab) / np.where(length2 > 0, length2, 1.0)
    return a + np.clip(t, 0.0, 1.0)[..., None] * ab


def _point_segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of each of ``points`` (K, 2) to the segment ab."""
    ab = b - a
    length2 = float(ab @ ab)
    t = np.zeros(len(points)) if length2 == 0 else np.clip((points - a) @ ab / length2, 0, 1)
    return np.linalg.norm(points - (a + t[:, None] * ab), axis=1)


def inside_polygon(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Even-odd rule: whether each of ``points`` (K, 2) lies strictly inside the polygon."""
    x, y = points[:, 0][:, None], points[:, 1][:, None]
    x0, y0 = vertices[:, 0], vertices[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    straddles = (y0 > y) != (y1 > y)
    with np.errstate(divide='ignore', invalid='ignore'):
        crossing = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return (np.count_nonzero(straddles & (x < crossing), axis=1) % 2) == 1


def _boundary_distance(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    edges = zip(vertices, np.roll(vertices, -1, axis=0))
    return np.min([_point_segment_distance(points, a, b) for a, b in edges], axis=0)


def _polygon_signed_distance(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Distance to the polygon's boundary, negative inside it."""
    distance = _boundary_distance(points, vertices)
    return np.where(inside_polygon(points, vertices), -distance, distance)


#: Points a segment that meets a polygon's boundary is sampled at for its deepest point.
SEGMENT_SAMPLES = 257


def _segment_polygon_distance(a: np.ndarray, b: np.ndarray, vertices: np.ndarray) -> float:
    """Signed distance of segment ab to a polygon: the least distance when they are apart,
    minus the depth of the segment's deepest point when any part of it is inside (0 when it
    only touches the boundary)."""
    meets = _segment_meets_edges(a, b, vertices, np.roll(vertices, -1, axis=0))
    if not meets:
        ends = _polygon_signed_distance(np.array([a, b]), vertices)
        if (ends < 0).any():  # wholly inside
            t = np.linspace(0.0, 1.0, SEGMENT_SAMPLES)[:, None]
            return float(_polygon_signed_distance(a + t * (b - a), vertices).min())
        # Apart: the nearest points are a vertex of one and a point of the other.
        return float(min(_point_segment_distance(vertices, a, b).min(), ends.min()))
    t = np.linspace(0.0, 1.0, SEGMENT_SAMPLES)[:, None]
    return float(min(_polygon_signed_distance(a + t * (b - a), vertices).min(), 0.0))


@dataclass(frozen=True)
class KeepOutCircle:
    """A disc the flight must not enter: centre (east, north) metres and radius metres."""

    center_m: tuple[float, float]
    radius_m: float
    #: Where the zone came from, as its file gave it (a fence's latitude and longitude), so
    #: that it is written back as it was read; not compared.
    source: object = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        try:
            center = np.array(self.center_m, dtype=float)
        except (TypeError, ValueError, OverflowError):
            center = np.array([math.nan])
        if not _numbers_only(self.center_m):
            center = np.array([math.nan])
        if center.shape != (2,) or not np.isfinite(center).all():
            raise InvalidScenarioError(f'a keep-out circle\'s centre must be a finite (x, y) '
                                       f'in metres, got {_short(self.center_m)}')
        radius = real_number('a keep-out circle\'s radius', self.radius_m, 'metres')
        if not (math.isfinite(radius) and radius > 0):
            raise InvalidScenarioError(
                f'a keep-out circle\'s radius must be positive and finite, got '
                f'{_short(self.radius_m)}')
        if max(np.abs(center).max(), radius) > MAX_ZONE_EXTENT_M:
            raise InvalidScenarioError(
                f'a keep-out circle (centre ({center[0]:g}, {center[1]:g}) m, radius '
                f'{radius:g} m) reaches beyond {MAX_ZONE_EXTENT_M:g} m from the origin: zones '
                f'are metres from a local origin')
        object.__setattr__(self, 'center_m', (float(center[0]), float(center[1])))
        object.__setattr__(self, 'radius_m', radius)

    def clearance(self, points: ArrayLike) -> np.ndarray:
        """Distance of each point (K, 2) outside the circle; negative inside."""
        points = np.atleast_2d(np.asarray(points, dtype=float))
        return np.linalg.norm(points - np.array(self.center_m), axis=1) - self.radius_m

    def segment_clearance(self, a: ArrayLike, b: ArrayLike) -> float:
        """The least clearance along the segment ab."""
        centre = np.array([self.center_m])
        distance = _point_segment_distance(centre, np.asarray(a, float), np.asarray(b, float))
        return float(distance[0]) - self.radius_m


class _Polygon:
    """What a polygon zone does with its vertices: validated as a simple polygon, stored
    counter-clockwise and read-only, compared and hashed by value (so that scenarios holding
    zones compare and hash as dataclasses do). ``what`` names it in errors; ``source`` is
    where it came from, as its file gave it (a fence's latitude and longitude), written back
    as it was read and not compared."""

    what = 'a polygon'
    vertices_m: np.ndarray

    def __post_init__(self) -> None:
        vertices = _simple_polygon(self.what, self.vertices_m)
        vertices.setflags(write=False)
        object.__setattr__(self, 'vertices_m', vertices)

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and np.array_equal(self.vertices_m, other.vertices_m)

    def __hash__(self) -> int:
        return hash((type(self).__name__, self.vertices_m.tobytes()))

    @property
    def convex(self) -> bool:
        return _is_convex(self.vertices_m)


@dataclass(frozen=True, eq=False)
class KeepOutPolygon(_Polygon):
    """A simple polygon the flight must not enter (vertices east-north metres, stored CCW)."""

    what = 'a keep-out polygon'
    vertices_m: np.ndarray
    source: object = field(default=None, compare=False, repr=False)

    def convex_pieces(self) -> list[np.ndarray]:
        """Convex polygons (CCW vertices) whose union is this one: itself when convex, else its
        ear-clipping triangles joined while convex. A point's distance to the polygon is the
        least of its distances to the pieces."""
        return convex_pieces(self.vertices_m)

    def clearance(self, points: ArrayLike) -> np.ndarray:
        points = np.atleast_2d(np.asarray(points, dtype=float))
        return _polygon_signed_distance(points, self.vertices_m)

    def segment_clearance(self, a: ArrayLike, b: ArrayLike) -> float:
        return _segment_polygon_distance(np.asarray(a, float), np.asarray(b, float),
                                         self.vertices_m)


@dataclass(frozen=True, eq=False)
class OperatingArea(_Polygon):
    """A simple polygon the whole flight stays inside (vertices east-north metres, CCW)."""

    what = 'the operating area'
    vertices_m: np.ndarray
    source: object = field(default=None, compare=False, repr=False)

    def hull_and_pockets(self) -> tuple[np.ndarray, list[np.ndarray]]:
        """The area's convex hull (CCW vertices) and its pockets, the polygons between the hull
        and the area (none for a convex area): the area is the hull less the pockets, and its
        boundary lies on the hull's edges and the pockets' boundaries, so a point in the hull
        at least d from the hull's edges and at least d outside every pocket is in the area,
        at least d from its boundary."""
        vertices = self.vertices_m
        hull = convex_hull(vertices)
        pockets = []
        for i, j in zip(hull, hull[1:] + [hull[0] + len(vertices)]):
            if j - i > 1:
                pockets.append(np.array([vertices[k % len(vertices)] for k in range(i, j + 1)]))
        # The pocket runs i, i+1, ..., j along the area (clockwise about the pocket): reverse.
        return vertices[hull], [pocket[::-1].copy() for pocket in pockets]

    def clearance(self, points: ArrayLike) -> np.ndarray:
        """Distance of each point inside the area from its boundary; negative outside."""
        points = np.atleast_2d(np.asarray(points, dtype=float))
        return -_polygon_signed_distance(points, self.vertices_m)

    def segment_clearance(self, a: ArrayLike, b: ArrayLike) -> float:
        """The least clearance inside the area along the segment ab; negative where it leaves."""
        return -_segment_polygon_distance_outside(np.asarray(a, float), np.asarray(b, float),
                                                  self.vertices_m)


def _segment_polygon_distance_outside(a: np.ndarray, b: np.ndarray,
                                      vertices: np.ndarray) -> float:
    """How far the segment ab gets from being wholly inside the polygon: minus its least
    distance to the boundary when it is inside, the depth of its farthest point outside when
    any part of it is outside (0 when it only touches)."""
    meets = _segment_meets_edges(a, b, vertices, np.roll(vertices, -1, axis=0))
    ends = _polygon_signed_distance(np.array([a, b]), vertices)
    if not meets and (ends < 0).all():
        inside = min(float(_point_segment_distance(vertices, a, b).min()), -float(ends.max()))
        return -inside
    t = np.linspace(0.0, 1.0, SEGMENT_SAMPLES)[:, None]
    return float(max(_polygon_signed_distance(a + t * (b - a), vertices).max(), 0.0))


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def ear_triangles(vertices: np.ndarray) -> list[tuple[int, int, int]]:
    """A simple polygon's vertices (V, 2), counter-clockwise, cut into V - 2 triangles (vertex
    indices, CCW) by ear clipping: a convex vertex whose triangle with its neighbours holds no
    other vertex is cut off, until three are left. Every simple polygon has an ear (two, when
    V > 3); the search goes on from the last ear cut, so a polygon takes O(V^2) tests."""
    points = np.asarray(vertices, dtype=float)
    left = list(range(len(points)))
    triangles = []
    scale = float(np.ptp(points, axis=0).max()) ** 2
    k = 0
    while len(left) > 3:
        count = len(left)
        for attempt in range(count):
            at = (k + attempt) % count
            corner = (left[at - 1], left[at], left[(at + 1) % count])
            a, b, c = points[list(corner)]
            if _cross(a, b, c) <= 1e-14 * scale:
                continue                      # reflex or flat: not an ear
            others = points[[v for v in left if v not in corner]]
            inside = ((_cross_many(a, b, others) >= 0) & (_cross_many(b, c, others) >= 0)
                      & (_cross_many(c, a, others) >= 0))
            if not inside.any():
                break
        else:                                 # round-off on a near-degenerate polygon
            at = max(range(count), key=lambda i: _cross(
                *points[[left[i - 1], left[i], left[(i + 1) % count]]]))
            corner = (left[at - 1], left[at], left[(at + 1) % count])
        triangles.append(corner)
        del left[at]
        k = max(at - 1, 0)
    triangles.append(tuple(left))
    return triangles


def _cross_many(o: np.ndarray, a: np.ndarray, points: np.ndarray) -> np.ndarray:
    return (a[0] - o[0]) * (points[:, 1] - o[1]) - (a[1] - o[1]) * (points[:, 0] - o[0])


def convex_hull(vertices: np.ndarray) -> list[int]:
    """Indices of the polygon's vertices on its convex hull (collinear ones included), in
    the polygon's (CCW) order."""
    order = sorted(range(len(vertices)), key=lambda i: (vertices[i][0], vertices[i][1]))
    hull: list[int] = []
    for sweep in (order, order[::-1]):
        start = len(hull)
        for i in sweep:
            # Collinear points stay: a pocket then never has an edge along the hull's.
            while len(hull) >= start + 2 and _cross(vertices[hull[-2]], vertices[hull[-1]],
                                                    vertices[i]) < 0:
                hull.pop()
            hull.append(i)
        hull.pop()
    return sorted(set(hull))


def merge_convex(vertices: np.ndarray,
                 pieces: list[tuple[int, ...]]) -> list[np.ndarray]:
    """Join convex CCW pieces of a polygon (vertex indices, sharing whole edges, as ear
    clipping leaves them) across each shared edge in turn while the union stays convex
    (Hertel and Mehlhorn: at most four times the fewest convex pieces): fewer pieces, so
    fewer constraints, the same set. Returns each piece's vertices (K, 2)."""
    points = np.asarray(vertices, dtype=float)
    owner: dict[tuple[int, int], int] = {}
    polygons: dict[int, list[int]] = {}
    for number, piece in enumerate(pieces):
        polygons[number] = list(piece)
        for i, j in zip(piece, piece[1:] + piece[:1]):
            owner[(i, j)] = number
    for (i, j), first in list(owner.items()):
        second = owner.get((j, i))
        if second is None or first == second or owner.get((i, j)) != first:
            continue
        union = _join(polygons[first], polygons[second], i, j)
        if not _is_convex(points[union]):
            continue
        for a, b in zip(polygons[second], polygons[second][1:] + polygons[second][:1]):
            owner[(a, b)] = first
        del owner[(i, j)], owner[(j, i)]
        polygons[first] = union
        del polygons[second]
    return [points[piece] for piece in polygons.values()]


def convex_pieces(vertices: np.ndarray) -> list[np.ndarray]:
    """A simple CCW polygon (V, 2) as convex CCW polygons whose union it is: itself when convex,
    else its ear-clipping triangles joined while convex."""
    if _is_convex(vertices):
        return [np.array(vertices, dtype=float)]
    return merge_convex(vertices, ear_triangles(vertices))


def _join(first: list[int], second: list[int], i: int, j: int) -> list[int]:
    """The polygon of two CCW polygons (vertex indices) across their shared edge: (i, j) in
    ``first``, (j, i) in ``second``."""
    at = first.index(j)
    around_first = first[at:] + first[:at]               # j ... i
    at = second.index(i)
    around_second = second[at:] + second[:at]            # i ... j
    return around_first + around_second[1:-1]


def _is_convex(vertices: np.ndarray) -> bool:
    edges = np.roll(vertices, -1, axis=0) - vertices
    turns = edges[:, 0] * np.roll(edges[:, 1], -1) - edges[:, 1] * np.roll(edges[:, 0], -1)
    return bool((turns >= -1e-12 * float(np.abs(edges).max()) ** 2).all())


KeepOut = Union[KeepOutCircle, KeepOutPolygon]


def _bounding_box(zone: KeepOut) -> np.ndarray:
    """A keep-out zone's bounding box, [[x low, y low], [x high, y high]] metres."""
    if isinstance(zone, KeepOutCircle):
        centre = np.array(zone.center_m)
        return np.array([centre - zone.radius_m, centre + zone.radius_m])
    return np.array([zone.vertices_m.min(axis=0), zone.vertices_m.max(axis=0)])


@dataclass(frozen=True)
class Zones:
    """The operating area (None: anywhere) and the keep-out zones, with the clearance
    ``margin_m`` the flight keeps from every edge."""

    area: OperatingArea | None = None
    keep_out: tuple[KeepOut, ...] = ()
    margin_m: float = 5.0

    def __post_init__(self) -> None:
        keep_out = tuple(self.keep_out)
        for zone in keep_out:
            if not isinstance(zone, (KeepOutCircle, KeepOutPolygon)):
                raise InvalidScenarioError(
                    f'a keep-out zone must be a KeepOutCircle or KeepOutPolygon, got '
                    f'{type(zone).__name__}')
        if self.area is not None and not isinstance(self.area, OperatingArea):
            raise InvalidScenarioError(
                f'the operating area must be an OperatingArea, got {type(self.area).__name__}')
        margin = real_number('the zone margin', self.margin_m, 'metres')
        if not (math.isfinite(margin) and margin >= 0):
            raise InvalidScenarioError(
                f'the zone margin must be >= 0 and finite, got {self.margin_m!r} m')
        if len(keep_out) > MAX_KEEP_OUT_ZONES:
            raise InvalidScenarioError(
                f'{len(keep_out)} keep-out zones given, more than {MAX_KEEP_OUT_ZONES}: merge '
                f'neighbouring zones')
        vertices = sum(len(zone.vertices_m) for zone in (self.area, *keep_out)
                       if isinstance(zone, (OperatingArea, KeepOutPolygon)))
        if vertices > MAX_TOTAL_VERTICES:
            raise InvalidScenarioError(
                f'the zones have {vertices} polygon vertices in all, more than '
                f'{MAX_TOTAL_VERTICES}: simplify them')
        object.__setattr__(self, 'keep_out', keep_out)
        object.__setattr__(self, 'margin_m', margin)

    @property
    def empty(self) -> bool:
        return self.area is None and not self.keep_out

    def clearance(self, points: ArrayLike) -> np.ndarray:
        """Each point's least clearance from every zone (inf with no zones); a point keeps
        the margin where this is >= margin_m."""
        points = np.atleast_2d(np.asarray(points, dtype=float))
        least = np.full(len(points), np.inf)
        for zone in (*((self.area,) if self.area is not None else ()), *self.keep_out):
            least = np.minimum(least, zone.clearance(points))
        return least

    def path_clearance(self, path: ArrayLike) -> float:
        """The least clearance along the polyline ``path`` (K, 2), segments included."""
        path = np.atleast_2d(np.asarray(path, dtype=float))
        least = float(np.min(self.clearance(path))) if len(path) else math.inf
        a, b = path[:-1], path[1:]
        if not len(a):
            return least
        if self.area is not None:
            for start, end in zip(a, b):
                least = min(least, self.area.segment_clearance(start, end))
        if not self.keep_out:
            return least
        # A segment's clearance from a keep-out zone is at least the gap between their
        # bounding boxes when those are apart: only the pairs whose gap is below the least
        # clearance found so far are measured, nearest first (the same least clearance).
        low_s, high_s = np.minimum(a, b), np.maximum(a, b)
        boxes = np.array([_bounding_box(zone) for zone in self.keep_out])    # (Z, 2, 2)
        low_z, high_z = boxes[:, 0], boxes[:, 1]
        gaps = np.maximum(np.maximum(low_z[None] - high_s[:, None], low_s[:, None] - high_z[None]),
                          0.0)
        gap = np.hypot(gaps[..., 0], gaps[..., 1])
        gap[gap == 0.0] = -math.inf     # boxes that meet: the segment may enter the zone
        order = np.argsort(gap, axis=None)
        for flat in order:
            segment, zone = np.unravel_index(flat, gap.shape)
            if gap[segment, zone] >= least:
                break
            least = min(least, self.keep_out[zone].segment_clearance(a[segment], b[segment]))
        return least

    def to_dict(self) -> dict:
        """A JSON-ready form: {'area': [[x, y], ...] or None, 'keep_out': [{'center_m': [x,
        y], 'radius_m': r} or {'vertices_m': [[x, y], ...]}, ...], 'margin_m': m}."""
        def zone(item: KeepOut) -> dict:
            if isinstance(item, KeepOutCircle):
                return {'center_m': list(item.center_m), 'radius_m': item.radius_m}
            return {'vertices_m': item.vertices_m.tolist()}
        return {'area': None if self.area is None else self.area.vertices_m.tolist(),
                'keep_out': [zone(item) for item in self.keep_out], 'margin_m': self.margin_m}

    @classmethod
    def from_dict(cls, data: object) -> 'Zones':
        """The zones of :meth:`to_dict`'s form; InvalidScenarioError for anything else."""
        if not isinstance(data, dict) or not set(data) <= {'area', 'keep_out', 'margin_m'}:
            raise InvalidScenarioError(
                f"zones must be a mapping of 'area', 'keep_out' and 'margin_m', got "
                f'{_short(data)}')
        items = data.get('keep_out', [])
        if not isinstance(items, (list, tuple)):
            raise InvalidScenarioError(f"zones' keep_out must be a list, got {_short(items)}")
        if len(items) > MAX_KEEP_OUT_ZONES:
            raise InvalidScenarioError(f"zones' keep_out holds {len(items)} zones, more than "
                                       f'{MAX_KEEP_OUT_ZONES}')
        keep_out = []
        for item in items:
            if isinstance(item, dict) and set(item) == {'center_m', 'radius_m'}:
                keep_out.append(KeepOutCircle(item['center_m'], item['radius_m']))
            elif isinstance(item, dict) and set(item) == {'vertices_m'}:
                keep_out.append(KeepOutPolygon(item['vertices_m']))
            else:
                raise InvalidScenarioError(
                    f"a keep-out zone is {{'center_m', 'radius_m'}} or {{'vertices_m'}}, got "
                    f'{_short(item)}')
        area = data.get('area')
        return cls(area=None if area is None else OperatingArea(area),
                   keep_out=tuple(keep_out), margin_m=data.get('margin_m', 5.0))


__all__ = ['crossing_message', 'KeepOut', 'KeepOutCircle', 'KeepOutPolygon', 'MAX_KEEP_OUT_ZONES',
           'MAX_POLYGON_VERTICES', 'MAX_TOTAL_VERTICES', 'MAX_ZONE_EXTENT_M',
           'OperatingArea', 'Zones']
