"""Air-to-ground channels chosen by name: the letter's free space, a path-loss exponent, and
Al-Hourani's line-of-sight probability.

A channel gives the power gain per unit of beta0 (the gain at 1 m) as a function of the
horizontal distance rho from the node and the altitude h; d = sqrt(rho^2 + h^2) is the 3D
distance and theta = atan(h / rho), in degrees, the elevation angle seen from the node:

- ``free-space`` (the letter's): g / beta0 = d^-2;
- ``free-space:alpha=A``: g / beta0 = d^-A, a path-loss exponent A in (0, 10];
- ``los:ENV`` (Al-Hourani, Kandeepan, Lardner, IEEE WCL 2014): the expected gain
  g / beta0 = d^-2 (P_LoS(theta) 10^(-eta_LoS / 10) + (1 - P_LoS(theta)) 10^(-eta_NLoS / 10)),
  P_LoS(theta) = 1 / (1 + a exp(-b (theta - a))), with (a, b, eta_LoS dB, eta_NLoS dB) of
  :data:`ENVIRONMENTS`.

Every one of them decreases with rho at a fixed altitude. For the trajectory step a channel also
gives the rate R(rho) = log2(1 + c g(rho) / beta0) and its derivative in rho
(:meth:`Channel.rate_and_slope`); the bound that keeps the step convex is in
:mod:`uav_comm_planner.core.sca.channel_rates`.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from uav_comm_planner.errors import InvalidChannelError

#: The letter's channel, the default.
FREE_SPACE = 'free-space'
#: Al-Hourani's (a, b, eta_LoS dB, eta_NLoS dB) by environment.
ENVIRONMENTS = {
    'suburban': (4.88, 0.43, 0.1, 21.0),
    'urban': (9.61, 0.16, 1.0, 20.0),
    'dense-urban': (12.08, 0.11, 1.6, 23.0),
    'highrise-urban': (27.23, 0.08, 2.3, 34.0),
}
#: The largest path-loss exponent accepted (beyond it no air-to-ground measurement goes).
MAX_EXPONENT = 10.0
_DEGREES = 180.0 / math.pi
_LN2 = math.log(2.0)


def channel_names() -> tuple[str, ...]:
    """The channels by name ('free-space:alpha=A' for any exponent A besides these)."""
    return (FREE_SPACE,) + tuple(f'los:{env}' for env in ENVIRONMENTS)


@dataclass(frozen=True)
class Channel:
    """One channel (module docstring): ``exponent`` alpha, and ``environment`` (a, b,
    eta_LoS dB, eta_NLoS dB) for a line-of-sight probability, None for free space."""

    name: str
    exponent: float = 2.0
    environment: tuple[float, float, float, float] | None = None

    @property
    def is_letter(self) -> bool:
        """The letter's channel, beta0 / d^2: computed exactly as the letter writes it."""
        return self.environment is None and self.exponent == 2.0

    @property
    def has_cusp(self) -> bool:
        """Whether the gain has a corner above the node (P_LoS falls linearly in rho there),
        so that the trajectory step's bound needs a term in rho, not only in rho^2."""
        return self.environment is not None

    def los_probability(self, theta_deg: np.ndarray) -> np.ndarray:
        """P_LoS(theta), theta in degrees (1 for free space)."""
        if self.environment is None:
            return np.ones_like(np.asarray(theta_deg, dtype=float))
        a, b, _, _ = self.environment
        return 1.0 / (1.0 + a * np.exp(-b * (np.asarray(theta_deg, dtype=float) - a)))

    def _excess(self) -> tuple[float, float]:
        """10^(-eta_LoS / 10) and 10^(-eta_NLoS / 10)."""
        _, _, eta_los, eta_nlos = self.environment
        return 10.0 ** (-eta_los / 10.0), 10.0 ** (-eta_nlos / 10.0)

    def gain(self, squared_horizontal: np.ndarray, altitude: np.ndarray) -> np.ndarray:
        """g / beta0 at squared horizontal distance rho^2 (m^2) and altitude h (m): the gain
        per unit of beta0, m^-alpha (arrays broadcast)."""
        s = np.asarray(squared_horizontal, dtype=float)
        h = np.asarray(altitude, dtype=float)
        d2 = s + h * h
        loss = 1.0 / d2 if self.exponent == 2.0 else d2 ** (-self.exponent / 2.0)
        if self.environment is None:
            return loss
        theta = _DEGREES * np.arctan2(h, np.sqrt(s))
        los = self.los_probability(theta)
        kappa_los, kappa_nlos = self._excess()
        return loss * (kappa_nlos + (kappa_los - kappa_nlos) * los)

    def los_parts(self, squared_horizontal: np.ndarray, altitude: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(P_LoS, g_LoS / beta0, g_NLoS / beta0) with :meth:`gain` = P_LoS g_LoS + (1 - P_LoS)
        g_NLoS: the line-of-sight lottery behind the expected gain (free space: always in
        line of sight, P_LoS = 1)."""
        s = np.asarray(squared_horizontal, dtype=float)
        h = np.asarray(altitude, dtype=float)
        d2 = s + h * h
        loss = 1.0 / d2 if self.exponent == 2.0 else d2 ** (-self.exponent / 2.0)
        if self.environment is None:
            return np.ones_like(loss), loss, loss
        kappa_los, kappa_nlos = self._excess()
        return (self.los_probability(_DEGREES * np.arctan2(h, np.sqrt(s))), loss * kappa_los,
                loss * kappa_nlos)

    def rate_and_slope(self, rho: np.ndarray, altitude: np.ndarray,
                       snr_scale: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """R(rho) = log2(1 + c g(rho) / beta0), bits per use, and dR/drho, per metre, for
        c = ``snr_scale`` (the SNR at g / beta0 = 1), rho horizontal metres, h = ``altitude``
        metres (arrays broadcast; at rho = 0 the slope is the one-sided one, rho -> 0+)."""
        rate, slope, _ = self.rate_gradient(rho, altitude, snr_scale)
        return rate, slope

    def rate_gradient(self, rho: np.ndarray, altitude: np.ndarray, snr_scale: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """R(rho, h) as :meth:`rate_and_slope`, with dR/drho and dR/dh (per metre)."""
        rho = np.asarray(rho, dtype=float)
        h = np.asarray(altitude, dtype=float)
        d2 = rho * rho + h * h
        snr = np.asarray(snr_scale, dtype=float) * self.gain(rho * rho, h)
        # d log g / d rho and d log g / d h: -alpha (rho, h) / d^2, plus the line of sight's.
        log_rho = -self.exponent * rho / d2
        log_h = -self.exponent * h / d2
        if self.environment is not None:
            los = self.los_probability(_DEGREES * np.arctan2(h, rho))
            _, b, _, _ = self.environment
            kappa_los, kappa_nlos = self._excess()
            mean = kappa_nlos + (kappa_los - kappa_nlos) * los
            # dP/dtheta = b P (1 - P); dtheta/drho = -(180/pi) h / d^2, dtheta/dh = (180/pi) rho
            # / d^2.
            per_degree = (kappa_los - kappa_nlos) * b * los * (1.0 - los) / mean * _DEGREES / d2
            log_rho = log_rho - per_degree * h
            log_h = log_h + per_degree * rho
        share = snr / (1.0 + snr) / _LN2
        return np.log1p(snr) / _LN2, share * log_rho, share * log_h


def _exponent(text: str, name: str) -> float:
    key, _, value = text.partition('=')
    if key.strip() != 'alpha' or not value:
        raise InvalidChannelError(
            f"channel {name!r}: free space takes one option, 'alpha=A' (the path-loss exponent)")
    try:
        alpha = float(value)
    except ValueError:
        raise InvalidChannelError(
            f'channel {name!r}: the path-loss exponent must be a number, got {value!r}') from None
    if not (math.isfinite(alpha) and 0.0 < alpha <= MAX_EXPONENT):
        raise InvalidChannelError(
            f'channel {name!r}: the path-loss exponent must be in (0, {MAX_EXPONENT:g}], '
            f'got {alpha:g}')
    return alpha


def parse_channel(name: object) -> Channel:
    """The channel named ``name``: 'free-space', 'free-space:alpha=2.5', 'los:urban', ... (see
    :func:`channel_names`); a :class:`Channel` is returned as it is. InvalidChannelError for
    anything else."""
    if isinstance(name, Channel):
        return name
    if not isinstance(name, str):
        raise InvalidChannelError(f'channel must be a name such as {FREE_SPACE!r} or '
                                  f"'los:urban', got {name!r}")
    text = name.strip().lower()
    kind, _, option = text.partition(':')
    if kind == FREE_SPACE:
        if not option:
            return Channel(FREE_SPACE)
        alpha = _exponent(option, name)
        if alpha == 2.0:
            return Channel(FREE_SPACE)
        shown = f'{alpha:g}' if float(f'{alpha:g}') == alpha else repr(alpha)
        return Channel(f'{FREE_SPACE}:alpha={shown}', exponent=alpha)
    if kind == 'los' and option in ENVIRONMENTS:
        return Channel(f'los:{option}', environment=ENVIRONMENTS[option])
    raise InvalidChannelError(
        f'unknown channel {name!r}: give one of {", ".join(channel_names())} or '
        f"'free-space:alpha=A'")


__all__ = ['Channel', 'channel_names', 'ENVIRONMENTS', 'FREE_SPACE', 'InvalidChannelError',
           'MAX_EXPONENT', 'parse_channel']
