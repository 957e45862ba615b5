"""The separation rows: every pair of UAVs at least d_min apart in every slot, kept convex.

||q_j[m] - q_k[m]|| >= d_min is not convex. For any direction a != 0, Cauchy-Schwarz gives
||q_j - q_k|| ||a|| >= a^T (q_j - q_k), so the linear row

    a^T (q_j[m] - q_k[m]) >= d_min ||a||

implies it: a convex restriction (Wu, Zeng, Zhang 2018, as the zones' rows are). With a the
current difference q_j^k[m] - q_k^k[m] (the tangent at the current point) the current point
keeps the row whenever it keeps the separation (a^T a = ||a||^2 >= d_min ||a||), so an SCA
step from a separated point stays feasible and never lowers the objective. The rows ask for
:data:`SEPARATION_CUSHION_M` more than d_min, so that a solver's answer keeps d_min itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uav_comm_planner.core.fleet.scenario import FleetScenario

#: Metres the rows ask beyond d_min: far above a conic solver's tolerance on positions in
#: kilometres (1e-8 km), far below anything a vehicle resolves.
SEPARATION_CUSHION_M = 1e-3


@dataclass(frozen=True)
class SeparationRows:
    """a^T (q_j[m] - q_k[m]) >= rhs for every pair (j, k) of ``pairs`` and slot m.

    direction: a (P, M, 2), unit vectors; rhs: (P, M) in the same units as q (d_min plus the
    cushion, as ||a|| = 1).
    """

    pairs: tuple[tuple[int, int], ...]
    direction: np.ndarray
    rhs: np.ndarray

    def slack(self, q: np.ndarray) -> np.ndarray:
        """a^T (q_j - q_k) - rhs (P, M) for q (K, M, 2) in the rows' units."""
        if not self.pairs:
            return np.zeros((0, q.shape[1]))
        j, k = (np.array(side) for side in zip(*self.pairs))
        return (self.direction * (q[j] - q[k])).sum(axis=-1) - self.rhs


def unit_directions(q: np.ndarray, pairs: tuple[tuple[int, int], ...],
                    fallback: np.ndarray | None = None) -> np.ndarray:
    """(q_j[m] - q_k[m]) / ||.|| (P, M, 2) for q (K, M, 2); where two UAVs coincide, the unit
    vector of ``fallback`` (P, M, 2) there (None: east)."""
    if not pairs:
        return np.zeros((0, q.shape[1], 2))
    j, k = (np.array(side) for side in zip(*pairs))
    difference = q[j] - q[k]
    length = np.linalg.norm(difference, axis=-1, keepdims=True)
    if fallback is None:
        fallback = np.broadcast_to(np.array([1.0, 0.0]), difference.shape)
    fallback_length = np.linalg.norm(fallback, axis=-1, keepdims=True)
    spare = np.where(fallback_length > 0.0, fallback / np.maximum(fallback_length, 1e-300),
                     np.array([1.0, 0.0]))
    return np.where(length > 0.0, difference / np.maximum(length, 1e-300), spare)


def separation_rows(q: np.ndarray, fleet: FleetScenario, scale: float = 1.0,
                    fallback: np.ndarray | None = None) -> SeparationRows:
    """The rows linearised at q (K, M, 2), in units of ``scale`` metres (1000: kilometres)."""
    pairs = fleet.pairs
    rhs = (fleet.min_separation_m + SEPARATION_CUSHION_M) / scale
    return SeparationRows(pairs=pairs, direction=unit_directions(q, pairs, fallback),
                          rhs=np.full((len(pairs), q.shape[1]), rhs))


def keeps_separation(q: np.ndarray, fleet: FleetScenario) -> bool:
    """Whether every pair of UAVs of q (K, M, 2) metres is at least d_min apart in every
    slot (exactly: no tolerance)."""
    if not fleet.pairs:
        return True
    j, k = (np.array(side) for side in zip(*fleet.pairs))
    return bool(np.linalg.norm(q[j] - q[k], axis=-1).min() >= fleet.min_separation_m)


__all__ = ['keeps_separation', 'SEPARATION_CUSHION_M', 'separation_rows', 'SeparationRows',
           'unit_directions']
