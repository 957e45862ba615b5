"""How long the autopilot takes to fly a leg, and where it is meanwhile.

ArduCopter flies a waypoint leg from rest to rest along ArduPilot's SCurve: the jerk rises to
the jerk limit J as a raised cosine over the jerk time tj (2 ATC_INPUT_TC, 0.3 s by default),
holds, falls the same way, so that the acceleration reaches the limit A; the speed then rises
at A to the cruise speed V, and the stop mirrors the start. Reaching V from rest takes
V / A + A / J + tj seconds over V (V / A + A / J + tj) / 2 metres (when V >= A (A / J + tj)), so
a leg of length L reaches at most the speed V with L = V (V / A + A / J + tj), and a leg flown at
V takes L / V + V / A + A / J + tj seconds. Shorter legs and lower speeds use the reduced
profiles SCurve::calculate_path chooses; :func:`scurve_pieces` follows it branch by branch. PX4
missions are timed with the same profile and its own limits.

A point where the flight turns by a few degrees is flown through without slowing; a hover is a
stop. So a flight is a chain of stops (:class:`Dwell`) joined by legs (:class:`Leg`), each leg a
polyline flown at one cruise speed from rest to rest; :class:`Flight` gives the position at any
time. ``LEG_LATENCY_S`` is what ArduCopter adds to each leg between the end of one hold and the
start of the next (the vehicle settling into the waypoint radius behind its target, and the
mission starting the next leg), measured on ArduCopter 4.7 software-in-the-loop: 0.4 to 1.0 s
over legs of 99 to 400 m.
"""

from __future__ import annotations

from dataclasses import dataclass
import functools
import math
from typing import Callable, Sequence

import numpy as np

from uav_comm_planner.vehicle.limits import VehicleLimits

#: Seconds ArduCopter adds to a rest-to-rest leg beyond its S-curve (see the module docstring).
LEG_LATENCY_S = 0.7
#: Kinds of jerk piece: constant, raised-cosine rise, raised-cosine fall.
CONSTANT, RISE, FALL = 0, 1, 2


@functools.lru_cache(maxsize=4096)
def _largest_peak(half_m: float, accel: float, jerk: float, tj: float) -> float:
    """Bisection: the largest peak acceleration a <= ``accel`` whose ramp a (a / J + tj)^2
    fits in half a leg (the same for every speed asked of the leg, so it is kept)."""
    low, high = 0.0, accel
    for _ in range(100):
        middle = 0.5 * (low + high)
        if middle * (middle / jerk + tj) ** 2 < half_m:
            low = middle
        else:
            high = middle
    return 0.5 * (low + high)


def _ramp_shape(length_m: float, speed_mps: float,
                limits: VehicleLimits) -> tuple[float, float, float, float, float]:
    """SCurve::calculate_path for a rest-to-rest leg: (J, tj, t2, t4, t15) seconds.

    t2: constant jerk inside each jerk pulse; t4: constant acceleration; t15: cruise.
    """
    accel, jerk, tj = limits.max_accel_mpss, limits.max_jerk_mpsss, limits.jerk_time_s
    snap = jerk * math.pi / (2.0 * tj)
    half = 0.5 * length_m
    reachable = min(accel, speed_mps / (2.0 * tj), half / (4.0 * tj * tj))
    if reachable <= 0.0:
        return jerk, tj, 0.0, 0.0, 0.0
    if reachable < jerk * tj:
        # Too short or too slow for a full jerk pulse: a shorter tj, the same snap.
        tj = min(tj, (half * math.pi / (8 * snap)) ** 0.25,
                 (speed_mps * math.pi / (4 * snap)) ** (1 / 3),
                 math.sqrt(accel * math.pi / (2 * snap)))
        jerk = 2 * snap * tj / math.pi
        accel = jerk * tj
        t2 = 0.0
        c = accel / jerk + tj
        t4 = 0.0 if (speed_mps <= 2 * accel * tj or half <= 4 * accel * tj * tj) else max(
            0.0, min((speed_mps - accel * c) / accel,
                     0.5 * (-3 * c + math.sqrt(c * c + 8 * half / accel))))
    else:
        c = accel / jerk + tj
        if speed_mps < accel * c or half < accel * c * c:
            # The acceleration limit is not reached: the largest peak that fits.
            by_speed = 0.5 * jerk * (math.sqrt(tj * tj + 4 * speed_mps / jerk) - tj)
            accel = min(accel, by_speed, _largest_peak(half, accel, jerk, tj))
            t2, t4 = accel / jerk - tj, 0.0
        else:
            t2 = accel / jerk - tj
            t4 = max(0.0, min((speed_mps - accel * c) / accel,
                              0.5 * (-3 * c + math.sqrt(c * c + 8 * half / accel))))
    c = accel / jerk + tj
    peak = accel * (c + t4)
    t15 = max(0.0, (length_m - peak * (2 * c + t4)) / peak)
    return jerk, tj, t2, t4, t15


def scurve_pieces(length_m: float, speed_mps: float,
                  limits: VehicleLimits) -> list[tuple[float, int, float]]:
    """The leg's jerk pieces in order: (duration s, kind, peak jerk m/s^3)."""
    jerk, tj, t2, t4, t15 = _ramp_shape(length_m, speed_mps, limits)
    up = [(tj, RISE, jerk), (t2, CONSTANT, jerk), (tj, FALL, jerk)]
    down = [(d, kind, -j) for d, kind, j in up]
    return (up + [(t4, CONSTANT, 0.0)] + down + [(t15, CONSTANT, 0.0)] + down
            + [(t4, CONSTANT, 0.0)] + up)


def _advance(kind: int, jerk: float, duration: float, x, a, v, s):
    """State (a, v, s) after ``x`` seconds of a piece that starts in state (a, v, s)."""
    if kind == CONSTANT or duration <= 0.0:
        return (a + jerk * x, v + a * x + jerk * x ** 2 / 2,
                s + v * x + a * x ** 2 / 2 + jerk * x ** 3 / 6)
    b, h = math.pi / duration, jerk / 2
    sign = -1.0 if kind == RISE else 1.0
    return (a + h * x + sign * (h / b) * np.sin(b * x),
            v + a * x + h * x ** 2 / 2 + sign * (h / b ** 2) * (1 - np.cos(b * x)),
            s + v * x + a * x ** 2 / 2 + h * x ** 3 / 6
            + sign * (h / b ** 2) * (x - np.sin(b * x) / b))


def leg_time(length_m: float, speed_mps: float, limits: VehicleLimits) -> float:
    """Seconds of a rest-to-rest leg asked to cruise at ``speed_mps`` (latency excluded)."""
    if length_m <= 0.0:
        return 0.0
    _, tj, t2, t4, t15 = _ramp_shape(length_m, speed_mps, limits)
    # The durations of scurve_pieces' pieces, summed in their order as sum() sums them.
    return sum((tj, t2, tj, t4, tj, t2, tj, t15, tj, t2, tj, t4, tj, t2, tj))


def ramp_time(speed_mps: float, limits: VehicleLimits) -> float:
    """Seconds from rest to ``speed_mps``: V / A + A / J + tj when the full ramp is needed."""
    accel, jerk, tj = limits.max_accel_mpss, limits.max_jerk_mpsss, limits.jerk_time_s
    if speed_mps >= accel * (accel / jerk + tj):
        return speed_mps / accel + accel / jerk + tj
    return tj + math.sqrt(tj * tj + 4 * speed_mps / jerk)


def ramp_distance(speed_mps: float, limits: VehicleLimits) -> float:
    """Metres flown while going from rest to ``speed_mps``: the ramp is symmetric, V t / 2."""
    return 0.5 * speed_mps * ramp_time(speed_mps, limits)


def peak_speed(length_m: float, speed_mps: float, limits: VehicleLimits) -> float:
    """The fastest a rest-to-rest leg of ``length_m`` flies when asked for ``speed_mps``."""
    jerk, tj, t2, t4, _ = _ramp_shape(length_m, speed_mps, limits)
    accel = jerk * (t2 + tj)
    return accel * (accel / jerk + tj + t4)


def slowest_speed_for(seconds_at: Callable[[float], float], duration_s: float,
                      max_speed_mps: float, *, tolerance_mps: float = 1e-12) -> float:
    """The slowest speed v <= ``max_speed_mps`` with ``seconds_at(v)`` <= ``duration_s``, to
    ``tolerance_mps`` (``seconds_at`` falling with the speed); ``max_speed_mps`` when even that
    is too slow for the time given.

    A leg takes about a + b / v seconds at cruise v, so the speed is searched in 1 / v: each
    guess is the speed at which the line through the bracket's ends in (1 / v, seconds) meets
    ``duration_s`` (at first, with only the top speed timed, a = 0), kept half a tolerance
    inside the bracket so that the bracket closes from both sides, and a bisection whenever
    two guesses have not halved it; a few timings where a bisection takes dozens (``seconds_at``
    is a simulation of the autopilot for PX4).
    """
    top = seconds_at(max_speed_mps)
    if top >= duration_s:
        return max_speed_mps
    low, high = 0.0, max_speed_mps               # seconds_at(low) > duration_s >= at high
    low_s, high_s = math.inf, top
    widths = [math.inf, math.inf]
    while high - low > tolerance_mps:
        if math.isinf(low_s):
            guess = high * high_s / duration_s
        else:
            share = (duration_s - high_s) / (low_s - high_s)
            guess = 1.0 / (1.0 / high + share * (1.0 / low - 1.0 / high))
        if high - low > 0.5 * widths[-2]:
            guess = 0.5 * (low + high)
        half = 0.5 * tolerance_mps
        guess = min(max(guess, low + half), high - half)
        seconds = seconds_at(guess)
        if seconds <= duration_s:
            high, high_s = guess, seconds
        else:
            low, low_s = guess, seconds
        widths.append(high - low)
    return high


def speed_for_time(length_m: float, duration_s: float, max_speed_mps: float,
                   limits: VehicleLimits) -> float:
    """The cruise speed that flies ``length_m`` rest to rest in ``duration_s`` (at most V).

    Returns ``max_speed_mps`` when even that is too slow for the time given.
    """
    return slowest_speed_for(lambda speed: leg_time(length_m, speed, limits), duration_s,
                             max_speed_mps)


@dataclass(frozen=True)
class Profile:
    """Distance along a rest-to-rest leg against time, from its jerk pieces.

    ``knots``: (K, 4) rows of (t, s, v, a) at the start of each piece; ``pieces``: (K, 3) rows
    of (duration, kind, jerk).
    """

    knots: np.ndarray
    pieces: np.ndarray
    duration_s: float
    length_m: float

    @classmethod
    def rest_to_rest(cls, length_m: float, speed_mps: float,
                     limits: VehicleLimits) -> 'Profile':
        if length_m <= 0.0:
            return cls(np.zeros((1, 4)), np.array([[0.0, CONSTANT, 0.0]]), 0.0, 0.0)
        pieces = [piece for piece in scurve_pieces(length_m, speed_mps, limits) if piece[0] > 0]
        knots = []
        t = s = v = a = 0.0
        for duration, kind, jerk in pieces:
            knots.append((t, s, v, a))
            a, v, s = _advance(kind, jerk, duration, duration, a, v, s)
            t += duration
        return cls(np.array(knots), np.array(pieces, dtype=float), t, length_m)

    def distance(self, t: np.ndarray) -> np.ndarray:
        """Metres flown at times ``t`` (s from the leg's start), clipped to [0, length]."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration_s)
        index = np.clip(np.searchsorted(self.knots[:, 0], t, side='right') - 1, 0,
                        len(self.pieces) - 1)
        t0, s0, v0, a0 = self.knots[index].T
        out = np.empty_like(t)
        for number, (duration, kind, jerk) in enumerate(self.pieces):
            mask = index == number
            if mask.any():
                out[mask] = _advance(int(kind), jerk, duration, t[mask] - t0[mask], a0[mask],
                                     v0[mask], s0[mask])[2]
        return np.clip(out, 0.0, self.length_m)


def polyline_point(vertices: np.ndarray, distance_m: np.ndarray) -> np.ndarray:
    """Points (K, 2) at arc lengths ``distance_m`` (K,) along ``vertices`` (V, 2)."""
    steps = np.linalg.norm(np.diff(vertices, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(steps)])
    if arc[-1] <= 0.0:
        return np.repeat(vertices[:1], len(distance_m), axis=0)
    return np.column_stack([np.interp(distance_m, arc, vertices[:, axis]) for axis in (0, 1)])


def along_track_heights(vertices: np.ndarray, heights: np.ndarray,
                        distance_m: np.ndarray) -> np.ndarray:
    """The altitude at horizontal arc lengths ``distance_m`` along a leg whose waypoints
    ``vertices`` (V, 2) are at ``heights`` (V,): linear in the horizontal progress along each
    segment, as a straight 3D segment is."""
    steps = np.linalg.norm(np.diff(vertices, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(steps)])
    if arc[-1] <= 0.0:
        return np.full(len(np.atleast_1d(distance_m)), float(heights[-1]))
    return np.interp(distance_m, arc, heights)


@dataclass(frozen=True)
class Dwell:
    """The vehicle at rest at ``position_m`` (2,) from ``start_s`` to ``end_s``, at
    ``altitude_m`` (None: the plan's one altitude)."""

    position_m: np.ndarray
    start_s: float
    end_s: float
    altitude_m: float | None = None


@dataclass(frozen=True)
class Leg:
    """A rest-to-rest leg along ``vertices`` (V, 2) at cruise ``speed_mps``, starting at rest.

    ``start_s`` is when the vehicle starts moving; it moves for ``profile.duration_s``.
    ``altitudes_m`` (V,): the vertices' altitudes (None: the plan's one altitude); the profile
    is then the horizontal motion (:mod:`.climbs`).
    """

    vertices: np.ndarray
    speed_mps: float
    start_s: float
    profile: Profile
    altitudes_m: np.ndarray | None = None

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

    def altitudes(self, times_s: Sequence[float]) -> np.ndarray | None:
        """Predicted altitudes (K,) metres at ``times_s`` (K,), as :meth:`positions` places the
        vehicle; None for a flight at the plan's one altitude."""
        if any((part.altitude_m if isinstance(part, Dwell) else part.altitudes_m) is None
               for part in self.parts):
            return None
        times = np.asarray(times_s, dtype=float)
        first = self.parts[0]
        out = np.full(len(times), first.altitude_m if isinstance(first, Dwell)
                      else float(first.altitudes_m[0]))
        for part in self.parts:
            mask = times >= part.start_s
            if isinstance(part, Dwell):
                out[mask] = part.altitude_m
            else:
                out[mask] = along_track_heights(
                    part.vertices, part.altitudes_m,
                    part.profile.distance(times[mask] - part.start_s))
        return out

    def track(self) -> np.ndarray:
        """Every vertex the flight passes, in order (K, 2): the line it follows."""
        points = []
        for part in self.parts:
            points.extend([part.position_m] if isinstance(part, Dwell) else part.vertices)
        return np.array(points)
