"""Fading in the evaluation: a plan made on the expected gain, judged by Monte Carlo.

A plan's power schedule p_n[m] is fixed in advance on the expected gain (the planner's), so in
flight node n's rate in slot m is log2(1 + p_n[m] N g / (B sigma^2)) with a random gain g. Two
models, each with E[g] the planner's expected gain, so that only the spread differs:

- ``rician``: in each slot each link is in line of sight with probability P_LoS(theta) (the
  channel's own; always under free space), and then fades Rician with factor K (power gain
  |sqrt(K/(K+1)) + sqrt(1/(K+1)) CN(0, 1)|^2 times the line-of-sight gain), otherwise Rayleigh
  (Exp(1) times the non-line-of-sight gain);
- ``rayleigh``: every link Rayleigh about the expected gain (no line-of-sight component).

Draws are independent across slots and nodes (a slot of a second or more spans many coherence
times of the small-scale fading, so this is the pessimistic end: independent draws are what a
slot's own average would smooth). Each draw of the whole horizon gives the nodes' average
throughputs R_n and their minimum; :func:`evaluate_fading` reports the mean of that minimum
over the draws (the ergodic min throughput of a flight), its standard deviation and 5th
percentile, and min_n of the per-node ergodic throughputs E[R_n]. By Jensen's inequality both
are at most the planned min throughput.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from uav_comm_planner.core.model import (LN2, snr_scale, spectral_efficiency_to_rate,
                                         squared_horizontal_distances)
from uav_comm_planner.core.numbers import real_number
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.errors import InvalidScenarioError

FADING_MODELS = ('rician', 'rayleigh')
#: The Rician factor of a line-of-sight link without --rician-k-db: 10 dB.
DEFAULT_K_DB = 10.0
#: Draws, and the most draws x N x M held at once.
DEFAULT_SAMPLES = 1000
MAX_SAMPLES = 100_000
_BATCH_ENTRIES = 2_000_000


@dataclass(frozen=True)
class Fading:
    """``model`` in :data:`FADING_MODELS`; ``k_factor_db`` K of a line-of-sight link;
    ``samples`` draws of the horizon; ``seed`` of the generator (the same seed, the same
    draws)."""

    model: str
    k_factor_db: float = DEFAULT_K_DB
    samples: int = DEFAULT_SAMPLES
    seed: int = 0

    def __post_init__(self) -> None:
        if self.model not in FADING_MODELS:
            raise InvalidScenarioError(f'fading must be one of {", ".join(FADING_MODELS)}, '
                                       f'got {self.model!r}')
        k = real_number('the Rician factor K', self.k_factor_db, 'dB')
        if not (math.isfinite(k) and -30.0 <= k <= 40.0):
            raise InvalidScenarioError(f'the Rician factor K must be in [-30, 40] dB, got {k:g}')
        object.__setattr__(self, 'k_factor_db', k)
        for name, low, high in (('samples', 1, MAX_SAMPLES), ('seed', 0, 2 ** 63 - 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) \
                    or not low <= value <= high:
                raise InvalidScenarioError(f'fading {name} must be an integer from {low} to '
                                           f'{high}, got {value!r}')
            object.__setattr__(self, name, int(value))

    @property
    def k_factor(self) -> float:
        """K, linear."""
        return 10.0 ** (self.k_factor_db / 10.0)


@dataclass(frozen=True)
class FadingEvaluation:
    """``min_throughputs`` (S,) bit/s: min_n R_n of each draw; ``node_ergodic`` (N,) bit/s:
    E[R_n]; ``planned``: the plan's own min throughput on the expected gain."""

    fading: Fading
    min_throughputs: np.ndarray
    node_ergodic: np.ndarray
    planned: float

    @property
    def mean(self) -> float:
        """The ergodic min throughput: the mean over draws of min_n R_n, bit/s."""
        return float(self.min_throughputs.mean())

    @property
    def std(self) -> float:
        return float(self.min_throughputs.std(ddof=1)) if len(self.min_throughputs) > 1 \
            else 0.0

    @property
    def fifth_percentile(self) -> float:
        return float(np.percentile(self.min_throughputs, 5.0))

    @property
    def min_node_ergodic(self) -> float:
        """min_n E[R_n], bit/s."""
        return float(self.node_ergodic.min())

    def to_dict(self) -> dict:
        return {'model': self.fading.model, 'k_factor_db': self.fading.k_factor_db,
                'samples': self.fading.samples, 'seed': self.fading.seed,
                'ergodic_min_throughput': self.mean, 'std': self.std,
                'fifth_percentile': self.fifth_percentile,
                'min_node_ergodic_throughput': self.min_node_ergodic,
                'planned_min_throughput': self.planned}


def power_gains(rng: np.random.Generator, fading: Fading, shape: tuple,
                los: np.ndarray) -> np.ndarray:
    """|h|^2 (shape) with E = 1: Rician(K) where ``los``, Rayleigh elsewhere."""
    scattered = (rng.standard_normal(shape) ** 2 + rng.standard_normal(shape) ** 2) / 2.0
    if fading.model == 'rayleigh':
        return scattered
    k = fading.k_factor
    real = math.sqrt(k / (k + 1.0)) + rng.standard_normal(shape) / math.sqrt(2.0 * (k + 1.0))
    imaginary = rng.standard_normal(shape) / math.sqrt(2.0 * (k + 1.0))
    return np.where(los, real ** 2 + imaginary ** 2, scattered)


def evaluate_fading(q: np.ndarray, p: np.ndarray, scenario: Scenario, fading: Fading,
                    altitudes: np.ndarray | None = None) -> FadingEvaluation:
    """The plan q (M, 2) metres, p (N, M) watts (at ``altitudes`` (M,) metres, None: the
    scenario's) under ``fading`` (module docstring)."""
    if not isinstance(fading, Fading):
        raise InvalidScenarioError(f'fading must be a Fading, got {type(fading).__name__}')
    p = np.asarray(p, dtype=float)
    n_nodes, m = p.shape
    h = np.full(m, scenario.altitude_m) if altitudes is None else np.asarray(altitudes, float)
    s = squared_horizontal_distances(q, scenario)
    p_los, g_los, g_nlos = scenario.channel_model.los_parts(s, h[None, :])
    scale = snr_scale(scenario)
    mean_snr = p * scale * (p_los * g_los + (1.0 - p_los) * g_nlos)
    planned = spectral_efficiency_to_rate(np.log1p(mean_snr).mean(axis=1) / LN2, scenario)
    rng = np.random.default_rng(fading.seed)
    batch = max(1, _BATCH_ENTRIES // (n_nodes * m))
    minima, sums = [], np.zeros(n_nodes)
    for first in range(0, fading.samples, batch):
        count = min(batch, fading.samples - first)
        shape = (count, n_nodes, m)
        if fading.model == 'rayleigh':
            snr = mean_snr * power_gains(rng, fading, shape, np.zeros(shape, dtype=bool))
        else:
            los = rng.random(shape) < p_los
            gain = np.where(los, g_los, g_nlos) * power_gains(rng, fading, shape, los)
            snr = p * scale * gain
        rates = spectral_efficiency_to_rate(np.log1p(snr).mean(axis=2) / LN2, scenario)
        minima.append(rates.min(axis=1))
        sums += rates.sum(axis=0)
    return FadingEvaluation(fading=fading, min_throughputs=np.concatenate(minima),
                            node_ergodic=sums / fading.samples, planned=float(planned.min()))


__all__ = ['DEFAULT_K_DB', 'DEFAULT_SAMPLES', 'evaluate_fading', 'Fading', 'FADING_MODELS',
           'FadingEvaluation', 'MAX_SAMPLES', 'power_gains']
