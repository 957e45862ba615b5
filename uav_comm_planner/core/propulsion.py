"""The propulsion power of a rotary-wing UAV, and the energy of a planned horizon.

Zeng, Xu and Zhang, "Energy minimization for wireless communication with rotary-wing UAV",
IEEE TWC 2019, eq. (12): in level flight at airspeed V,

    P(V) = P0 (1 + 3 V^2 / U_tip^2)                                   blade profile
         + Pi (sqrt(1 + V^4 / (4 v0^4)) - V^2 / (2 v0^2))^(1/2)       induced
         + (1/2) d0 rho s A V^3                                       parasite

with P0 + Pi the hover power. A climb at v_z > 0 adds ``climb_w_per_mps`` v_z (about m g over
the propulsive efficiency) and a descent changes the power by ``descent_w_per_mps`` |v_z|
(usually a small saving, so a negative number); both measured per airframe.

The energy of a planned horizon is in :mod:`uav_comm_planner.core.energy`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
import math

import numpy as np
from scipy import optimize

from uav_comm_planner.errors import InvalidScenarioError


@dataclass(frozen=True)
class Airframe:
    """A rotary-wing airframe's propulsion power (module docstring), SI units in the names.

    blade_profile_power_w: P0; induced_power_w: Pi; tip_speed_mps: U_tip;
    induced_velocity_mps: v0, the mean rotor induced velocity in hover; fuselage_drag_ratio: d0;
    air_density_kg_per_m3: rho; rotor_solidity: s; rotor_disc_area_m2: A; top_airspeed_mps:
    the fastest it flies through the air; climb_w_per_mps and descent_w_per_mps: the power
    per m/s of climb and of descent, added to the level power.
    """

    name: str
    blade_profile_power_w: float
    induced_power_w: float
    tip_speed_mps: float
    induced_velocity_mps: float
    fuselage_drag_ratio: float
    air_density_kg_per_m3: float
    rotor_solidity: float
    rotor_disc_area_m2: float
    top_airspeed_mps: float
    climb_w_per_mps: float = 0.0
    descent_w_per_mps: float = 0.0

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise InvalidScenarioError('an airframe needs a name')
        for name, value in asdict(self).items():
            if name == 'name':
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InvalidScenarioError(f'airframe {self.name!r}: {name} must be a number, '
                                           f'got {value!r}')
            if not math.isfinite(value):
                raise InvalidScenarioError(f'airframe {self.name!r}: {name} must be finite')
            object.__setattr__(self, name, float(value))
        for name in ('blade_profile_power_w', 'tip_speed_mps', 'induced_velocity_mps',
                     'air_density_kg_per_m3', 'rotor_solidity', 'rotor_disc_area_m2',
                     'top_airspeed_mps'):
            if getattr(self, name) <= 0.0:
                raise InvalidScenarioError(f'airframe {self.name!r}: {name} must be positive, '
                                           f'got {getattr(self, name):g}')
        for name in ('induced_power_w', 'fuselage_drag_ratio', 'climb_w_per_mps'):
            if getattr(self, name) < 0.0:
                raise InvalidScenarioError(f'airframe {self.name!r}: {name} must be at least 0, '
                                           f'got {getattr(self, name):g}')

    @property
    def parasite_coefficient(self) -> float:
        """(1/2) d0 rho s A, W per (m/s)^3."""
        return 0.5 * (self.fuselage_drag_ratio * self.air_density_kg_per_m3
                      * self.rotor_solidity * self.rotor_disc_area_m2)

    def level_power_w(self, airspeed_mps: np.ndarray | float) -> np.ndarray:
        """P(V) of eq. (12), W, elementwise for airspeeds V >= 0 m/s."""
        v = np.abs(np.asarray(airspeed_mps, dtype=float))
        v0 = self.induced_velocity_mps
        ratio = v ** 2 / (2.0 * v0 ** 2)
        # sqrt(1 + r^2) - r written as 1 / (sqrt(1 + r^2) + r): no cancellation at speed.
        induced = self.induced_power_w / np.sqrt(np.sqrt(1.0 + ratio ** 2) + ratio)
        return (self.blade_profile_power_w * (1.0 + 3.0 * v ** 2 / self.tip_speed_mps ** 2)
                + induced + self.parasite_coefficient * v ** 3)

    def power_w(self, airspeed_mps: np.ndarray | float,
                climb_mps: np.ndarray | float = 0.0) -> np.ndarray:
        """The power at airspeed V and vertical speed v_z (up positive), W."""
        climb = np.asarray(climb_mps, dtype=float)
        vertical = np.where(climb > 0.0, self.climb_w_per_mps * climb,
                            self.descent_w_per_mps * (-climb))
        return self.level_power_w(airspeed_mps) + vertical

    @property
    def hover_power_w(self) -> float:
        """P(0) = P0 + Pi, W."""
        return float(self.level_power_w(0.0))

    def least_power(self) -> tuple[float, float]:
        """(airspeed m/s, power W) of the least level power over [0, top airspeed]."""
        found = optimize.minimize_scalar(lambda v: float(self.level_power_w(v)),
                                         bounds=(0.0, self.top_airspeed_mps), method='bounded',
                                         options={'xatol': 1e-6})
        candidates = [(float(found.x), float(found.fun)), (0.0, self.hover_power_w)]
        return min(candidates, key=lambda pair: pair[1])


#: Table I of Zeng, Xu and Zhang (2019), with their 30 m/s as the top airspeed.
ZENG2019 = Airframe(name='zeng2019', blade_profile_power_w=79.86, induced_power_w=88.63,
                    tip_speed_mps=120.0, induced_velocity_mps=4.03, fuselage_drag_ratio=0.6,
                    air_density_kg_per_m3=1.225, rotor_solidity=0.05, rotor_disc_area_m2=0.503,
                    top_airspeed_mps=30.0)


__all__ = ['Airframe', 'ZENG2019']
