"""How long the autopilot takes to fly a leg, and where it is meanwhile.

ArduCopter and PX4 fly a waypoint leg from rest to rest with a jerk-limited speed profile: the
acceleration rises to the acceleration limit A, stays there, falls as the speed reaches the
cruise speed V; the stop mirrors the start. ArduPilot's SCurve shapes the jerk as a raised
cosine over a jerk time tj (2 ATC_INPUT_TC = 0.3 s by default), so reaching V from rest takes
V / A + A / J + tj seconds. The functions here take the constant jerk J' that gives the same
ramp time, 1 / J' = 1 / J + tj / A (:attr:`VehicleLimits.ramp_jerk_mpsss`): a ramp to V takes
V / A + A / J' seconds over V (V / A + A / J') / 2 metres (when V >= A^2 / J'; else
2 sqrt(V / J')), a leg of length L reaches at most the speed V with L = V (V / A + A / J'), and a
leg flown at V takes L / V + V / A + A / J' seconds: the start and the stop each cost half of
V / A + A / J' over flying at V throughout.

A point where the flight turns by a few degrees is flown through without slowing; a hover is a
stop. So a flight is a chain of stops (:class:`Dwell`) joined by legs (:class:`Leg`), each leg a
polyline flown at one cruise speed from rest to rest; :class:`Flight` gives the position at any
time. ``LEG_LATENCY_S`` is what ArduCopter adds to each leg between the end of one hold and the
start of the next (the vehicle settling into the waypoint radius behind its target, and
the mission starting the next leg), measured on ArduCopter 4.7 software-in-the-loop: 0.4 to
1.0 s over legs of 99 to 400 m.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Sequence

import numpy as np

#: Seconds ArduCopter adds to a rest-to-rest leg beyond its S-curve (see the module docstring).
LEG_LATENCY_S = 0.7


def ramp_time(speed_mps: float, accel_mpss: float, jerk_mpsss: float) -> float:
    """Seconds to go from rest to ``speed_mps`` (or back) under the limits A and J."""
    if speed_mps >= accel_mpss ** 2 / jerk_mpsss:
        return speed_mps / accel_mpss + accel_mpss / jerk_mpsss
    return 2.0 * math.sqrt(speed_mps / jerk_mpsss)


def ramp_distance(speed_mps: float, accel_mpss: float, jerk_mpsss: float) -> float:
    """Metres flown while going from rest to ``speed_mps``: the ramp is symmetric, so V t / 2."""
    return 0.5 * speed_mps * ramp_time(speed_mps, accel_mpss, jerk_mpsss)


def peak_speed(length_m: float, speed_mps: float, accel_mpss: float,
               jerk_mpsss: float) -> float:
    """The fastest a rest-to-rest leg of ``length_m`` flies when asked for ``speed_mps``."""
    if 2.0 * ramp_distance(speed_mps, accel_mpss, jerk_mpsss) <= length_m:
        return speed_mps
    low, high = 0.0, speed_mps
    for _ in range(60):
        middle = 0.5 * (low + high)
        if 2.0 * ramp_distance(middle, accel_mpss, jerk_mpsss) <= length_m:
            low = middle
        else:
            high = middle
    return low


def leg_time(length_m: float, speed_mps: float, accel_mpss: float, jerk_mpsss: float) -> float:
    """Seconds of a rest-to-rest leg asked to cruise at ``speed_mps`` (latency excluded)."""
    if length_m <= 0.0:
        return 0.0
    peak = peak_speed(length_m, speed_mps, accel_mpss, jerk_mpsss)
    cruise = length_m - 2.0 * ramp_distance(peak, accel_mpss, jerk_mpsss)
    return 2.0 * ramp_time(peak, accel_mpss, jerk_mpsss) + max(cruise, 0.0) / peak


def speed_for_time(length_m: float, duration_s: float, max_speed_mps: float,
                   accel_mpss: float, jerk_mpsss: float) -> float:
    """The cruise speed that flies ``length_m`` rest to rest in ``duration_s`` (at most V).

    Returns ``max_speed_mps`` when even that is too slow for the time given.
    """
    if leg_time(length_m, max_speed_mps, accel_mpss, jerk_mpsss) >= duration_s:
        return max_speed_mps
    low, high = 0.0, max_speed_mps
    for _ in range(60):
        middle = 0.5 * (low + high)
        if middle > 0 and leg_time(length_m, middle, accel_mpss, jerk_mpsss) <= duration_s:
            high = middle
        else:
            low = middle
    return high


def _jerk_segments(peak_mps: float, accel_mpss: float,
                   jerk_mpsss: float) -> list[tuple[float, float]]:
    """(duration s, jerk m/s^3) pieces of the ramp from rest to ``peak_mps``."""
    if peak_mps >= accel_mpss ** 2 / jerk_mpsss:
        rise = accel_mpss / jerk_mpsss
        hold = peak_mps / accel_mpss - rise
        return [(rise, jerk_mpsss), (hold, 0.0), (rise, -jerk_mpsss)]
    rise = math.sqrt(peak_mps / jerk_mpsss)
    return [(rise, jerk_mpsss), (rise, -jerk_mpsss)]


@dataclass(frozen=True)
class Profile:
    """Distance along a rest-to-rest leg against time: piecewise-constant jerk, integrated.

    ``knots``: (K, 4) rows of (t, s, v, a) at the start of each piece; ``jerks``: (K,).
    """

    knots: np.ndarray
    jerks: np.ndarray
    duration_s: float
    length_m: float

    @classmethod
    def rest_to_rest(cls, length_m: float, speed_mps: float, accel_mpss: float,
                     jerk_mpsss: float) -> 'Profile':
        if length_m <= 0.0:
            return cls(np.zeros((1, 4)), np.zeros(1), 0.0, 0.0)
        peak = peak_speed(length_m, speed_mps, accel_mpss, jerk_mpsss)
        start = _jerk_segments(peak, accel_mpss, jerk_mpsss)
        cruise = max(length_m - 2.0 * ramp_distance(peak, accel_mpss, jerk_mpsss), 0.0) / peak
        pieces = start + [(cruise, 0.0)] + [(d, -j) for d, j in start]
        knots, jerks = [], []
        t = s = v = a = 0.0
        for duration, jerk in pieces:
            knots.append((t, s, v, a))
            jerks.append(jerk)
            s += v * duration + a * duration ** 2 / 2 + jerk * duration ** 3 / 6
            v += a * duration + jerk * duration ** 2 / 2
            a += jerk * duration
            t += duration
        return cls(np.array(knots), np.array(jerks), t, length_m)

    def distance(self, t: np.ndarray) -> np.ndarray:
        """Metres flown at times ``t`` (s from the leg's start), clipped to [0, length]."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration_s)
        index = np.clip(np.searchsorted(self.knots[:, 0], t, side='right') - 1, 0,
                        len(self.jerks) - 1)
        t0, s0, v0, a0 = self.knots[index].T
        dt = t - t0
        s = s0 + v0 * dt + a0 * dt ** 2 / 2 + self.jerks[index] * dt ** 3 / 6
        return np.clip(s, 0.0, self.length_m)


def polyline_point(vertices: np.ndarray, distance_m: np.ndarray) -> np.ndarray:
    """Points (K, 2) at arc lengths ``distance_m`` (K,) along ``vertices`` (V, 2)."""
    steps = np.linalg.norm(np.diff(vertices, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(steps)])
    if arc[-1] <= 0.0:
        return np.repeat(vertices[:1], len(distance_m), axis=0)
    return np.column_stack([np.interp(distance_m, arc, vertices[:, axis]) for axis in (0, 1)])


@dataclass(frozen=True)
class Dwell:
    """The vehicle at rest at ``position_m`` (2,) from ``start_s`` to ``end_s``."""

    position_m: np.ndarray
    start_s: float
    end_s: float


@dataclass(frozen=True)
class Leg:
    """A rest-to-rest leg along ``vertices`` (V, 2) at cruise ``speed_mps``, starting at rest.

    ``start_s`` is when the vehicle starts moving; it moves for ``profile.duration_s``.
    """

    vertices: np.ndarray
    speed_mps: float
    start_s: float
    profile: Profile

    @property
    def end_s(self) -> float:
        return self.start_s + self.profile.duration_s

    @property
    def length_m(self) -> float:
        return self.profile.length_m


@dataclass(frozen=True)
class Flight:
    """A predicted flight: dwells and legs in time order, from the first stop's arrival."""

    parts: tuple[Dwell | Leg, ...]

    @property
    def end_s(self) -> float:
        last = self.parts[-1]
        return last.end_s

    def positions(self, times_s: Sequence[float]) -> np.ndarray:
        """Predicted positions (K, 2) metres at ``times_s`` (K,); before the start, the first
        stop; after the end, the last."""
        times = np.asarray(times_s, dtype=float)
        out = np.empty((len(times), 2))
        first = self.parts[0]
        out[:] = first.position_m if isinstance(first, Dwell) else first.vertices[0]
        for part in self.parts:
            if isinstance(part, Dwell):
                mask = times >= part.start_s
                out[mask] = part.position_m
            else:
                mask = times >= part.start_s
                out[mask] = polyline_point(part.vertices,
                                           part.profile.distance(times[mask] - part.start_s))
        return out

    def track(self) -> np.ndarray:
        """Every vertex the flight passes, in order (K, 2): the line it follows."""
        points = []
        for part in self.parts:
            points.extend([part.position_m] if isinstance(part, Dwell) else part.vertices)
        return np.array(points)
