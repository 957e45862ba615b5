"""The fleet's channel and throughput on orthogonal channels, from the letter's model per UAV.

Notation: q (K, M, 2) metres, every UAV's waypoints; p (K, N, M) watts; a (K, N, M) per watt,
a_{k,n}[m] the letter's SNR per watt from UAV k (:func:`~uav_comm_planner.core.model.
snr_per_watt` of UAV k's scenario). Node n's throughput is the sum over the UAVs of the
letter's rate, R_n = (B/N) sum_k mean_m log2(1 + p_{k,n}[m] a_{k,n}[m]).
"""

from __future__ import annotations

import itertools

import numpy as np

from uav_comm_planner.core.fleet.scenario import FleetScenario
from uav_comm_planner.core.model import (snr_per_watt, spectral_efficiencies,
                                         spectral_efficiency_to_rate)


def fleet_snr(q: np.ndarray, fleet: FleetScenario) -> np.ndarray:
    """a (K, N, M) per watt for q (K, M, 2) metres."""
    return np.stack([snr_per_watt(q_k, vehicle) for q_k, vehicle in zip(q, fleet.vehicles)])


def fleet_efficiencies(a: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Per UAV and node, mean_m log2(1 + p a): (K, N) bits per use."""
    return np.stack([spectral_efficiencies(a_k, p_k) for a_k, p_k in zip(a, p)])


def fleet_rates(q: np.ndarray, p: np.ndarray, fleet: FleetScenario) -> np.ndarray:
    """R_n (N,) bit/s: each node's throughput summed over the UAVs."""
    bits = fleet_efficiencies(fleet_snr(q, fleet), p).sum(axis=0)
    return spectral_efficiency_to_rate(bits, fleet.scenario)


def pairwise_distances(q: np.ndarray) -> np.ndarray:
    """||q_j[m] - q_k[m]|| for every pair j < k (in :func:`itertools.combinations` order):
    (pairs, M) metres; (0, M) for one UAV."""
    q = np.asarray(q, dtype=float)
    pairs = list(itertools.combinations(range(q.shape[0]), 2))
    if not pairs:
        return np.zeros((0, q.shape[1]))
    return np.stack([np.linalg.norm(q[j] - q[k], axis=1) for j, k in pairs])


def closest_approach_m(q: np.ndarray) -> float:
    """The least distance between two UAVs over every slot, metres (inf for one UAV)."""
    distances = pairwise_distances(q)
    return float(distances.min()) if distances.size else float('inf')


__all__ = ['closest_approach_m', 'fleet_efficiencies', 'fleet_rates', 'fleet_snr',
           'pairwise_distances']
