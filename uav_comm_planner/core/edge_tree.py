"""Which zone edges come near which segments: a tree of boxes over the edges, walked for many
segments at once.

The visibility graph round the zones (:mod:`~uav_comm_planner.core.detour`) tests hundreds of
thousands of corner-to-corner segments against thousands of zone edges; comparing every
segment's box with every edge's box is that product of comparisons, most of them for edges
far away. The edges of a polygon, in their order round it, lie next to each other: runs of
:data:`LEAF_EDGES` consecutive edges make compact boxes, pairs of runs make their parents, up
to a root that holds them all. A segment is taken down only into the boxes (grown by the
margin) that it comes near, one level of the tree at a time for all segments together, so
the work grows with the edges near each segment and the tree's depth, not with all edges.

A segment comes near a box when their boxes overlap and the box, grown by the margin, is
not wholly on one side of the segment's line beyond the margin (the separating axes of a
segment and a box). Both are conservative: every edge within the margin of a segment is
found, and some farther ones, which the exact tests that follow measure.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator, Sequence

import numpy as np

from uav_comm_planner.core.zones import closest_on_segments

#: Consecutive edges under one leaf of the tree.
LEAF_EDGES = 8
#: With at most this many edges every segment's box is compared with every edge's instead.
DENSE_EDGES = 512
#: Where the empty leaves' boxes stand (zones are within 1e7 m of the origin).
FAR_M = 1e300
#: (segment, box) pairs taken down one level at once (bounds the work arrays' memory).
CHUNK_PAIRS = 500_000


@dataclass(frozen=True)
class EdgeTree:
    """Boxes over edges c[e] d[e] (E, 2): ``levels[0]`` the root's (1, 4), ``levels[-1]`` the
    leaves' (2^depth, 4) as (x_low, y_low, x_high, y_high); leaf k holds edges
    k * LEAF_EDGES .. (k + 1) * LEAF_EDGES - 1 (fewer in the last), empty leaves an empty box
    at :data:`FAR_M`, which no segment comes near."""

    starts: np.ndarray
    ends: np.ndarray
    levels: tuple[np.ndarray, ...]

    @classmethod
    def of(cls, starts: np.ndarray, ends: np.ndarray) -> 'EdgeTree':
        count = len(starts)
        leaves = max(1, -(-count // LEAF_EDGES))
        width = 1 << (leaves - 1).bit_length()
        boxes = np.empty((width, 4))
        boxes[:] = FAR_M
        padded = np.full((leaves * LEAF_EDGES, 4), np.nan)
        padded[:count, :2] = np.minimum(starts, ends)
        padded[:count, 2:] = np.maximum(starts, ends)
        padded = padded.reshape(leaves, LEAF_EDGES, 4)
        if count:
            boxes[:leaves, :2] = np.nanmin(padded[..., :2], axis=1)
            boxes[:leaves, 2:] = np.nanmax(padded[..., 2:], axis=1)
        levels = [boxes]
        while len(levels[-1]) > 1:
            below = levels[-1].reshape(-1, 2, 4)
            levels.append(np.concatenate([below[:, :, :2].min(axis=1),
                                          below[:, :, 2:].max(axis=1)], axis=1))
        return cls(starts, ends, tuple(levels[::-1]))

    @classmethod
    def of_rings(cls, rings: Sequence[np.ndarray]) -> 'EdgeTree':
        """The tree of the closed polygons' edges (each (V, 2), edge k from vertex k to
        k + 1), the polygons in the order of their centres along a Z-order curve, so that
        the tree's upper boxes hold neighbouring polygons, not polygons from all over."""
        if not rings:
            return cls.of(np.zeros((0, 2)), np.zeros((0, 2)))
        centres = np.array([ring.mean(axis=0) for ring in rings])
        order = np.argsort(_z_order(centres), kind='stable')
        return cls.of(np.vstack([rings[k] for k in order]),
                      np.vstack([np.roll(rings[k], -1, axis=0) for k in order]))

    def near_pairs(self, a: np.ndarray, b: np.ndarray,
                   margin: float) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """(segment, edge) index arrays of every edge within ``margin`` of segment a[s] b[s]
        (S, 2) each (and some farther), in parts of at most about :data:`CHUNK_PAIRS`."""
        if not len(self.starts) or not len(a):
            return
        # Round-off in the separating axes never drops a pair that touches: a little more.
        margin = margin + 1e-9 * (1.0 + max(np.abs(a).max(), np.abs(b).max(),
                                            np.abs(self.starts).max()))
        if len(self.starts) <= DENSE_EDGES:
            yield from self._every_box(a, b, margin)
            return
        rows = max(1, CHUNK_PAIRS // 4)
        for first in range(0, len(a), rows):
            segment = np.arange(first, min(first + rows, len(a)))
            yield from self._descend(a, b, margin, segment, np.zeros(len(segment), dtype=int),
                                     0)

    def _every_box(self, a: np.ndarray, b: np.ndarray,
                   margin: float) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """The pairs whose boxes, the edge's grown by the margin, overlap: every segment's box
        against every edge's, for few edges (the tree's walk costs more there)."""
        low_s, high_s = np.minimum(a, b), np.maximum(a, b)
        low_e = np.minimum(self.starts, self.ends) - margin
        high_e = np.maximum(self.starts, self.ends) + margin
        rows = max(1, CHUNK_PAIRS // len(self.starts))
        for first in range(0, len(a), rows):
            part = slice(first, first + rows)
            near = ((low_s[part, None, 0] <= high_e[None, :, 0])
                    & (high_s[part, None, 0] >= low_e[None, :, 0])
                    & (low_s[part, None, 1] <= high_e[None, :, 1])
                    & (high_s[part, None, 1] >= low_e[None, :, 1]))
            segment, edge = np.nonzero(near)
            yield segment + first, edge

    def _descend(self, a: np.ndarray, b: np.ndarray, margin: float, segment: np.ndarray,
                 node: np.ndarray, level: int) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """The pairs under (segment, node) pairs at ``level`` whose boxes the segments come
        near; a level's pairs past :data:`CHUNK_PAIRS` are taken down in parts."""
        for first in range(0, len(segment), CHUNK_PAIRS):
            part_segment = segment[first:first + CHUNK_PAIRS]
            part_node = node[first:first + CHUNK_PAIRS]
            near = _segments_near_boxes(a[part_segment], b[part_segment],
                                        self.levels[level][part_node], margin)
            part_segment, part_node = part_segment[near], part_node[near]
            if not len(part_segment):
                continue
            if level + 1 < len(self.levels):
                yield from self._descend(a, b, margin, np.repeat(part_segment, 2),
                                         (2 * part_node[:, None] + np.arange(2)).ravel(),
                                         level + 1)
                continue
            edges = (part_node[:, None] * LEAF_EDGES + np.arange(LEAF_EDGES)).ravel()
            segments = np.repeat(part_segment, LEAF_EDGES)
            real = edges < len(self.starts)
            segments, edges = segments[real], edges[real]
            # Each edge's own box, as the leaves' were tested.
            boxes = np.hstack([np.minimum(self.starts[edges], self.ends[edges]),
                               np.maximum(self.starts[edges], self.ends[edges])])
            near = _segments_near_boxes(a[segments], b[segments], boxes, margin)
            yield segments[near], edges[near]


def _z_order(points: np.ndarray) -> np.ndarray:
    """Each point's place (K,) on the Z-order curve over their bounding box, 16 bits a
    coordinate."""
    low, high = points.min(axis=0), points.max(axis=0)
    cells = ((points - low) / np.where(high > low, high - low, 1.0) * 65535).astype(np.uint64)
    code = np.zeros(len(points), dtype=np.uint64)
    for bit in range(16):
        for axis in range(2):
            code |= ((cells[:, axis] >> np.uint64(bit)) & np.uint64(1)) \
                << np.uint64(2 * bit + axis)
    return code


def _segments_near_boxes(a: np.ndarray, b: np.ndarray, boxes: np.ndarray,
                         margin: float) -> np.ndarray:
    """Whether segment a[k] b[k] comes near box k (each (K, 2), (K, 4)) by the separating
    axes x, y and the segment's normal, the box grown by ``margin``."""
    low, high = boxes[:, :2] - margin, boxes[:, 2:] + margin
    overlap = ((np.minimum(a, b) <= high) & (np.maximum(a, b) >= low)).all(axis=1)
    direction = b - a
    normal = np.stack([-direction[:, 1], direction[:, 0]], axis=1)
    length = np.hypot(normal[:, 0], normal[:, 1])
    centre, half = (low + high) / 2.0, (high - low) / 2.0
    # The box's reach along the normal against the centre's distance from the line.
    reach = np.abs(normal[:, 0]) * half[:, 0] + np.abs(normal[:, 1]) * half[:, 1]
    offset = np.abs(np.einsum('kj,kj->k', normal, centre - a))
    return overlap & (offset <= reach + margin * length)


def _orient(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) \
        - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])


def point_segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances of points to segments ab, broadcasting over leading axes."""
    return np.linalg.norm(points - closest_on_segments(points, a, b), axis=-1)


def against_edges(a: np.ndarray, b: np.ndarray, tree: EdgeTree,
                  margin: float) -> tuple[np.ndarray, np.ndarray]:
    """For segments ab (S, 2) each and the edges of ``tree``: whether each segment meets an
    edge, and its least distance to them when it meets none (0 where it does; inf where no
    edge comes within ``margin`` of it: only the segment-edge pairs the tree finds near are
    measured)."""
    c, d = tree.starts, tree.ends
    meets = np.zeros(len(a), dtype=bool)
    distance = np.full(len(a), np.inf)
    for segment, edge in tree.near_pairs(a, b, margin):
        a2, b2, c2, d2 = a[segment], b[segment], c[edge], d[edge]
        o1, o2 = _orient(a2, b2, c2), _orient(a2, b2, d2)
        o3, o4 = _orient(c2, d2, a2), _orient(c2, d2, b2)
        crossing = (o1 * o2 < 0) & (o3 * o4 < 0)
        meets[segment[crossing]] = True
        # Distances only for the segments that cross no edge (the others are out already).
        keep = ~meets[segment]
        segment, a2, b2, c2, d2 = segment[keep], a2[keep], b2[keep], c2[keep], d2[keep]
        apart = np.minimum.reduce([point_segment_distance(a2, c2, d2),
                                   point_segment_distance(b2, c2, d2),
                                   point_segment_distance(c2, a2, b2),
                                   point_segment_distance(d2, a2, b2)])
        np.minimum.at(distance, segment, apart)
    # A proper crossing, or touching (distance 0: a margin of 0 then still keeps off the
    # boundary). Orientations alone would count any segment on the line through an edge,
    # however far from it, and any hover (a zero-length leg) on such a line.
    meets |= distance <= 0.0
    distance[meets] = 0.0
    return meets, distance


__all__ = ['EdgeTree', 'LEAF_EDGES', 'against_edges', 'point_segment_distance']
