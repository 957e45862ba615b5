"""Catching up a timed path after the vehicle lost time on it (a held link, a pause).

A timed path p(tau) (the streamed reference, tau seconds from q0) is flown on a clock e (the
same seconds from q0). A vehicle that stopped at p(tau0) while the clock ran on to e0 > tau0 is
lag = e0 - tau0 seconds behind. It catches up by flying the same path, every point of it in
order, faster where the path is slower than the vehicle can fly: from (e0, tau0), each step
d tau of the path takes

    d e = max(|d p| / v, d tau / MAX_RATE),  v = min(max(V, |d p| / d tau), sqrt(2 A s))

of the clock (V the ground speed the vehicle holds along that step, and in a turn no more than
the speed whose turning acceleration A the vehicle has; no step slower than the path's own
pace but the first ones, where the vehicle gathers speed from rest at A over the distance s
from its hold, the step's mean speed on that ramp; a hover passed in 1 / MAX_RATE of its
time), until the lag is gone; from there on e = tau, the path's own time. The map
e -> tau(e) is a :class:`CatchUp`; the path's velocity is flown times d tau / d e, its
acceleration times its square (within the vehicle's acceleration). When the lag is not gone
by the path's end, the path cannot be caught up (None).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Callable, Sequence

import numpy as np

#: A hover (no motion) is passed this many times faster than planned, not in no time, so
#: that the map's rate stays finite.
MAX_RATE = 20.0
#: Samples of the path per second of its time.
SAMPLES_PER_S = 20.0
#: A share of the vehicle's ground speed the catch-up asks for: the rest is margin for a wind
#: the plan was not told and for the corners.
CATCH_UP_SPEED_SHARE = 0.9


@dataclass(frozen=True)
class CatchUp:
    """The path's time ``reference_s`` (K,) at clock times ``clock_s`` (K,), both increasing,
    from the resumption (clock_s[0], the path held at reference_s[0]) to the moment the lag is
    gone (clock_s[-1] == reference_s[-1]); before it the path is held, after it e = tau."""

    clock_s: np.ndarray
    reference_s: np.ndarray

    @property
    def lag_s(self) -> float:
        """The time lost at the resumption, seconds."""
        return float(self.clock_s[0] - self.reference_s[0])

    @property
    def caught_s(self) -> float:
        """The clock time at which the lag is gone."""
        return float(self.clock_s[-1])

    def reference_time(self, elapsed_s: float | np.ndarray) -> np.ndarray:
        """tau at clock times ``elapsed_s``: held before the resumption, e after the catch-up."""
        e = np.asarray(elapsed_s, dtype=float)
        inside = np.interp(e, self.clock_s, self.reference_s)
        return np.where(e >= self.clock_s[-1], e, inside)

    def rate(self, elapsed_s: float | np.ndarray) -> np.ndarray:
        """d tau / d e at clock times ``elapsed_s``: 0 before the resumption, 1 after."""
        e = np.atleast_1d(np.asarray(elapsed_s, dtype=float))
        slopes = np.diff(self.reference_s) / np.diff(self.clock_s)
        piece = np.clip(np.searchsorted(self.clock_s, e, side='right') - 1, 0, len(slopes) - 1)
        rate = slopes[piece]
        rate = np.where(e < self.clock_s[0], 0.0, rate)
        return np.where(e >= self.clock_s[-1], 1.0, rate)


def ground_speed(speed_mps: float, wind_mps: Sequence[float] = (0.0, 0.0),
                 airspeed_mps: float | None = None) -> Callable[[np.ndarray], np.ndarray]:
    """The fastest ground speed along unit directions d (K, 2): ``speed_mps``, and in wind w
    with an ``airspeed_mps`` A the speed v with ||v d - w|| = A when that is less,
    v = d . w + sqrt(A^2 - ||w||^2 + (d . w)^2)."""
    wind = np.asarray(wind_mps, dtype=float)

    def along(directions: np.ndarray) -> np.ndarray:
        fastest = np.full(len(directions), float(speed_mps))
        if airspeed_mps is None:
            return fastest
        tail = directions @ wind
        root = np.sqrt(np.maximum(airspeed_mps ** 2 - wind @ wind + tail ** 2, 0.0))
        return np.minimum(fastest, np.maximum(tail + root, 0.0))
    return along


def turn_speeds(points: np.ndarray, accel_mpss: float) -> np.ndarray:
    """The fastest speed (K - 1,) on each step of the sampled path ``points`` (K, 2) that
    keeps the turning acceleration v^2 kappa within ``accel_mpss``, kappa the curvature of the
    circle through the step's points and their neighbours (the larger at its two ends;
    straight: no limit)."""
    before, here, after = points[:-2], points[1:-1], points[2:]
    a = np.linalg.norm(here - before, axis=1)
    b = np.linalg.norm(after - here, axis=1)
    c = np.linalg.norm(after - before, axis=1)
    d1, d2 = here - before, after - here
    cross = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    spans = a * b * c
    curvature = np.where(spans > 1e-12, 2.0 * cross / np.where(spans > 1e-12, spans, 1.0), 0.0)
    ends = np.concatenate([[0.0], curvature, [0.0]])
    step = np.maximum(ends[:-1], ends[1:])
    with np.errstate(divide='ignore'):
        return np.where(step > 0.0, np.sqrt(accel_mpss / np.where(step > 0.0, step, 1.0)),
                        np.inf)


def accelerated(wanted: np.ndarray, pace: np.ndarray, lengths: np.ndarray,
                accel_mpss: float) -> np.ndarray:
    """The mean speed (K,) of each of K steps of ``lengths`` (K,) metres: at most ``wanted``
    (K,), reached from rest at the first step's start and changed between steps at no more
    than ``accel_mpss`` over their lengths (a forward pass for the speeding up, a backward one
    for the slowing down), and never below the path's own ``pace`` (K,) once the speed has
    come up to it (the path's own speed changes within the acceleration already)."""
    count = len(wanted)
    end = np.empty(count)
    mean = np.empty(count)
    floor = np.zeros(count)
    previous, ramping = 0.0, True
    for k in range(count):
        reach = math.sqrt(previous ** 2 + 2.0 * accel_mpss * lengths[k])
        speed = min(wanted[k], reach)
        ramping = ramping and speed < pace[k]
        floor[k] = 0.0 if ramping else pace[k]
        end[k] = max(speed, floor[k])
        mean[k] = (previous + end[k]) / 2.0 if end[k] >= reach else end[k]
        previous = end[k]
    following = end[-1] if count else 0.0
    for k in range(count - 2, -1, -1):
        reach = math.sqrt(following ** 2 + 2.0 * accel_mpss * lengths[k + 1])
        if end[k] > reach:
            end[k] = max(reach, floor[k])
            mean[k] = min(mean[k], end[k])
        following = end[k]
    return mean


def catch_up(position_at: Callable[[np.ndarray], np.ndarray], duration_s: float,
             held_s: float, resumed_s: float,
             speed_along: Callable[[np.ndarray], np.ndarray], *,
             accel_mpss: float | None = None) -> CatchUp | None:
    """How the path ``position_at(tau)`` ((K,) -> (K, 2) metres, tau in [0, ``duration_s``]),
    held at tau = ``held_s`` until the clock read ``resumed_s``, is caught up by a vehicle
    whose ground speed along a direction is ``speed_along`` (:func:`ground_speed`), and with
    ``accel_mpss`` in turns at most the speed whose turning acceleration that is
    (:func:`turn_speeds`) and from rest at the hold no faster than that acceleration gives
    (None: neither limit) (module docstring); None when the lag is not gone by the path's
    end."""
    held_s = min(max(float(held_s), 0.0), float(duration_s))
    lag = float(resumed_s) - held_s
    if lag <= 0.0:
        return CatchUp(np.array([resumed_s, resumed_s + 1e-9]),
                       np.array([resumed_s, resumed_s + 1e-9]))
    count = max(int(math.ceil((duration_s - held_s) * SAMPLES_PER_S)), 1) + 1
    tau = np.linspace(held_s, duration_s, count)
    step_tau = np.diff(tau)
    points = position_at(tau)
    moves = np.diff(points, axis=0)
    lengths = np.linalg.norm(moves, axis=1)
    directions = moves / np.where(lengths > 0.0, lengths, 1.0)[:, None]
    speeds = speed_along(directions)
    if accel_mpss is not None and count > 2:
        speeds = np.minimum(speeds, turn_speeds(points, accel_mpss))
    pace = lengths / step_tau
    speeds = (np.maximum(speeds, pace) if accel_mpss is None
              else accelerated(np.maximum(speeds, pace), pace, lengths, accel_mpss))
    speeds = np.maximum(speeds, 1e-9)
    step_clock = np.maximum(lengths / speeds, step_tau / MAX_RATE)
    left = lag - np.cumsum(step_tau - step_clock)
    gone = np.flatnonzero(left <= 0.0)
    if len(gone) == 0:
        return None
    last = int(gone[0])
    # The last step ends exactly on the path's own time.
    behind = np.maximum(left[:last + 1], 0.0)
    clock = np.concatenate([[float(resumed_s)], tau[1:last + 2] + behind])
    return CatchUp(clock, tau[:last + 2].copy())


__all__ = ['CATCH_UP_SPEED_SHARE', 'CatchUp', 'MAX_RATE', 'SAMPLES_PER_S', 'catch_up',
           'accelerated', 'ground_speed', 'turn_speeds']
