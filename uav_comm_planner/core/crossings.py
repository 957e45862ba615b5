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

    def orient(p, q, r):
        return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) \
            - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])

    def on(p, q, r):  # r on segment pq, given collinear
        return ((np.minimum(p[..., 0], q[..., 0]) <= r[..., 0])
                & (r[..., 0] <= np.maximum(p[..., 0], q[..., 0]))
                & (np.minimum(p[..., 1], q[..., 1]) <= r[..., 1])
                & (r[..., 1] <= np.maximum(p[..., 1], q[..., 1])))
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
        o1, o2, o3, o4 = orient(p, q, r), orient(p, q, s), orient(r, s, p), orient(r, s, q)
        meet = (((o1 * o2 < 0) & (o3 * o4 < 0)) | ((o1 == 0) & on(p, q, r))
                | ((o2 == 0) & on(p, q, s)) | ((o3 == 0) & on(r, s, p))
                | ((o4 == 0) & on(r, s, q)))
        if meet.any():
            at = int(np.argmax(meet))        # nonzero lists pairs in row-major order
            return int(rows[ii[at]]), int(jj[at])
    return None


def segment_meets_edges(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> bool:
    """Whether the closed segment ab shares a point with any of the closed segments cd ((E, 2)
    each): ``zones._segments_cross`` for every edge at once."""
    def orient(p, q, r):
        return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) \
            - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])

    def on(p, q, r):  # r on segment pq, given collinear
        return ((np.minimum(p[..., 0], q[..., 0]) <= r[..., 0])
                & (r[..., 0] <= np.maximum(p[..., 0], q[..., 0]))
                & (np.minimum(p[..., 1], q[..., 1]) <= r[..., 1])
                & (r[..., 1] <= np.maximum(p[..., 1], q[..., 1])))
    o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
    meet = (((o1 * o2 < 0) & (o3 * o4 < 0)) | ((o1 == 0) & on(a, b, c))
            | ((o2 == 0) & on(a, b, d)) | ((o3 == 0) & on(c, d, a)) | ((o4 == 0) & on(c, d, b)))
    return bool(meet.any())


__all__ = ['CROSSING_CHUNK_PAIRS', 'first_crossing', 'segment_meets_edges']
