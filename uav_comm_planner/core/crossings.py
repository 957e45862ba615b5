"""Whether segments share a point, vectorised: a polygon's first pair of crossing edges (its
self-crossing check) and whether a segment meets any of a polygon's edges. Closed segments:
touching counts, as a vertex on an edge and edges along one line that overlap do."""

from __future__ import annotations

import numpy as np


#: Edge pairs the self-crossing check tests at once (bounds its work arrays' memory).
CROSSING_CHUNK_PAIRS = 1_000_000


def first_crossing(points: np.ndarray) -> tuple[int, int] | None:
    """The first pair of edges i < j (edge k from vertex k to k + 1, the last one closing
    the polygon; in the order i, then j) that are not neighbours and share a point, as
    ``zones._segments_cross`` finds it; None for a simple polygon. Vectorised over the pairs,
    in blocks of rows."""
    count = len(points)
    a, b = points, np.roll(points, -1, axis=0)
    columns = np.arange(count)
    rows_per_block = max(1, CROSSING_CHUNK_PAIRS // count)

    for first in range(0, count, rows_per_block):
        rows = np.arange(first, min(first + rows_per_block, count))
        i, j = rows[:, None], columns[None, :]
        valid = (j >= i + 2) & ~((i == 0) & (j == count - 1))   # not neighbours
        p, q, r, s = a[rows][:, None], b[rows][:, None], a[None], b[None]
        # Only edge pairs whose bounding boxes meet can share a point.
        valid &= ((np.minimum(p[..., 0], q[..., 0]) <= np.maximum(r[..., 0], s[..., 0]))
                  & (np.minimum(r[..., 0], s[..., 0]) <= np.maximum(p[..., 0], q[..., 0]))
                  & (np.minimum(p[..., 1], q[..., 1]) <= np.maximum(r[..., 1], s[..., 1]))
                  & (np.minimum(r[..., 1], s[..., 1]) <= np.maximum(p[..., 1], q[..., 1])))
        if not valid.any():
            continue
        ii, jj = np.nonzero(valid)
        p, q, r, s = a[rows[ii]], b[rows[ii]], a[jj], b[jj]
        meet = _segments_meet(p, q, r, s)
        if meet.any():
            at = int(np.argmax(meet))        # nonzero lists pairs in row-major order
            return int(rows[ii[at]]), int(jj[at])
    return None


def segment_meets_edges(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> bool:
    """Whether the closed segment ab shares a point with any of the closed segments cd ((E, 2)
    each): ``zones._segments_cross`` for every edge at once."""
    return bool(_segments_meet(a, b, c, d).any())


def _orient(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The sign of the turn p -> q -> r (twice the signed area), elementwise over (..., 2)."""
    return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) \
        - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])


def _on(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """r within the box of segment pq (on it, given the three are collinear)."""
    return ((np.minimum(p[..., 0], q[..., 0]) <= r[..., 0])
            & (r[..., 0] <= np.maximum(p[..., 0], q[..., 0]))
            & (np.minimum(p[..., 1], q[..., 1]) <= r[..., 1])
            & (r[..., 1] <= np.maximum(p[..., 1], q[..., 1])))


def _segments_meet(p: np.ndarray, q: np.ndarray, r: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Whether the closed segments pq and rs share a point, elementwise (broadcast)."""
    o1, o2, o3, o4 = _orient(p, q, r), _orient(p, q, s), _orient(r, s, p), _orient(r, s, q)
    return (((o1 * o2 < 0) & (o3 * o4 < 0)) | ((o1 == 0) & _on(p, q, r))
            | ((o2 == 0) & _on(p, q, s)) | ((o3 == 0) & _on(r, s, p))
            | ((o4 == 0) & _on(r, s, q)))


__all__ = ['CROSSING_CHUNK_PAIRS', 'first_crossing', 'segment_meets_edges']
