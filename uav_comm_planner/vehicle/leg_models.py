"""How each autopilot's legs are timed, behind one interface for the mission's schedule.

:mod:`.flyable` turns a plan into stops and legs; what a leg costs depends on the autopilot.
ArduCopter plans a leg ahead along its S-curve (:mod:`.timing`) and starts a hold's timer once
at rest, ``LEG_LATENCY_S`` after the curve ends; PX4 follows its trajectory generator
(:mod:`.px4_timing`), slows at fly-through turns, and starts a hold's timer on entering the
acceptance radius, still braking. A :class:`LegModel` says, for one of them, how a leg along
some vertices at some speed moves, when the hold at its end starts counting, and how long a
stop must hold for the next leg to start from rest. The firmware table
(:data:`~uav_comm_planner.vehicle.firmware.FIRMWARES`) names the model each firmware uses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np

from uav_comm_planner.vehicle.firmware import firmware_named
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.px4_timing import (px4_profile, px4_speed_for_time,
                                                 shortest_leg_m, START_DELAY_S)
from uav_comm_planner.vehicle.timing import LEG_LATENCY_S, Profile, speed_for_time

#: A stop holds at least this long once the vehicle is at rest: with no hold the autopilot
#: would fly through it. q0 too: ArduCopter runs the DO_CHANGE_SPEED after a waypoint while it
#: holds there; at q0 without a hold the first leg starts at the previous speed and was
#: measured up to 6 s early at 3 m/s.
MIN_STOP_HOLD_S = 1.0


class LegProfile(Protocol):
    """Distance flown along a leg against time, from rest to rest."""

    duration_s: float
    length_m: float

    def distance(self, t: np.ndarray) -> np.ndarray: ...


def length_of(vertices: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(vertices, axis=0), axis=1).sum())


@dataclass(frozen=True)
class LegModel:
    """One autopilot's leg timing.

    profile(vertices (V, 2), speed, limits): the leg's motion from rest to rest;
    timed_s(profile): the part of the motion a leg's speed is fitted to and centred on the
    plan's time for it (ArduCopter: rest to rest; PX4: up to the acceptance radius);
    speed_for_time(vertices, seconds, max speed, limits): the cruise whose ``timed_s`` fits
    the time given (at most the max speed);
    start_delay_s: from the end of a hold to the start of the motion;
    after_timed_s: from the end of ``timed_s`` until the hold at the leg's end starts counting
    and the autopilot reports the waypoint reached (:meth:`reached_s`);
    per_vertex: whether the leg's inner vertices change its time (PX4 slows at each turn;
    ArduCopter's S-curve spans the whole polyline);
    shortest_leg_m(limits): stops closer together than this are one (PX4 may report the next
    reached before it flies there; ArduCopter flies any leg).
    """

    profile: Callable[[np.ndarray, float, VehicleLimits], LegProfile]
    timed_s: Callable[[LegProfile], float]
    speed_for_time: Callable[[np.ndarray, float, float, VehicleLimits], float]
    start_delay_s: float
    after_timed_s: float
    per_vertex: bool
    shortest_leg_m: Callable[[VehicleLimits], float] = lambda limits: 0.0

    def reached_s(self, profile: LegProfile) -> float:
        """When, after the motion starts, the hold at the leg's end starts counting."""
        return self.timed_s(profile) + self.after_timed_s

    def settle_s(self, profile: LegProfile) -> float:
        """How long after :meth:`reached_s` the vehicle comes to rest."""
        return max(profile.duration_s - self.reached_s(profile), 0.0)

    def min_hold_s(self, incoming: LegProfile | None, cruise_mps: float,
                   limits: VehicleLimits) -> float:
        """The shortest hold at a stop reached by ``incoming`` (None: q0, reached from the
        take-off, at up to ``cruise_mps``): the vehicle at rest for MIN_STOP_HOLD_S."""
        if incoming is None:
            incoming = self.profile(np.array([[0.0, 0.0], [1000.0, 0.0]]), cruise_mps, limits)
        return MIN_STOP_HOLD_S + self.settle_s(incoming)


def _scurve_profile(vertices: np.ndarray, speed: float, limits: VehicleLimits) -> Profile:
    return Profile.rest_to_rest(length_of(vertices), speed, limits)


def _scurve_speed(vertices: np.ndarray, duration_s: float, max_speed: float,
                  limits: VehicleLimits) -> float:
    return speed_for_time(length_of(vertices), duration_s, max_speed, limits)


LEG_MODELS = {
    # ArduCopter starts a leg, and a hold, half of LEG_LATENCY_S after the S-curve's ends.
    'scurve': LegModel(_scurve_profile, lambda profile: profile.duration_s, _scurve_speed,
                       LEG_LATENCY_S / 2, LEG_LATENCY_S / 2, False),
    'px4': LegModel(px4_profile, lambda profile: profile.hold_start_s, px4_speed_for_time,
                    START_DELAY_S, 0.0, True, shortest_leg_m),
}


def leg_model(firmware: str) -> LegModel:
    """The leg timing of the firmware called ``firmware``."""
    return LEG_MODELS[firmware_named(firmware).timing]


__all__ = ['LEG_MODELS', 'LegModel', 'LegProfile', 'MIN_STOP_HOLD_S', 'leg_model', 'length_of']
