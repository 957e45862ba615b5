"""The SCA bound of the trajectory step (letter, problem (11)), and what a step returns.

Around the current trajectory q^k, with d^k_{n,m} = ||q^k[m] - w_n||^2 + H^2 and the SNR
there, snr^k_{n,m} = p_n[m] a_n[m](q^k) = gamma beta0 / d^k, the convexity of
log2(1 + A / (d + x)) in x gives, for x = ||q[m] - w_n||^2 - ||q^k[m] - w_n||^2,

    r_{n,m}(q) >= lbr_{n,m}(q) = log2(1 + snr^k) - snr^k / ((1 + snr^k) ln 2) * x / d^k,

which is the letter's bound, since
gamma beta0 / (d^k (gamma beta0 + d^k)) = snr^k / ((1 + snr^k) d^k).
With a path-loss exponent alpha, snr^k = c (d^k)^(-alpha/2) and the same convexity holds in
x, with the slope alpha / 2 times the above. The bound is global and tight at q^k, so
maximising min_n mean_m lbr_{n,m} subject to the speed limits never lowers the true minimum
rate.

With offsets o_n (N,) bits per use (the data a node already holds, see
:mod:`uav_comm_planner.core.receding`) the step maximises min_n (o_n + mean_m lbr_{n,m}): the
same bound plus a constant per node, still global and tight at q^k.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import functools
from typing import Callable

import numpy as np

from uav_comm_planner.core.model import (leg_lengths, LN2, snr_per_watt, snr_scale,
                                         squared_distances)
from uav_comm_planner.core.sca.channel_bound import channel_lower_bound
from uav_comm_planner.core.scenario import Scenario

#: The conic problems see positions in kilometres: coordinates of order 1, not 1000.
KM = 1000.0


@dataclass(frozen=True)
class SurrogateCoefficients:
    """lbr_{n,m}(q) = value - slope * (||q[m] - w_n||^2 - ||q^k[m] - w_n||^2) / d^k.

    value: log2(1 + snr^k), (N, M) bits per use; slope: snr^k / ((1 + snr^k) ln 2), (N, M);
    d: d^k, (N, M) square metres; horizontal: ||q^k[m] - w_n||^2, (N, M) square metres.
    """

    value: np.ndarray
    slope: np.ndarray
    d: np.ndarray
    horizontal: np.ndarray


def surrogate_coefficients(q_k: np.ndarray, p: np.ndarray,
                           scenario: Scenario) -> SurrogateCoefficients:
    """The SCA bound's coefficients at the expansion point q^k (M, 2) for power p (N, M)."""
    d = squared_distances(q_k, scenario)
    channel = scenario.channel_model
    if channel.has_cusp:
        raise ValueError(f'channel {channel.name}: its bound is channel_coefficients '
                         '(core/sca/channel_bound.py)')
    if channel.is_letter:
        snr = np.asarray(p, dtype=float) * (snr_scale(scenario) / d)
    else:
        snr = np.asarray(p, dtype=float) * snr_per_watt(q_k, scenario)
    # d^-alpha/2 in d: the slope in x / d is alpha / 2 times the letter's (alpha = 2).
    half_exponent = channel.exponent / 2.0
    return SurrogateCoefficients(value=np.log1p(snr) / LN2,
                                 slope=half_exponent * snr / ((1.0 + snr) * LN2),
                                 d=d, horizontal=d - scenario.altitude_m ** 2)


def kilometre_rows(coef: SurrogateCoefficients) -> tuple[np.ndarray, np.ndarray]:
    """The bound in kilometres: mean_m lbr_{n,m}(q) = constant_n - (1/M) sum_m weight_{n,m}
    ||z[m] - w_n||^2 with z = q / 1000 and w_n / 1000 (or both about the same centre).
    Returns weight (N, M), per km^2, and constant (N,), bits per use."""
    # x / d^k is dimensionless, so the slope may be divided by d^k in km^2.
    weight = coef.slope / (coef.d / KM ** 2)
    constant = (coef.value + weight * coef.horizontal / KM ** 2).sum(axis=1) / weight.shape[1]
    return weight, constant


def sca_lower_bound(q: np.ndarray, q_k: np.ndarray, p: np.ndarray,
                    scenario: Scenario) -> np.ndarray:
    """lbr_{n,m}(q) expanded at q^k: (N, M) bits per use, a lower bound of log2(1 + p a(q))
    (the line-of-sight channels' bound: :func:`~uav_comm_planner.core.sca.channel_bound.
    channel_lower_bound`)."""
    if scenario.channel_model.has_cusp:
        return channel_lower_bound(q, q_k, p, scenario)
    coef = surrogate_coefficients(q_k, p, scenario)
    x = squared_distances(q, scenario) - coef.d
    return coef.value - coef.slope * x / coef.d


def with_offsets(constant: np.ndarray, offsets: np.ndarray | None) -> np.ndarray:
    """constant_n + o_n (N,), or ``constant`` itself without offsets."""
    if offsets is None:
        return constant
    return constant + np.asarray(offsets, dtype=float).reshape(-1)


@dataclass(frozen=True)
class TrajectoryStep:
    """q: (M, 2) metres, the maximiser; bound: min_n mean_m lbr_{n,m}(q), bits per use.

    Algorithm 1 judges a step by the true rates, so the bound is evaluated on first use only
    (``bound_of`` computes it).
    """

    q: np.ndarray
    bound_of: Callable[[], float] = field(repr=False, compare=False)

    @functools.cached_property
    def bound(self) -> float:
        return float(self.bound_of())


def path_length_km(q: np.ndarray, scenario: Scenario) -> float:
    """The length of the path q0, q[1..M] (q (M, 2) metres), qF, kilometres."""
    return float(leg_lengths(q, scenario).sum()) / KM


__all__ = ['KM', 'kilometre_rows', 'path_length_km', 'sca_lower_bound', 'surrogate_coefficients',
           'SurrogateCoefficients', 'TrajectoryStep', 'with_offsets']
