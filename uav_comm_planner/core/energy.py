"""The propulsion energy of a planned horizon.

The legs q0 -> q[1] -> ... -> q[M] -> qF are each flown at constant velocity over one slot
delta, so leg l's ground velocity is v_l = (its vector) / delta and its airspeed ||v_l - w|| in
the wind w; its power is the airframe's P(||v_l - w||)
(:class:`~uav_comm_planner.core.propulsion.Airframe`) and the horizon's energy is
sum_l P(||v_l - w||) delta.

A mission adds its takeoff to the altitude before q0 and its landing after qF
(:func:`takeoff_landing_j`, with the autopilot's vertical speeds, :class:`VerticalProfile`);
a :class:`Battery` gives the energy a mission may use, its usable energy less a reserve, and
what remains of it for the horizon once takeoff and landing are paid
(:func:`horizon_allowance_wh`).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from uav_comm_planner.core.model import legs
from uav_comm_planner.core.numbers import real_number
from uav_comm_planner.core.propulsion import Airframe
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.errors import InvalidScenarioError

#: Joules in a watt-hour.
JOULES_PER_WH = 3600.0


def leg_airspeeds(q: np.ndarray, scenario: Scenario) -> np.ndarray:
    """||v_l - w|| of the M + 1 legs q0 -> q[1] -> ... -> qF flown at constant velocity over a
    slot each, in the scenario's wind: (M + 1,) m/s."""
    velocity = legs(q, scenario) / scenario.slot_s
    return np.linalg.norm(velocity - scenario.wind_mps, axis=1)


def leg_powers(q: np.ndarray, scenario: Scenario, airframe: Airframe) -> np.ndarray:
    """The propulsion power of each of the M + 1 legs of q (M, 2) metres: (M + 1,) W."""
    return airframe.level_power_w(leg_airspeeds(q, scenario))


def horizon_energy_j(q: np.ndarray, scenario: Scenario, airframe: Airframe) -> float:
    """The propulsion energy of the horizon's M + 1 legs, sum_l P(||v_l - w||) delta, J."""
    return float(leg_powers(q, scenario, airframe).sum() * scenario.slot_s)


def least_horizon_energy_j(scenario: Scenario, airframe: Airframe) -> float:
    """A lower bound on any plan's horizon energy: the M + 1 legs at the least level power."""
    return (scenario.num_slots + 1) * scenario.slot_s * airframe.least_power()[1]


@dataclass(frozen=True)
class VerticalProfile:
    """How the autopilot climbs to the mission's altitude and lands: ArduCopter's defaults
    (WPNAV_SPEED_UP 2.5 m/s, WPNAV_SPEED_DN 1.5 m/s, LAND_SPEED 0.5 m/s below LAND_ALT_LOW
    10 m)."""

    climb_mps: float = 2.5
    descent_mps: float = 1.5
    land_speed_mps: float = 0.5
    land_slow_below_m: float = 10.0


def takeoff_landing_j(airframe: Airframe, altitude_m: float,
                      profile: VerticalProfile = VerticalProfile()) -> tuple[float, float]:
    """(takeoff, landing) propulsion energy, J: the climb from the ground to ``altitude_m``,
    and the descent from it, fast to ``land_slow_below_m`` then at the landing speed, each
    with no airspeed (:meth:`~uav_comm_planner.core.propulsion.Airframe.power_w`)."""
    slow = min(profile.land_slow_below_m, altitude_m)
    up = float(airframe.power_w(0.0, profile.climb_mps)) * altitude_m / profile.climb_mps
    down = (float(airframe.power_w(0.0, -profile.descent_mps)) * (altitude_m - slow)
            / profile.descent_mps
            + float(airframe.power_w(0.0, -profile.land_speed_mps)) * slow
            / profile.land_speed_mps)
    return up, down


#: The share of a battery's usable energy kept in reserve by default.
DEFAULT_RESERVE = 0.2


@dataclass(frozen=True)
class Battery:
    """A battery as the user states it: ``usable_wh`` of energy, of which ``reserve`` (a share,
    0.2 by default) is kept back at landing."""

    usable_wh: float
    reserve: float = DEFAULT_RESERVE

    def __post_init__(self):
        usable = real_number('battery_wh', self.usable_wh)
        reserve = real_number('battery_reserve', self.reserve)
        if not (math.isfinite(usable) and usable > 0.0):
            raise InvalidScenarioError(f'battery_wh must be positive and finite, got '
                                       f'{self.usable_wh!r}')
        if not 0.0 <= reserve < 1.0:
            raise InvalidScenarioError(f'battery_reserve is a share in [0, 1), got '
                                       f'{self.reserve!r}')
        object.__setattr__(self, 'usable_wh', usable)
        object.__setattr__(self, 'reserve', reserve)

    @property
    def available_wh(self) -> float:
        """What a mission may use: the usable energy less the reserve."""
        return self.usable_wh * (1.0 - self.reserve)


def horizon_allowance_wh(battery: Battery, airframe: Airframe, altitude_m: float,
                         profile: VerticalProfile = VerticalProfile()) -> float:
    """The energy the horizon q0 -> qF may use: the battery's available energy less takeoff and
    landing (may be negative: then no horizon is flyable)."""
    up, down = takeoff_landing_j(airframe, altitude_m, profile)
    return battery.available_wh - (up + down) / JOULES_PER_WH


__all__ = ['Battery', 'DEFAULT_RESERVE', 'horizon_allowance_wh', 'horizon_energy_j',
           'JOULES_PER_WH', 'least_horizon_energy_j', 'leg_airspeeds', 'leg_powers',
           'takeoff_landing_j', 'VerticalProfile']
