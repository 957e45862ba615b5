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

    @property
    def num_pieces(self) -> int:
        return len(self.radii) + len(self.polygons)

    @property
    def rows_per_slot(self) -> int:
        """K: a row per hull edge and two per keep-out piece."""
        return len(self.hull_offsets) + 2 * self.num_pieces

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
        separations = [_circle_half_plane(a, b, c, r) for c, r in zip(self.centres, self.radii)]
        separations += [_polygon_half_plane(a, b, piece) for piece in self.polygons]
        for n, support, separation in separations:          # per leg: (L, 2), (L,), (L,)
            offset = support + np.minimum(wanted, separation)
            # Slot m ends leg m - 1 and starts leg m (legs counted from 0 at q0).
            normals += [n[:-1, None, :], n[1:, None, :]]
            offsets += [offset[:-1, None], offset[1:, None]]
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
    """vectors (L, 2) normalised; ``fallback`` (L, 2) unit vectors where one is zero."""
    length = np.linalg.norm(vectors, axis=1)
    safe = length > 1e-12 * (1.0 + np.abs(vectors).max(initial=0.0))
    unit = vectors / np.where(safe, length, 1.0)[:, None]
    return np.where(safe[:, None], unit, fallback)


def _leg_fallback(a: np.ndarray, b: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """A direction for a leg that touches or enters a piece (only an infeasible path does):
    away from the piece's centre through the leg's midpoint, or east."""
    return _unit((a + b) / 2.0 - centre, np.tile([1.0, 0.0], (len(a), 1)))


def _separation(n: np.ndarray, a: np.ndarray, b: np.ndarray,
                support: np.ndarray) -> np.ndarray:
    """How far the half-plane n . x >= support keeps the leg ab: min over its ends."""
    return np.minimum(np.einsum('lj,lj->l', n, a), np.einsum('lj,lj->l', n, b)) - support


def _circle_half_plane(a: np.ndarray, b: np.ndarray, centre: np.ndarray,
                       radius: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per leg ab (L, 2): the unit normal n from the centre to the leg's closest point, the
    disc's support n . c + r, and the leg's separation from the disc along n."""
    closest = closest_on_segments(centre[None, :], a, b)
    n = _unit(closest - centre, _leg_fallback(a, b, centre))
    support = n @ centre + radius
    return n, support, _separation(n, a, b, support)


def _polygon_half_plane(a: np.ndarray, b: np.ndarray,
                        vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per leg ab (L, 2) and a convex polygon (V, 2): the unit normal from the polygon's point
    closest to the leg to the leg's, the polygon's support max_v n . v, and the separation.

    The closest pair of a segment and a convex polygon (apart) is an end of the segment and a
    point of an edge, or a vertex and a point of the segment.
    """
    starts, ends = vertices, np.roll(vertices, -1, axis=0)
    candidates_leg, candidates_piece = [], []
    for end in (a, b):                                   # an end of the leg and each edge
        on_edge = closest_on_segments(end[:, None, :], starts[None], ends[None])   # (L, V, 2)
        candidates_leg.append(np.broadcast_to(end[:, None, :], on_edge.shape))
        candidates_piece.append(on_edge)
    on_leg = closest_on_segments(vertices[None], a[:, None, :], b[:, None, :])    # (L, V, 2)
    candidates_leg.append(on_leg)
    candidates_piece.append(np.broadcast_to(vertices[None], on_leg.shape))
    leg_points = np.concatenate(candidates_leg, axis=1)
    piece_points = np.concatenate(candidates_piece, axis=1)
    gaps = np.linalg.norm(leg_points - piece_points, axis=2)
    best = np.argmin(gaps, axis=1)
    rows = np.arange(len(a))
    n = _unit(leg_points[rows, best] - piece_points[rows, best],
              _leg_fallback(a, b, vertices.mean(axis=0)))
    support = (n @ vertices.T).max(axis=1)
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
