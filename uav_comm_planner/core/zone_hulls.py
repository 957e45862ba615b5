"""Keep-out polygons the paths round the zones may wrap by their convex hulls.

A path that keeps the margin from a zone Z and starts and ends outside its hull grown by the
margin never needs to enter that grown hull when nothing else (no other zone, no edge of the
operating area) lies in it: the hull less the grown zone is a set of pockets, each open to
the outside through one straight lid (an edge of the grown hull), so a path that went into a
pocket came out through the same lid and the lid itself is shorter. Round such a zone the
shortest path is the shortest path round its hull, and the visibility graph
(:func:`~uav_comm_planner.core.detour.corner_graph`) needs only the corners round the hull's
vertices, each with its neighbours along the hull: a 1000-vertex star's teeth then add no
corners in its pockets, and the lines that count as tangent at its corners are the few along
its hull, not nearly all of them (round a tooth's tip nearly every line is tangent).

A zone is taken so (``wrapped``) when it is not convex and its hull keeps
:func:`isolation_m` from every other zone and from the area's edges, the hull inside the
area; a path that starts or ends in such a hull's grown region (:func:`zones_holding`) is
searched with that zone's own corners, as before.
"""

from __future__ import annotations

import functools

import numpy as np

from uav_comm_planner.core.edge_tree import against_edges, EdgeTree, point_segment_distance
from uav_comm_planner.core.zones import (convex_hull, inside_polygon, KeepOutCircle,
                                         KeepOutPolygon, Zones)


def isolation_m(zones: Zones, reach_m: float) -> float:
    """How far (m) the other zones keep from a wrapped zone's hull: twice the corners'
    distance ``reach_m`` from their zone and a metre (as the tangent rule asks of a corner's
    neighbourhood), so that no other zone's corner or margin comes into the grown hull."""
    return 2.0 * reach_m + 1.0


@functools.lru_cache(maxsize=16)
def wrapped_hulls(zones: Zones, reach_m: float) -> dict[int, np.ndarray]:
    """The keep-out polygons that the graph wraps by their hulls: their places in
    ``zones.keep_out`` and their hulls' vertices (H, 2), counter-clockwise."""
    wrapped = {}
    distance = isolation_m(zones, reach_m)
    for number, zone in enumerate(zones.keep_out):
        if isinstance(zone, KeepOutCircle) or zone.convex:
            continue
        hull = zone.vertices_m[convex_hull(zone.vertices_m)]
        others = tuple(other for k, other in enumerate(zones.keep_out) if k != number)
        if _hull_alone(hull, others, zones, distance):
            wrapped[number] = hull
    return wrapped


def _hull_alone(hull: np.ndarray, others: tuple, zones: Zones, distance: float) -> bool:
    """Whether the hull's boundary keeps ``distance`` from every zone of ``others`` and
    from the area's edges, no other zone lies inside it and it lies inside the area."""
    a, b = hull, np.roll(hull, -1, axis=0)
    circles = [zone for zone in others if isinstance(zone, KeepOutCircle)]
    polygons = [zone.vertices_m for zone in others if isinstance(zone, KeepOutPolygon)]
    inner = [np.array(zone.center_m) for zone in circles] + [vertices[0] for vertices in
                                                             polygons]
    if inner and inside_polygon(np.array(inner), hull).any():
        return False
    for zone in circles:
        centre = np.array(zone.center_m)[None]
        if point_segment_distance(centre, a, b).min() < zone.radius_m + distance:
            return False
    boundaries = [polygons] if polygons else []
    if zones.area is not None:
        area = zones.area.vertices_m
        if not inside_polygon(hull[:1], area)[0]:
            return False
        boundaries.append([area])
    for rings in boundaries:
        meets, apart = against_edges(a, b, EdgeTree.of_rings(rings), distance)
        if meets.any() or apart.min() < distance:
            return False
    return True


def zones_holding(zones: Zones, reach_m: float, points: np.ndarray) -> frozenset[int]:
    """The wrapped zones (:func:`wrapped_hulls` with ``reach_m``) whose hull grown by the
    margin holds one of ``points`` (K, 2) inside it: a path from there may need the zone's own
    corners (from a point on that grown hull or beyond, none does)."""
    points = np.atleast_2d(np.asarray(points, dtype=float))
    holding = set()
    for number, hull in wrapped_hulls(zones, reach_m).items():
        ring = point_segment_distance(points[:, None], hull, np.roll(hull, -1, axis=0))
        if (ring.min(axis=1) < zones.margin_m).any() or inside_polygon(points, hull).any():
            holding.add(number)
    return frozenset(holding)


__all__ = ['isolation_m', 'wrapped_hulls', 'zones_holding']
