"""The letter's channel and throughput model (Section II), vectorised over nodes and slots.

Notation: q (M, 2) waypoints in metres, w (N, 2) ground nodes in metres, p (N, M) watts.
"""

from __future__ import annotations

import math

import numpy as np

from uav_comm_planner.core.scenario import Scenario


#: ln 2: log2(1 + x) is computed as log1p(x) / LN2, exact to the last digits even when x is tiny.
LN2 = math.log(2.0)


def squared_distances(q: np.ndarray, scenario: Scenario) -> np.ndarray:
    """d_n[m] = ||q[m] - w_n||^2 + H^2: (N, M) square metres."""
    q = np.asarray(q, dtype=float).reshape(-1, 2)
    w = scenario.nodes
    # Per axis on (N, M) arrays: half the time of a sum over a trailing axis of two.
    dx = q[:, 0] - w[:, :1]
    dy = q[:, 1] - w[:, 1:]
    dx *= dx
    dy *= dy
    dx += dy
    dx += scenario.altitude_m ** 2
    return dx


def snr_scale(scenario: Scenario) -> float:
    """N beta0 / (B sigma^2): the SNR per watt at a gain of beta0 (at 1 m in free space)."""
    return scenario.num_nodes * scenario.reference_gain / (
        scenario.bandwidth_hz * scenario.noise_psd_w_per_hz)


def snr_per_watt(q: np.ndarray, scenario: Scenario) -> np.ndarray:
    """a_n[m] = N g_n[m] / (B sigma^2): (N, M) per watt (OFDMA, B/N per node), with the
    scenario's channel gain g_n[m]: the letter's beta0 / d_n[m] under 'free-space'
    (:mod:`uav_comm_planner.core.channel` for the others)."""
    channel = scenario.channel_model
    if channel.is_letter:
        return snr_scale(scenario) / squared_distances(q, scenario)
    return snr_at(squared_horizontal_distances(q, scenario), scenario)


def squared_horizontal_distances(q: np.ndarray, scenario: Scenario) -> np.ndarray:
    """||q[m] - w_n||^2: (N, M) square metres."""
    q = np.asarray(q, dtype=float).reshape(-1, 2)
    w = scenario.nodes
    return (q[:, 0] - w[:, :1]) ** 2 + (q[:, 1] - w[:, 1:]) ** 2


def snr_at(squared_horizontal: np.ndarray, scenario: Scenario) -> np.ndarray:
    """The SNR per watt at squared horizontal distances rho^2 (m^2, any shape) from a node,
    at the scenario's altitude and channel: snr_scale g / beta0."""
    return snr_scale(scenario) * scenario.channel_model.gain(squared_horizontal,
                                                             scenario.altitude_m)


def best_snr_per_watt(scenario: Scenario) -> float:
    """a_max, the SNR per watt right above a node: every channel's gain falls with the
    horizontal distance at a fixed altitude (N beta0 / (H^2 B sigma^2) in free space)."""
    if scenario.channel_model.is_letter:
        return snr_scale(scenario) / scenario.altitude_m ** 2
    return float(snr_at(0.0, scenario))


def spectral_efficiency_to_rate(bits_per_use: np.ndarray, scenario: Scenario) -> np.ndarray:
    """R = (B / N) * mean over slots of log2(1 + SNR): the average throughput in bit/s.

    (1/T) sum_m delta (B/N) log2(...) equals (B/N) times the mean over the M slots, because
    delta / T = 1 / M: the time-weighted form of the letter's eq. (3).
    """
    return scenario.bandwidth_hz / scenario.num_nodes * bits_per_use


def spectral_efficiencies(a: np.ndarray, p: np.ndarray,
                          offsets: np.ndarray | None = None) -> np.ndarray:
    """o_n + mean_m log2(1 + p_n[m] a_n[m]): (N,) bits per channel use, for a and p (N, M)
    (or (..., N) for a stack of them, (..., N, M)).

    ``offsets`` o (N,) bits per use are the data a node already holds (the receding horizon,
    :mod:`uav_comm_planner.core.receding`); without them o = 0, the letter's rates.
    """
    bits = np.log1p(np.asarray(p, dtype=float) * a).sum(axis=-1) / (LN2 * a.shape[-1])
    return bits if offsets is None else bits + offsets


def average_rates(q: np.ndarray, p: np.ndarray, scenario: Scenario,
                  offsets: np.ndarray | None = None) -> np.ndarray:
    """R_n = (B/N) (o_n + mean_m log2(1 + p_n[m] a_n[m])): (N,) bit/s, the average throughput
    of each node over the horizon (o = 0 without ``offsets``)."""
    return spectral_efficiency_to_rate(
        spectral_efficiencies(snr_per_watt(q, scenario), p, offsets), scenario)


def min_rate(q: np.ndarray, p: np.ndarray, scenario: Scenario) -> float:
    """min_n R_n, bit/s: the letter's objective."""
    return float(average_rates(q, p, scenario).min())


def flown_path(q: np.ndarray, scenario: Scenario) -> np.ndarray:
    """q0, q[1], ..., q[M], qF: (M + 2, 2) metres."""
    return np.vstack([scenario.start_m, np.asarray(q, dtype=float).reshape(-1, 2),
                      scenario.goal_m])


def legs(q: np.ndarray, scenario: Scenario) -> np.ndarray:
    """q[1] - q0, q[m] - q[m-1], qF - q[M]: the M + 1 legs, (M + 1, 2) metres."""
    return np.diff(flown_path(q, scenario), axis=0)


def vector_lengths(vectors: np.ndarray, axis: int) -> np.ndarray:
    """Euclidean lengths along ``axis`` (as :func:`numpy.linalg.norm`, without its checks:
    for the loops that measure many small arrays)."""
    return np.sqrt((vectors * vectors).sum(axis=axis))


def leg_lengths(q: np.ndarray, scenario: Scenario) -> np.ndarray:
    """||q[1] - q0||, ||q[m] - q[m-1]||, ||qF - q[M]||: (M + 1,) metres."""
    return np.linalg.norm(legs(q, scenario), axis=1)


def speeds(q: np.ndarray, scenario: Scenario) -> np.ndarray:
    """Speed on each of the M + 1 legs: (M + 1,) m/s."""
    return leg_lengths(q, scenario) / scenario.slot_s
