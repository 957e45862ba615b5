"""Climbs and descents in the vehicle's timing: ArduCopter's S-curve in three dimensions.

ArduCopter (AC_WPNav, SCurve::calculate_track) plans a waypoint segment along its 3D direction
with limits taken from the horizontal and vertical ones: the speed along the track is the
largest whose horizontal part keeps WPNAV_SPEED and whose vertical part keeps WPNAV_SPEED_UP
climbing or WPNAV_SPEED_DN descending (:func:`kinematic_limit`), the acceleration likewise from
WPNAV_ACCEL and WPNAV_ACCEL_Z; the jerk is the horizontal one along the track.

On a segment climbing at a slope s = dz / dxy, the horizontal limit binds while V s <= V_up:
the vehicle then flies V over the ground whatever the climb, and the altitude follows the
horizontal progress along the segment. A leg here is given a cruise no faster than keeps every
one of its segments so (:func:`leg_limits`), so its horizontal motion is the horizontal
S-curve of :mod:`.timing` with the acceleration the vertical limit leaves at its ends
(A_z / s where that is below A) and the horizontal part of the jerk (J cos): the timing of a
leg with climbs is the timing of a level leg with those limits.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math

import numpy as np

from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.timing import ramp_distance
from uav_comm_planner.vehicle.waypoints import simplify

#: A leg's cruise keeps its steepest segment's climb this far below the vertical limit (the
#: waypoints the autopilot flies join the plan's points by chords a little steeper than them).
CLIMB_MARGIN = 0.95
#: Horizontal steps shorter than this (metres) count as this long: a vertical segment.
MIN_HORIZONTAL_M = 1e-6


@dataclass(frozen=True)
class ClimbLimits:
    """The vehicle's vertical limits: ``up_mps`` (WPNAV_SPEED_UP, 2.5 m/s by default),
    ``down_mps`` (WPNAV_SPEED_DN, 1.5 m/s) and ``accel_mpss`` (WPNAV_ACCEL_Z, 1 m/s/s)."""

    up_mps: float = 2.5
    down_mps: float = 1.5
    accel_mpss: float = 1.0

    def __post_init__(self) -> None:
        for name in ('up_mps', 'down_mps', 'accel_mpss'):
            value = getattr(self, name)
            if (isinstance(value, bool) or not isinstance(value, (int, float))
                    or not math.isfinite(value) or value <= 0):
                raise InvalidScenarioError(f'vehicle climb {name} must be a positive finite '
                                           f'number, got {value!r}')

    @property
    def slowest_mps(self) -> float:
        """The slower of the climb and the descent: the fastest altitude change a plan may
        ask in either direction."""
        return min(self.up_mps, self.down_mps)


def kinematic_limit(horizontal_m: float, vertical_m: float, max_xy: float, max_up: float,
                    max_down: float) -> float:
    """The largest magnitude along the direction (horizontal_m, vertical_m) whose horizontal
    part is at most ``max_xy`` and whose vertical part at most ``max_up`` (climbing) or
    ``max_down`` (descending): ArduPilot's kinematic_limit."""
    length = math.hypot(horizontal_m, vertical_m)
    if length == 0.0:
        return 0.0
    vertical_cap = max_up if vertical_m > 0 else max_down
    if horizontal_m == 0.0:
        return vertical_cap
    along = max_xy * length / horizontal_m
    if vertical_m == 0.0:
        return along
    return min(along, vertical_cap * length / abs(vertical_m))


def _slopes(path: np.ndarray, heights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per segment of a leg: its horizontal length (metres) and slope dz / dxy (signed)."""
    horizontal = np.linalg.norm(np.diff(path, axis=0), axis=1)
    return horizontal, np.diff(heights) / np.maximum(horizontal, MIN_HORIZONTAL_M)


def leg_limits(path: np.ndarray, heights: np.ndarray, limits: VehicleLimits,
               climb: ClimbLimits) -> tuple[float, VehicleLimits]:
    """For a leg along ``path`` (K, 2) metres at ``heights`` (K,) metres: the fastest cruise
    over the ground at which the horizontal speed limit binds on every segment, and the
    horizontal limits its S-curve has (module docstring): the acceleration and the jerk as the
    vertical limit leaves them on the segments within a ramp of either end."""
    horizontal, slope = _slopes(np.asarray(path, float), np.asarray(heights, float))
    if not len(slope):
        return limits.cruise_speed_mps, limits
    caps = np.where(slope > 0, climb.up_mps, climb.down_mps) / np.maximum(np.abs(slope), 1e-12)
    cruise = min(limits.cruise_speed_mps, CLIMB_MARGIN * float(caps.min()))
    arc = np.concatenate([[0.0], np.cumsum(horizontal)])
    reach = ramp_distance(limits.cruise_speed_mps, limits)
    ends = (arc[:-1] <= reach) | (arc[1:] >= arc[-1] - reach)
    steepest = float(np.abs(slope[ends]).max(initial=0.0))
    accel = limits.max_accel_mpss
    if steepest > 0.0:
        accel = min(accel, climb.accel_mpss / steepest)
    jerk = limits.max_jerk_mpsss / math.sqrt(1.0 + steepest * steepest)
    return cruise, replace(limits, max_accel_mpss=max(accel, 0.01),
                           max_jerk_mpsss=max(jerk, 0.01))


def with_altitude_bends(path: np.ndarray, heights: np.ndarray, kept: list[int],
                        tolerance_m: float) -> list[int]:
    """``kept`` (indices of ``path`` (K, 2) a leg flies through, chosen for its horizontal
    line) with the points where its altitude profile bends: the Douglas-Peucker points of the
    curve (horizontal arc length, altitude) within ``tolerance_m``, so that the straight 3D
    segments between the waypoints keep the planned altitudes within it too."""
    steps = np.linalg.norm(np.diff(np.asarray(path, float), axis=0), axis=1)
    profile = np.column_stack([np.concatenate([[0.0], np.cumsum(steps)]),
                               np.asarray(heights, float)])
    return sorted(set(kept) | set(simplify(profile, tolerance_m)))


def vertex_heights(vertices: np.ndarray, path: np.ndarray, heights: np.ndarray) -> np.ndarray:
    """The heights (V,) of a leg's waypoints ``vertices`` (V, 2), each one of the rows of
    ``path`` (K, 2) in order (the leg keeps some of its points), from ``heights`` (K,)."""
    out = np.empty(len(vertices))
    row = 0
    for index, vertex in enumerate(vertices):
        while row < len(path) - 1 and not np.array_equal(path[row], vertex):
            row += 1
        out[index] = heights[row]
    return out


def check_climb_rate(max_climb_mps: float, climb: ClimbLimits) -> None:
    """Refuse a planned climb rate faster than the vehicle climbs or descends."""
    if max_climb_mps > climb.slowest_mps * (1 + 1e-9):
        raise InvalidScenarioError(
            f'the plan climbs or descends at up to {max_climb_mps:g} m/s, the vehicle at '
            f'{climb.up_mps:g} m/s up (WPNAV_SPEED_UP) and {climb.down_mps:g} m/s down '
            f'(WPNAV_SPEED_DN): plan with a climb rate of {climb.slowest_mps:g} m/s or less')


__all__ = ['check_climb_rate', 'ClimbLimits', 'kinematic_limit',
           'leg_limits', 'vertex_heights', 'with_altitude_bends']
