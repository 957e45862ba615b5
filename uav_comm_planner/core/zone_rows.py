"""The zones as linear constraints on the slot points: their restriction at the current path.

Keeping out of a disc or a polygon is not convex. At the current path q^k (q0, q^k[1..M],
qF) each leg l, the segment from one path point to the next, is separated from each convex
piece of each zone by a half-plane n . x >= h + level, with n a unit vector, h = max_{y in
piece} n . y the piece's support in direction n, and level the clearance asked for:

- a keep-out circle (centre c, radius r): n points from c to the leg's closest point p* to c,
  h = n . c + r. For a single point this is the letter's restriction
  (q^k - c)^T (q - c) >= (r + margin) ||q^k - c||; for a leg it keeps the whole leg out;
- a convex keep-out polygon: n points from the polygon's closest point to the leg's (the
  closest pair of two disjoint convex sets, so the half-plane is the widest that separates
  them); a non-convex polygon is first cut into convex pieces
  (:meth:`~uav_comm_planner.core.zones.KeepOutPolygon.convex_pieces`);
- the operating area: every slot point stays at least ``level`` inside each edge of its convex
  hull, and out of the hull's pockets as out of keep-out polygons
  (:meth:`~uav_comm_planner.core.zones.OperatingArea.hull_and_pockets`); for a convex area
  these are its edges inset by the margin.

Each leg's half-plane is imposed on both of its ends, so a slot point has two rows per piece
(from the leg before it and the leg after it) and one per hull edge. A half-plane is convex:
with both ends on its safe side the whole leg is, at least ``level`` from the piece, so every
leg keeps ``level`` from every zone, not only the slot points. The rows are linear, hold at
q^k (``level`` is at most the clearance q^k already has: min(margin + cushion, separation))
and imply the zones' constraints: the SCA step stays feasible from its expansion point and
never lowers the objective. Pieces are convex and their union is the zone, so the distance to
the zone is the least distance to its pieces.
"""

from __future__ import annotations

from dataclasses import dataclass
import functools
from typing import Sequence

import numpy as np

from uav_comm_planner.core.zones import (closest_on_segments, convex_pieces, KeepOutCircle,
                                         Zones)

#: The rows ask for this much more than the margin where the current path already has it, so
#: that a conic solver's feasibility tolerance (about 1e-5 m here) never ends below the margin.
ZONE_CUSHION_M = 1e-3


@dataclass(frozen=True)
class ZoneRows:
    """Linear constraints normals[m, k] . q[m] >= offsets[m, k] on the slot points q (M, 2)
    metres: normals (M, K, 2) unit vectors, offsets (M, K) metres."""

    normals: np.ndarray
    offsets: np.ndarray

    def slack(self, q: np.ndarray) -> np.ndarray:
        """normals . q - offsets: (M, K) metres, >= 0 where q keeps the rows."""
        return np.einsum('mkj,mj->mk', self.normals, np.asarray(q, dtype=float)) - self.offsets


@dataclass(frozen=True)
class ZoneModel:
    """The zones as convex pieces, built once per scenario.

    hull_normals (E, 2), hull_offsets (E,): the operating area's hull as n_e . x <= h_e (none
    without an area); centres (C, 2) and radii (C,): the keep-out circles; polygons: convex
    pieces (CCW vertices) of the keep-out polygons and of the area's pockets.
    """

    margin_m: float
    hull_normals: np.ndarray
    hull_offsets: np.ndarray
    centres: np.ndarray
    radii: np.ndarray
    polygons: tuple[np.ndarray, ...]

    @classmethod
    def of(cls, zones: Zones) -> 'ZoneModel':
        circles = [zone for zone in zones.keep_out if isinstance(zone, KeepOutCircle)]
        polygons = [piece for zone in zones.keep_out if not isinstance(zone, KeepOutCircle)
                    for piece in zone.convex_pieces()]
        normals, offsets = np.zeros((0, 2)), np.zeros(0)
        if zones.area is not None:
            hull, pockets = zones.area.hull_and_pockets()
            normals, offsets = _outward_edges(hull)
            polygons += [piece for pocket in pockets for piece in convex_pieces(pocket)]
        return cls(margin_m=zones.margin_m, hull_normals=normals, hull_offsets=offsets,
                   centres=np.array([c.center_m for c in circles], dtype=float).reshape(-1, 2),
                   radii=np.array([c.radius_m for c in circles], dtype=float),
                   polygons=tuple(polygons))

    @functools.cached_property
    def padded_groups(self) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
        """The polygon pieces grouped by size: per group, the pieces' places in
        :attr:`polygons` and the pieces as one array (P, V, 2), each padded to the group's V, a
        power of two, by repeating its last vertex (an edge of length 0 changes no distance
        nor support). A zone's convex core may have hundreds of vertices beside hundreds of
        triangles: padding every piece to the core's size multiplied the work by a hundred."""
        sizes = np.array([len(piece) for piece in self.polygons])
        padded = np.maximum(4, 2 ** np.ceil(np.log2(np.maximum(sizes, 1))).astype(int))
        groups = []
        for most in np.unique(padded):
            index = np.flatnonzero(padded == most)
            groups.append((index, np.stack([
                np.vstack([piece, np.repeat(piece[-1:], most - len(piece), axis=0)])
                for piece in (self.polygons[i] for i in index)])))
        return tuple(groups)

    @property
    def num_pieces(self) -> int:
        return len(self.radii) + len(self.polygons)

    @property
    def rows_per_slot(self) -> int:
        """K: a row per hull edge and two per keep-out piece."""
        return len(self.hull_offsets) + 2 * self.num_pieces

    def pieces_rows_per_slot(self, pieces: int | None) -> int:
        """K with at most ``pieces`` polygon pieces per slot (None: all of them)."""
        chosen = len(self.polygons) if pieces is None else min(pieces, len(self.polygons))
        return len(self.hull_offsets) + 2 * (len(self.radii) + chosen)

    def nearest_rows(self, rows: ZoneRows, points: Sequence[np.ndarray],
                     pieces: int) -> ZoneRows:
        """Of ``rows`` (:meth:`rows`), each slot's hull and circle rows and the rows of the
        ``pieces`` polygon pieces nearest it (least slack of their two rows at any of
        ``points``, slot points (M, 2) each), in the order of :meth:`rows`: (M,
        :meth:`pieces_rows_per_slot`) rows."""
        fixed = len(self.hull_offsets) + 2 * len(self.radii)
        count = len(self.polygons)
        if pieces >= count:
            return rows
        slots = len(points[0])
        slack = np.min([rows.slack(q)[:, fixed:].reshape(slots, count, 2).min(axis=2)
                        for q in points], axis=0)
        nearest = np.sort(np.argpartition(slack, pieces - 1, axis=1)[:, :pieces],
                          axis=1)                                                  # (M, k)
        columns = np.concatenate([np.broadcast_to(np.arange(fixed), (slots, fixed)),
                                  fixed + (2 * nearest[:, :, None] + np.arange(2))
                                  .reshape(slots, -1)], axis=1)
        return ZoneRows(np.take_along_axis(rows.normals, columns[:, :, None], axis=1),
                        np.take_along_axis(rows.offsets, columns, axis=1))

    def rows(self, path: np.ndarray, *, cushion_m: float = ZONE_CUSHION_M) -> ZoneRows:
        """The restriction at the current path q0, q^k[1..M], qF ((M + 2, 2) metres), each
        row asking for min(margin + cushion, the clearance the path has there)."""
        path = np.asarray(path, dtype=float)
        q = path[1:-1]
        wanted = self.margin_m + cushion_m
        normals, offsets = [], []
        if len(self.hull_offsets):
            inside = self.hull_offsets[None, :] - q @ self.hull_normals.T        # (M, E)
            normals.append(np.broadcast_to(-self.hull_normals,
                                           (len(q),) + self.hull_normals.shape))
            offsets.append(-self.hull_offsets[None, :] + np.minimum(wanted, inside))
        a, b = path[:-1], path[1:]
        parts = []
        if len(self.radii):
            parts.append(_circle_half_planes(a, b, self.centres, self.radii))
        if self.polygons:
            parts.append(_grouped_half_planes(a, b, self.padded_groups,
                                              len(self.polygons)))
        for n, support, separation in parts:      # per piece and leg: (P, L, 2), (P, L) twice
            offset = support + np.minimum(wanted, separation)
            # Slot m ends leg m - 1 and starts leg m (legs counted from 0 at q0): its rows
            # are, piece by piece, the leg before it and the leg after it.
            pieces = len(n)
            normals.append(np.stack([n[:, :-1], n[:, 1:]], axis=2).transpose(1, 0, 2, 3)
                           .reshape(len(q), 2 * pieces, 2))
            offsets.append(np.stack([offset[:, :-1], offset[:, 1:]], axis=2).transpose(1, 0, 2)
                           .reshape(len(q), 2 * pieces))
        if not normals:
            return ZoneRows(np.zeros((len(q), 0, 2)), np.zeros((len(q), 0)))
        return ZoneRows(np.concatenate(normals, axis=1), np.concatenate(offsets, axis=1))


def _outward_edges(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A convex CCW polygon as n_e . x <= h_e, n_e its edges' outward unit normals; edges
    of zero length (repeated hull points) left out."""
    edges = np.roll(vertices, -1, axis=0) - vertices
    lengths = np.linalg.norm(edges, axis=1)
    keep = lengths > 0
    normals = np.stack([edges[keep, 1], -edges[keep, 0]], axis=1) / lengths[keep, None]
    return normals, np.einsum('ej,ej->e', normals, vertices[keep])


def _unit(vectors: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """vectors (..., 2) normalised; ``fallback`` (..., 2) unit vectors where one is zero."""
    length = np.linalg.norm(vectors, axis=-1)
    safe = length > 1e-12 * (1.0 + np.abs(vectors).max(initial=0.0))
    unit = vectors / np.where(safe, length, 1.0)[..., None]
    return np.where(safe[..., None], unit, fallback)


def _leg_fallback(a: np.ndarray, b: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """Directions (P, L, 2) for legs that touch or enter a piece (only an infeasible path's
    do): away from the piece's centre (P, 2) through the leg's midpoint, or east."""
    away = (a + b)[None] / 2.0 - centres[:, None, :]
    return _unit(away, np.broadcast_to([1.0, 0.0], away.shape))


def _separation(n: np.ndarray, a: np.ndarray, b: np.ndarray,
                support: np.ndarray) -> np.ndarray:
    """How far the half-planes n . x >= support (P, L) keep the legs ab: min over the ends."""
    return np.minimum(np.einsum('plj,lj->pl', n, a), np.einsum('plj,lj->pl', n, b)) - support


def _circle_half_planes(a: np.ndarray, b: np.ndarray, centres: np.ndarray,
                        radii: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per disc (C) and leg ab (L, 2): the unit normal n from the centre to the leg's closest
    point, the disc's support n . c + r, and the leg's separation from the disc along n."""
    closest = closest_on_segments(centres[:, None, :], a[None], b[None])         # (C, L, 2)
    n = _unit(closest - centres[:, None, :], _leg_fallback(a, b, centres))
    support = np.einsum('clj,cj->cl', n, centres) + radii[:, None]
    return n, support, _separation(n, a, b, support)


def _grouped_half_planes(a: np.ndarray, b: np.ndarray,
                         groups: tuple[tuple[np.ndarray, np.ndarray], ...],
                         count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_polygon_half_planes` of every group of pieces, in the pieces' order."""
    n, support, separation = np.empty((count, len(a), 2)), np.empty((count, len(a))), \
        np.empty((count, len(a)))
    for index, polygons in groups:
        n[index], support[index], separation[index] = _polygon_half_planes(a, b, polygons)
    return n, support, separation


#: Work arrays of the polygons' half-planes hold about this many points at the most.
CHUNK_POINTS = 1_000_000


def _polygon_half_planes(a: np.ndarray, b: np.ndarray,
                         polygons: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per convex polygon (P, V, 2) and leg ab (L, 2): the unit normal from the polygon's
    point closest to the leg to the leg's, the polygon's support max_v n . v, and the
    separation.

    The closest pair of a segment and a convex polygon (apart) is an end of the segment and a
    point of an edge, or a vertex and a point of the segment.
    """
    chunk = max(1, CHUNK_POINTS // (3 * len(a) * polygons.shape[1]))
    if len(polygons) > chunk:
        parts = [_polygon_half_planes(a, b, polygons[i:i + chunk])
                 for i in range(0, len(polygons), chunk)]
        return tuple(np.concatenate(arrays) for arrays in zip(*parts))
    starts, ends = polygons[:, None], np.roll(polygons, -1, axis=1)[:, None]   # (P, 1, V, 2)
    shape = (len(polygons), len(a), polygons.shape[1], 2)
    leg_points, piece_points = [], []
    for end in (a, b):                                   # an end of the leg and each edge
        leg_points.append(np.broadcast_to(end[None, :, None], shape))
        piece_points.append(closest_on_segments(end[None, :, None], starts, ends))
    leg_points.append(closest_on_segments(polygons[:, None], a[None, :, None],
                                          b[None, :, None]))
    piece_points.append(np.broadcast_to(polygons[:, None], shape))
    leg_points = np.concatenate(leg_points, axis=2)                              # (P, L, 3V, 2)
    piece_points = np.concatenate(piece_points, axis=2)
    difference = leg_points - piece_points
    best = np.argmin(np.einsum('plvj,plvj->plv', difference, difference), axis=2)
    nearest = np.take_along_axis(difference, best[..., None, None], axis=2)[:, :, 0]
    n = _unit(nearest, _leg_fallback(a, b, polygons.mean(axis=1)))
    support = np.einsum('plj,pvj->plv', n, polygons).max(axis=2)
    return n, support, _separation(n, a, b, support)


def zone_model(zones: Zones | None) -> ZoneModel | None:
    """The zones' model, or None when there are none (no work is added then)."""
    if zones is None or zones.empty:
        return None
    return _cached_model(zones)


@functools.lru_cache(maxsize=16)
def _cached_model(zones: Zones) -> ZoneModel:
    return ZoneModel.of(zones)


__all__ = ['ZONE_CUSHION_M', 'ZoneModel', 'ZoneRows', 'zone_model']
