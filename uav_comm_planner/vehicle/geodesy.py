"""The geodetic anchor of the planning frame: east-north-up metres from a home point on WGS84.

The planner works in metres with x = east and y = north; a mission file needs latitude and
longitude. The conversion goes through pymap3d's ENU <-> geodetic transforms on the WGS84
ellipsoid, which stay exact over any distance (a flat-earth approximation drifts by metres
over a few kilometres at high latitude).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
import pymap3d

from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.vehicle.firmware import FIRMWARES, firmware_named

#: Home altitudes accepted, metres above mean sea level: from below the Dead Sea shore
#: (-430 m) to above the highest airfields, with margin.
HOME_ALTITUDE_RANGE_M = (-1000.0, 10000.0)


@dataclass(frozen=True)
class Home:
    """Where the planning frame is anchored: the launch point, ground level.

    ``altitude_m`` is the home altitude above mean sea level as the autopilot reports it. The
    ENU transform reads it as the ellipsoidal height; the geoid separation (at most ~100 m)
    scales horizontal distances by less than 2e-5, i.e. under 4 cm over the letter's 2 km.
    """

    latitude_deg: float
    longitude_deg: float
    altitude_m: float

    def __post_init__(self) -> None:
        for name in ('latitude_deg', 'longitude_deg', 'altitude_m'):
            value = getattr(self, name)
            try:
                number = float(value)
            except (TypeError, ValueError, OverflowError):
                number = math.nan
            if isinstance(value, (bool, np.bool_)) or not isinstance(
                    value, (int, float, np.integer, np.floating)) or not math.isfinite(number):
                raise InvalidScenarioError(f'home {name} must be a finite number, got {value!r}')
            object.__setattr__(self, name, number)
        if not -90.0 <= self.latitude_deg <= 90.0:
            raise InvalidScenarioError(
                f'home latitude must be in [-90, 90] degrees, got {self.latitude_deg}')
        if not -180.0 <= self.longitude_deg <= 180.0:
            raise InvalidScenarioError(
                f'home longitude must be in [-180, 180] degrees, got {self.longitude_deg}')
        low, high = HOME_ALTITUDE_RANGE_M
        if not low <= self.altitude_m <= high:
            raise InvalidScenarioError(
                f'home altitude must be in [{low:g}, {high:g}] m above sea level, got '
                f'{self.altitude_m:g}')

    @classmethod
    def parse(cls, text: str) -> 'Home':
        """Read ``'LAT,LON,ALT'`` (degrees, degrees, metres above sea level)."""
        parts = [part.strip() for part in str(text).split(',')]
        if len(parts) != 3:
            raise InvalidScenarioError(
                f'home must be LAT,LON,ALT (degrees, degrees, metres), got {text!r}')
        try:
            latitude, longitude, altitude = (float(part) for part in parts)
        except ValueError:
            raise InvalidScenarioError(
                f'home must be three numbers LAT,LON,ALT, got {text!r}') from None
        return cls(latitude, longitude, altitude)


def enu_to_geodetic(east_m: np.ndarray, north_m: np.ndarray, up_m: np.ndarray | float,
                    home: Home) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ENU metres from ``home`` -> (latitude deg, longitude deg, ellipsoidal height m).

    Inputs broadcast against each other: (K,) each, or scalars; outputs have their shape.
    Raises :class:`~uav_comm_planner.errors.InvalidScenarioError` when a result is not a finite
    latitude in [-90, 90] and longitude in [-180, 180] (offsets too large for the ellipsoid).
    """
    latitude, longitude, height = pymap3d.enu2geodetic(
        np.asarray(east_m, dtype=float), np.asarray(north_m, dtype=float),
        np.asarray(up_m, dtype=float), home.latitude_deg, home.longitude_deg, home.altitude_m,
        ell=pymap3d.Ellipsoid.from_name('wgs84'), deg=True)
    latitude, longitude, height = (np.asarray(v) for v in (latitude, longitude, height))
    if not (np.all(np.isfinite(latitude)) and np.all(np.isfinite(longitude))
            and np.all(np.isfinite(height)) and np.all(np.abs(latitude) <= 90.0)
            and np.all(np.abs(longitude) <= 180.0)):
        raise InvalidScenarioError(
            f'positions up to {float(np.max(np.abs(east_m))):g} m east and '
            f'{float(np.max(np.abs(north_m))):g} m north of home do not map to valid '
            f'latitudes and longitudes')
    return latitude, longitude, height


def geodetic_to_enu(latitude_deg: np.ndarray, longitude_deg: np.ndarray,
                    height_m: np.ndarray | float,
                    home: Home) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(latitude deg, longitude deg, ellipsoidal height m) -> ENU metres from ``home``."""
    east, north, up = pymap3d.geodetic2enu(
        np.asarray(latitude_deg, dtype=float), np.asarray(longitude_deg, dtype=float),
        np.asarray(height_m, dtype=float), home.latitude_deg, home.longitude_deg,
        home.altitude_m, ell=pymap3d.Ellipsoid.from_name('wgs84'), deg=True)
    return np.asarray(east), np.asarray(north), np.asarray(up)


def default_home(firmware: str) -> Home:
    """The home a plan for ``firmware`` is anchored at when none is given: that firmware's
    simulator home (ArduPilot SITL's CMAC, -35.363262, 149.165237, 584 m; PX4 SITL's Zurich,
    47.397742, 8.545594, 489 m). Raises InvalidScenarioError for an unknown firmware."""
    return Home(*firmware_named(firmware).sitl_home)


#: The default firmware's (ArduPilot's) home: ArduPilot SITL's CMAC, Canberra.
DEFAULT_HOME = FIRMWARES['ardupilot'].sitl_home


def geodetic_to_plane(latitude_deg: np.ndarray, longitude_deg: np.ndarray,
                      home: Home) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(latitude deg, longitude deg) -> (east m, north m, distance m): the point of the planning
    frame's plane (ENU up = 0 at ``home``) that :func:`enu_to_geodetic` with ``up_m=0`` turns
    back into the same latitude and longitude, as a mission's waypoints are turned; and the
    straight-line distance from home of the place on the ground (at home's height).

    That point is where the place's ellipsoid normal meets the plane: the normal is a straight
    line along which ENU up is affine in the ellipsoidal height, so one step solves it, and the
    round trip is exact to round-off (about 1e-9 m). ``geodetic_to_enu`` at home's height drops
    the ground's fall below the plane (d^2 / 2R, 0.7 km at 95 km), which moves a far place
    sideways by that times d / R (10 m at 95 km). Inputs (K,) each; outputs (K,).
    """
    ellipsoid = pymap3d.Ellipsoid.from_name('wgs84')
    latitude = np.asarray(latitude_deg, dtype=float)
    longitude = np.asarray(longitude_deg, dtype=float)

    def enu(height: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        east, north, up = pymap3d.geodetic2enu(
            latitude, longitude, height, home.latitude_deg, home.longitude_deg,
            home.altitude_m, ell=ellipsoid, deg=True)
        return np.asarray(east), np.asarray(north), np.asarray(up)

    east, north, up = enu(home.altitude_m)
    distance = np.sqrt(east ** 2 + north ** 2 + up ** 2)
    step_m = 1000.0
    slope = (enu(home.altitude_m + step_m)[2] - up) / step_m   # cos of the normals' angle
    with np.errstate(divide='ignore', invalid='ignore'):
        height = home.altitude_m - up / np.where(slope > 0.1, slope, np.nan)
    east, north, _ = enu(height)
    return east, north, distance


__all__ = ['DEFAULT_HOME', 'default_home', 'HOME_ALTITUDE_RANGE_M', 'Home', 'enu_to_geodetic',
           'geodetic_to_enu', 'geodetic_to_plane']
