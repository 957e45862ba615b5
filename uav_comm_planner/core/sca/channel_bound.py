"""The trajectory step's bound for a channel with a line-of-sight probability.

At a fixed altitude h a node's rate in slot m is a function of the horizontal distance
rho = ||q[m] - w_n||: R(rho) = log2(1 + c g(rho) / beta0), c = p_n[m] snr_scale
(:meth:`~uav_comm_planner.core.channel.Channel.rate_and_slope`). The letter's bound is the
tangent of R in s = rho^2, a global lower bound because log2(1 + c / (h^2 + s)) is convex in s.
Al-Hourani's P_LoS(theta) makes R convex in s as well (checked on a dense grid of environments,
altitudes, distances and SNRs: ``test/test_channel.py``), but with a corner above the node:
theta falls like rho, so dR/ds -> -infinity as s -> 0 and the tangent in s, although valid,
becomes useless (and infinite) where the UAV hovers. So the bound is written in rho, about the
expansion point rho_k = ||q^k[m] - w_n||:

    lbr(rho) = R(rho_k) + R'(rho_k) (rho - rho_k) - B (rho - rho_k)^2
             = constant - A rho - B rho^2,    A = -R'(rho_k) - 2 B rho_k,

which equals R and its slope at rho_k (tight). It is below R everywhere exactly when
B >= B* = sup_rho [R(rho_k) + R'(rho_k) (rho - rho_k) - R(rho)] / (rho - rho_k)^2 (the curvature
bound), and it is concave in q when A >= 0 and B >= 0, since rho and rho^2 are convex in q.
A >= 0 holds for B <= -R'(rho_k) / (2 rho_k) = -dR/ds at s_k: that largest B is the letter's
tangent in s (A = 0), itself a global bound by the convexity in s, so B* never exceeds it and
the choice B = min(-dR/ds, max(:data:`CURVATURE_MARGIN` B*, a floor)) is both valid and
concave; the floor (:data:`FLOOR_SHARE`) keeps the bound strongly concave in every slot. B* is the
largest ratio over a grid of rho (:func:`curvature_bound`): every altitude apart, and close to
rho_k, where the ratio tends to -R''(rho_k) / 2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uav_comm_planner.core.channel import Channel
from uav_comm_planner.core.model import snr_scale, squared_horizontal_distances
from uav_comm_planner.core.scenario import Scenario

#: B is this times the grid's largest ratio (a margin for the ratio between grid points; the
#: tests check the bound on grids a hundred times denser).
CURVATURE_MARGIN = 1.02
#: B is at least this share of -R'(rho_k) / (2 max(rho_k, h)) (never above the tangent's).
FLOOR_SHARE = 0.01
#: The grid of rho, in altitudes: from the node out (geometric, and every half degree of
#: elevation, where P_LoS changes: suburban's sigmoid turns within a few degrees), and
#: about rho_k.
_FAR = np.concatenate([[0.0], np.geomspace(1e-4, 1e3, 100),
                       1.0 / np.tan(np.radians(np.arange(0.5, 90.0, 0.5)))])
_NEAR = np.geomspace(1e-5, 2.0, 40)
#: The grid's best points refined, the refinements, and the points of each.
_PEAKS, _REFINE, _REFINE_POINTS = 4, 3, 17
#: Rows of (N, M) handled at once (bounds the memory of the grid to a few megabytes).
_CHUNK = 1024


@dataclass(frozen=True)
class ChannelCoefficients:
    """lbr_{n,m}(q) = constant - linear ||q[m] - w_n|| - weight ||q[m] - w_n||^2 (module
    docstring): each (N, M), bits per use, per metre, per square metre; ``value`` is
    R(rho_k), ``rho`` is rho_k, metres."""

    constant: np.ndarray
    linear: np.ndarray
    weight: np.ndarray
    value: np.ndarray
    rho: np.ndarray

    def at(self, rho: np.ndarray) -> np.ndarray:
        """lbr at horizontal distances rho (N, M) metres."""
        return self.constant - self.linear * rho - self.weight * rho * rho


def _grid(rho_k: np.ndarray, altitude: np.ndarray) -> np.ndarray:
    """(rows, G): the grid of rho for each expansion point rho_k (rows,) at altitudes (rows,)
    metres."""
    far = altitude[:, None] * _FAR[None, :]
    near = rho_k[:, None] + altitude[:, None] * np.concatenate([-_NEAR, _NEAR])[None, :]
    return np.maximum(np.concatenate([far, near], axis=1), 0.0)


def _ratios(channel, h: np.ndarray, rho_k: np.ndarray, c: np.ndarray, value: np.ndarray,
            slope: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """[R_k + R'_k (rho - rho_k) - R(rho)] / (rho - rho_k)^2 for rows of rho (rows, ...) at
    altitudes h (rows,), 0 at rho_k itself."""
    extra = (slice(None),) + (None,) * (rho.ndim - 1)
    rate, _ = channel.rate_and_slope(rho, h[extra], c[extra])
    gap = rho - rho_k[extra]
    apart = np.abs(gap) > 1e-9 * h[extra]
    return np.where(apart, (value[extra] + slope[extra] * gap - rate)
                    / np.where(apart, gap * gap, 1.0), 0.0)


def curvature_bound(channel: Channel, altitude: np.ndarray, rho_k: np.ndarray,
                    c: np.ndarray) -> np.ndarray:
    """B* (rows,) per square metre: the largest [R_k + R'_k (rho - rho_k) - R(rho)] /
    (rho - rho_k)^2 (0 where the tangent is below R), for expansion points rho_k (rows,)
    metres at altitudes (rows,) metres and SNR scales c (rows,).

    The ratio can peak sharply where the tangent almost touches R a second time (suburban's
    steep P_LoS), so the grid's :data:`_PEAKS` best points are refined: :data:`_REFINE` times,
    a grid of :data:`_REFINE_POINTS` between the neighbours of the best point so far.
    """
    altitude = np.broadcast_to(np.asarray(altitude, dtype=float), rho_k.shape)
    out = np.zeros(len(rho_k))
    for first in range(0, len(rho_k), _CHUNK):
        part = slice(first, first + _CHUNK)
        rk, ck, h = rho_k[part], c[part], altitude[part]
        value, slope = channel.rate_and_slope(rk, h, ck)
        rho = np.sort(_grid(rk, h), axis=1)
        ratio = _ratios(channel, h, rk, ck, value, slope, rho)
        best = np.argsort(ratio, axis=1)[:, -_PEAKS:]                 # (rows, K)
        low = np.take_along_axis(rho, np.maximum(best - 1, 0), axis=1)
        high = np.take_along_axis(rho, np.minimum(best + 1, rho.shape[1] - 1), axis=1)
        top = ratio.max(axis=1)
        steps = np.linspace(0.0, 1.0, _REFINE_POINTS)
        for _ in range(_REFINE):
            fine = low[..., None] + (high - low)[..., None] * steps     # (rows, K, P)
            fine_ratio = _ratios(channel, h, rk, ck, value, slope, fine)
            top = np.maximum(top, fine_ratio.max(axis=(1, 2)))
            at = fine_ratio.argmax(axis=2)[..., None]
            width = (high - low) / (_REFINE_POINTS - 1)
            centre = np.take_along_axis(fine, at, axis=2)[..., 0]
            low, high = np.maximum(centre - width, 0.0), centre + width
        out[part] = np.maximum(top, 0.0)
    return out


def channel_coefficients(q_k: np.ndarray, p: np.ndarray,
                         scenario: Scenario) -> ChannelCoefficients:
    """The bound's coefficients at q^k (M, 2) metres for power p (N, M) watts."""
    rho_k = np.sqrt(squared_horizontal_distances(q_k, scenario))
    c = np.asarray(p, dtype=float) * snr_scale(scenario)
    return coefficients_at(scenario.channel_model, rho_k,
                           np.full(rho_k.shape, scenario.altitude_m), c)


def coefficients_at(channel: Channel, rho_k: np.ndarray, altitude: np.ndarray,
                    c: np.ndarray) -> ChannelCoefficients:
    """The bound's coefficients for horizontal distances rho_k, altitudes and SNR scales c
    (arrays of one shape; metres, metres, the SNR at g / beta0 = 1)."""
    value, slope = channel.rate_and_slope(rho_k, altitude, c)
    slope = np.minimum(slope, 0.0)
    # Slots without power have R = 0 everywhere: no curvature to search (water-filling leaves
    # most slots of most nodes empty).
    powered = c.ravel() > 0.0
    curvature = np.zeros(rho_k.size)
    curvature[powered] = CURVATURE_MARGIN * curvature_bound(
        channel, altitude.ravel()[powered], rho_k.ravel()[powered], c.ravel()[powered])
    curvature = curvature.reshape(rho_k.shape)
    # -dR/ds = -R'(rho_k) / (2 rho_k): the letter's tangent in s, the largest concave choice.
    with np.errstate(divide='ignore', invalid='ignore'):
        tangent = np.where(rho_k > 0.0, -slope / (2.0 * rho_k), np.inf)
    # At least a share of the tangent (capped at one altitude out): strongly concave in every
    # slot that carries power, which the step's dual certificate needs.
    floor = FLOOR_SHARE * -slope / (2.0 * np.maximum(rho_k, altitude))
    weight = np.minimum(np.maximum(curvature, floor), tangent)
    linear = np.maximum(-slope - 2.0 * weight * rho_k, 0.0)
    constant = value + linear * rho_k + weight * rho_k * rho_k     # tight at rho_k
    return ChannelCoefficients(constant=constant, linear=linear, weight=weight, value=value,
                               rho=rho_k)


def channel_lower_bound(q: np.ndarray, q_k: np.ndarray, p: np.ndarray,
                        scenario: Scenario) -> np.ndarray:
    """lbr_{n,m}(q) expanded at q^k: (N, M) bits per use, below log2(1 + p a(q))."""
    coefficients = channel_coefficients(q_k, p, scenario)
    return coefficients.at(np.sqrt(squared_horizontal_distances(q, scenario)))


__all__ = ['channel_coefficients', 'channel_lower_bound', 'ChannelCoefficients', 'coefficients_at',
           'CURVATURE_MARGIN', 'curvature_bound', 'FLOOR_SHARE']
