"""An :class:`~uav_comm_planner.core.propulsion.Airframe` fitted to measured power.

Samples of (airspeed V m/s, vertical speed v_z m/s, power W), steady flight only, are fitted by
least squares (scipy's bounded trust-region reflective method, from a few starts) to
``Airframe.power_w(V, v_z)``: P0, Pi, U_tip, v0 and d0 of Zeng 2019 eq. (12) and the climb and
descent coefficients. rho, s and A are held at fixed values (:data:`FIXED_CONSTANTS`): the
formula holds them only in the product d0 rho s A, which d0 takes up, so that power alone
cannot tell them apart. A climb (or descent) coefficient is fitted only when samples climb (or
descend) at :data:`MIN_VERTICAL_MPS` or faster; otherwise it stays 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize

from uav_comm_planner.core.propulsion import Airframe
from uav_comm_planner.errors import InvalidScenarioError

#: rho (kg/m^3, sea level), rotor solidity s and disc area A (m^2) held fixed (Zeng's Table I).
FIXED_CONSTANTS = {'air_density_kg_per_m3': 1.225, 'rotor_solidity': 0.05,
                   'rotor_disc_area_m2': 0.503}
#: Fewest level samples a fit accepts, and the fewest distinct airspeeds (1 m/s apart) among
#: them: the curve's shape needs more than two speeds.
MIN_LEVEL_SAMPLES = 10
MIN_DISTINCT_SPEEDS = 3
#: A sample is level when |v_z| is below this, m/s; it climbs or descends when |v_z| is at least
#: MIN_VERTICAL_MPS.
LEVEL_MPS = 0.2
MIN_VERTICAL_MPS = 0.3
_LEVEL_NAMES = ('blade_profile_power_w', 'induced_power_w', 'tip_speed_mps',
                'induced_velocity_mps', 'fuselage_drag_ratio')


@dataclass(frozen=True)
class AirframeFit:
    """A fitted airframe and how well it matches its samples: the RMS and the largest absolute
    residual (W) over the ``samples`` used, the fastest airspeed among them (m/s), and whether
    the climb and descent coefficients were fitted (else 0: no sample climbed or descended)."""

    airframe: Airframe
    rms_w: float
    max_error_w: float
    samples: int
    fastest_mps: float
    fitted_climb: bool = False
    fitted_descent: bool = False


def _checked(airspeed_mps, climb_mps, power_w) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    arrays = [np.asarray(values, dtype=float).ravel()
              for values in (airspeed_mps, climb_mps, power_w)]
    if len({array.size for array in arrays}) != 1:
        raise InvalidScenarioError('airspeeds, vertical speeds and powers must be as many')
    if not all(np.isfinite(array).all() for array in arrays):
        raise InvalidScenarioError('samples must be finite numbers')
    if (arrays[0] < 0).any():
        raise InvalidScenarioError('airspeeds must be at least 0 m/s')
    if (arrays[2] <= 0).any():
        raise InvalidScenarioError('powers must be positive')
    return arrays[0], arrays[1], arrays[2]


def _airframe(name: str, values: np.ndarray, fit_climb: bool, fit_descent: bool,
              top_airspeed_mps: float) -> Airframe:
    level = dict(zip(_LEVEL_NAMES, values[:5]))
    vertical = list(values[5:])
    climb = vertical.pop(0) if fit_climb else 0.0
    descent = vertical.pop(0) if fit_descent else 0.0
    return Airframe(name=name, **level, **FIXED_CONSTANTS, top_airspeed_mps=top_airspeed_mps,
                    climb_w_per_mps=climb, descent_w_per_mps=descent)


def fit_airframe(name: str, airspeed_mps, climb_mps, power_w, *,
                 top_airspeed_mps: float | None = None) -> AirframeFit:
    """The airframe whose ``power_w(V, v_z)`` best fits steady samples (module docstring).

    ``airspeed_mps``, ``climb_mps`` (up positive) and ``power_w`` are equal-length sequences;
    ``top_airspeed_mps`` defaults to the fastest sample's airspeed. Raises
    :class:`~uav_comm_planner.errors.InvalidScenarioError` for samples that cannot identify the
    curve (too few level samples, or too few distinct airspeeds among them).
    """
    speed, climb, power = _checked(airspeed_mps, climb_mps, power_w)
    level = np.abs(climb) < LEVEL_MPS
    distinct = np.unique(np.round(speed[level])).size
    if level.sum() < MIN_LEVEL_SAMPLES or distinct < MIN_DISTINCT_SPEEDS:
        raise InvalidScenarioError(
            f'{int(level.sum())} steady level samples at {distinct} distinct airspeeds; a fit '
            f'needs at least {MIN_LEVEL_SAMPLES} at {MIN_DISTINCT_SPEEDS} airspeeds 1 m/s or '
            f'more apart (fly level legs at several steady speeds)')
    fit_climb = bool((climb >= MIN_VERTICAL_MPS).any())
    fit_descent = bool((climb <= -MIN_VERTICAL_MPS).any())
    top = float(speed.max()) if top_airspeed_mps is None else float(top_airspeed_mps)
    if not top > 0:
        raise InvalidScenarioError(f'the top airspeed must be positive, got {top:g} m/s')
    slowest = level & (speed <= np.quantile(speed[level], 0.1) + 0.5)
    hover = float(np.median(power[slowest]))
    # P0, Pi, U_tip, v0, d0 [, climb W/(m/s)] [, descent W/(m/s)]
    lower = [1e-3 * hover, 0.0, 10.0, 0.3, 0.0]
    upper = [10.0 * hover, 10.0 * hover, 500.0, 50.0, 100.0]
    scale = [hover, hover, 100.0, 5.0, 1.0]
    if fit_climb:
        lower, upper, scale = lower + [0.0], upper + [100.0 * hover], scale + [10.0]
    if fit_descent:
        lower, upper, scale = lower + [-100.0 * hover], upper + [100.0 * hover], scale + [10.0]

    def residuals(values: np.ndarray) -> np.ndarray:
        airframe = _airframe(name, values, fit_climb, fit_descent, top)
        return airframe.power_w(speed, climb) - power

    best = None
    for share in (0.3, 0.5, 0.7):
        for v0 in (2.0, 5.0, 12.0):
            for d0 in (0.05, 0.6):
                start = [share * hover, (1.0 - share) * hover, 120.0, v0, d0]
                start += [10.0] * fit_climb + [-5.0] * fit_descent
                found = optimize.least_squares(residuals, start, bounds=(lower, upper),
                                               x_scale=scale, method='trf')
                if best is None or found.cost < best.cost:
                    best = found
    airframe = _airframe(name, best.x, fit_climb, fit_descent, top)
    error = airframe.power_w(speed, climb) - power
    return AirframeFit(airframe, float(np.sqrt(np.mean(error ** 2))),
                       float(np.abs(error).max()), int(speed.size), float(speed.max()),
                       fit_climb, fit_descent)


__all__ = ['AirframeFit', 'FIXED_CONSTANTS', 'fit_airframe', 'LEVEL_MPS', 'MIN_DISTINCT_SPEEDS',
           'MIN_LEVEL_SAMPLES', 'MIN_VERTICAL_MPS']
