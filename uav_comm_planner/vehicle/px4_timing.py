"""How long PX4 takes to fly a mission leg, and where it is meanwhile.

PX4 (v1.16, multicopter, AUTO.MISSION) does not plan a leg ahead as ArduCopter does. Every
cycle its trajectory generator (FlightTaskAuto with PositionSmoothing) asks for a speed
towards the current waypoint and follows it with a jerk-limited velocity profile:

- **The speed asked for** is the cruise V (MPC_XY_CRUISE, or the mission's DO_CHANGE_SPEED),
  cut to the fastest speed from which the vehicle can still slow down to the speed wanted at
  the waypoint in the distance d left: v(d, v_e) = (-b + sqrt(b^2 + 8 A d + 4 v_e^2)) / 2 with
  b = 4 A^2 / J (TrajMath's computeMaxSpeedFromDistance), A = MPC_ACC_HOR, J = MPC_JERK_AUTO.
  Near a stop v(d, 0) ~ J d / (2 A): the last metres decay exponentially with the time
  constant 2 A / J (1.5 s at PX4's defaults).
- **At a fly-through waypoint** (no hold) the speed wanted there is
  sqrt(P A R tan(alpha / 2)), alpha the interior angle of the turn, R the acceptance radius
  (NAV_ACC_RAD, 2 m), P = MPC_XY_TRAJ_P (0.5), and no more than the vehicle can stop from on
  the next segment; the next waypoint becomes the target as soon as the vehicle is within R.
  A turn of 10 degrees at R = 2 m caps the speed at 5.9 m/s, one of 20 at 4.1. A turn whose
  cap is above the cruise costs nothing on the SITL (legs of 15 turns of 1-11 degrees at
  5 m/s were flown at the cruise): the vehicle brakes only for the next turn it cannot take
  at the cruise, or for the stop.
- **The velocity profile** changes the velocity with jerk J up to the acceleration A, per
  axis of the local frame, the axes synchronised: along a leg at heading h the acceleration
  and jerk reach A / c and J / c, c = max(|cos h|, |sin h|).
- **The cruise it holds** is below V: PX4 slows the trajectory's clock by 1 - e / E when the
  vehicle is a distance e behind it (E = MPC_XY_ERR_MAX, 2 m; PositionSmoothing's time
  stretch). The vehicle trails the trajectory by about ``TRACKING_LAG_S`` x its speed, so it
  cruises at V (1 - TRACKING_LAG_S V / E): 4.94 at 5 m/s, 9.78 at 10 m/s, as on the SITL.
- **A hold** (the waypoint's param1) starts counting when the vehicle enters the acceptance
  radius, still braking (mission_block's is_mission_item_reached_or_completed): it enters it
  at 2.3-3 m/s, ahead of the braking curve (``BRAKING_LEAD_S2``); when the hold ends the next
  leg starts, after ``START_DELAY_S`` (the vehicle moving off more slowly than its
  trajectory). PX4 reports the waypoint reached then, and a fly-through waypoint (hold 0) on
  entering the radius.

:func:`px4_profile` simulates this along a leg's polyline (the distance flown against time,
from rest at its first vertex to rest at its last) at ``STEP_S``; it gives the leg's duration
and ``hold_start_s``, when the hold at its end starts counting. The constants PX4's source
does not fix are fitted to flights on PX4 v1.16 SITL (SIH quadrotor), named where defined.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache
import math

import numpy as np

from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.timing import slowest_speed_for

#: NAV_ACC_RAD, metres: PX4's default acceptance radius for multicopters (a waypoint's param2
#: = 0), where the vehicle's limits do not give theirs (a parameter file's NAV_ACC_RAD).
ACCEPTANCE_RADIUS_M = 2.0
#: Metres a hovering vehicle may be from its stop when its hold ends: a next stop within the
#: acceptance radius plus this may be reported reached at once, before any leg is flown (a
#: 2.0 m leg flown on PX4 SITL was: its stop's hold began 2.2 s before the model's time, and
#: every later point flew that much early, the worst 0.98 slot).
HOVER_WANDER_M = 1.0
#: MPC_XY_TRAJ_P: the share of MPC_ACC_HOR a fly-through turn is flown with.
TRAJECTORY_GAIN = 0.5
#: MPC_XY_ERR_MAX, metres: the lag at which PX4 stops the trajectory's clock.
MAX_POSITION_ERROR_M = 2.0
#: Seconds the vehicle trails the trajectory by (its lag e = TRACKING_LAG_S x speed), fitted
#: to the cruise PX4 SITL holds along straight legs: 4.90-4.95 m/s at 5, 9.74-9.83 at 10.
TRACKING_LAG_S = 0.0045
#: The vehicle brakes later than its trajectory and runs ahead of it: it enters a waypoint's
#: acceptance radius when the trajectory is still BRAKING_LEAD_S2 x V^2 further out (V the
#: leg's cruise; s^2/m). Fitted to when PX4 SITL reports a stop reached (the vehicle 2 m from
#: it along the leg), from the end of the hold before: over 25 legs of 150-820 m flown
#: (case I at 5 and 10 m/s, six random nodes at 5), 0.03 left the legs at 10 m/s 0.36 s
#: longer than the model (mean; -0.6 to +1.2 s by leg) and those at 5 m/s or less 0.13 s; 0.022
#: leaves -0.01 and +0.01. It holds the braking's time, not its shape: the model enters the
#: radius at 1.6 m/s at 5 and 2.4 at 10, PX4 SITL at 2.0-2.4 and 2.7-2.9 (the braking curve
#: alone gives 1.2).
BRAKING_LEAD_S2 = 0.022
#: Seconds from the end of a hold to the start of the next leg, fitted to PX4 SITL: the vehicle
#: moves off more slowly than its trajectory (its first 80 m from rest took 0.9-2.0 s longer
#: than the limits give, at 5 and at 10 m/s alike), taken as a delay; with it and
#: BRAKING_LEAD_S2, the 25 legs named there reach their ends within -1.0..+0.9 s of the model.
START_DELAY_S = 1.7
#: The simulation's step, seconds (PX4's position controller runs at 50 Hz or faster).
STEP_S = 0.02
#: The leg ends (the vehicle at rest) when it is this close to its last vertex, metres.
REST_DISTANCE_M = 0.1


def stopping_speed(distance_m: float, end_speed_mps: float, accel: float, jerk: float) -> float:
    """The fastest speed from which the vehicle slows to ``end_speed_mps`` within
    ``distance_m`` (PX4's braking curve, module docstring)."""
    b = 4.0 * accel * accel / jerk
    return 0.5 * (-b + math.sqrt(b * b + 8.0 * accel * max(distance_m, 0.0)
                                 + 4.0 * end_speed_mps * end_speed_mps))


def corner_speed(interior_rad: float, accel: float, radius_m: float = ACCEPTANCE_RADIUS_M,
                 gain: float = TRAJECTORY_GAIN) -> float:
    """The speed PX4 flies a fly-through waypoint at: sqrt(P A R tan(alpha / 2))."""
    alpha = min(max(interior_rad, 0.0), math.pi - 1e-6)
    return math.sqrt(gain * accel * radius_m * math.tan(alpha / 2.0))


def _velocity_step(a: float, v: float, target: float, accel: float, jerk: float,
                   dt: float) -> tuple[float, float, float]:
    """(a, v, ds) after ``dt`` of the time-optimal jerk-limited change of the velocity from
    (a, v) towards ``target``: jerk +-J up to the acceleration A, constant acceleration,
    jerk -+J down to zero acceleration as the velocity reaches the target. (Written out piece
    by piece: a leg's simulation takes thousands of these.)"""
    # The velocity reached if the acceleration is brought to zero at once.
    settle = v + a * abs(a) / (2.0 * jerk)
    if target > settle or (target == settle and a > 0):
        direction = 1.0
    elif target < settle or a < 0:
        direction = -1.0
    else:
        return 0.0, v, v * dt
    j = direction * jerk
    dv = target - v
    peak_sq = 0.5 * (2.0 * j * dv + a * a) if j * dv + 0.5 * a * a >= 0 else 0.0
    root = math.sqrt(peak_sq) if peak_sq > 0.0 else 0.0
    peak = direction * (root if root < accel else accel)
    t1 = (peak - a) / j
    t1 = t1 if t1 > 0.0 else 0.0
    t3 = peak / j
    t3 = t3 if t3 > 0.0 else 0.0
    v1 = v + a * t1 + 0.5 * j * t1 * t1
    v3_gain = peak * t3 - 0.5 * j * t3 * t3
    if abs(peak) > 1e-12:
        t2 = (target - v1 - v3_gain) / peak
        t2 = t2 if t2 > 0.0 else 0.0
    else:
        t2 = 0.0
    # Jerk j for t1, none for t2, -j for t3, then at the target velocity.
    x = dt if dt <= t1 else t1
    ds = v * x + 0.5 * a * x * x + j * x ** 3 / 6.0
    v += a * x + 0.5 * j * x * x
    a += j * x
    left = dt - x
    if left > 0.0:
        x = left if left <= t2 else t2
        ds += v * x + 0.5 * a * x * x
        v += a * x
        left -= x
        if left > 0.0:
            x = left if left <= t3 else t3
            ds += v * x + 0.5 * a * x * x + -j * x ** 3 / 6.0
            v += a * x + 0.5 * -j * x * x
            a += -j * x
            left -= x
            if left > 0.0:
                a = 0.0
                ds += v * left
    return a, v, ds


@dataclass(frozen=True)
class SampledProfile:
    """Distance flown along a leg against time, sampled: ``times_s`` (K,), ``distances_m``
    (K,) from the leg's start; ``duration_s`` until at rest at the end, ``hold_start_s`` when
    the vehicle enters the acceptance radius of the leg's last vertex (the hold there starts
    counting)."""

    times_s: np.ndarray
    distances_m: np.ndarray
    duration_s: float
    length_m: float
    hold_start_s: float

    def distance(self, t: np.ndarray) -> np.ndarray:
        """Metres flown at times ``t`` (s from the leg's start), clipped to [0, length]."""
        return np.clip(np.interp(np.asarray(t, dtype=float), self.times_s, self.distances_m),
                       0.0, self.length_m)


def px4_profile(vertices: np.ndarray, speed_mps: float, limits: VehicleLimits) -> SampledProfile:
    """PX4's flight along ``vertices`` (V, 2) from rest to rest at cruise ``speed_mps``, fly-
    through waypoints at the inner vertices (module docstring), with the vehicle's acceptance
    radius, turn gain and largest tracking error (``limits``; PX4's defaults
    :data:`ACCEPTANCE_RADIUS_M`, :data:`TRAJECTORY_GAIN`, :data:`MAX_POSITION_ERROR_M` where
    they are None)."""
    return _simulate(*_key(vertices, speed_mps, limits))


def _key(vertices: np.ndarray, speed_mps: float, limits: VehicleLimits) -> tuple:
    """A leg's simulation by what it depends on (cached)."""
    vertices = np.asarray(vertices, dtype=float)
    return (vertices.round(6).tobytes(), len(vertices), round(float(speed_mps), 6),
            float(limits.max_accel_mpss), float(limits.max_jerk_mpsss), _shape(limits))


def _shape(limits: VehicleLimits) -> tuple[float, float, float]:
    """The acceptance radius, turn gain and largest tracking error a leg is timed with:
    ``limits``' own, PX4's defaults where they are None."""
    return (acceptance_radius(limits),
            TRAJECTORY_GAIN if limits.turn_gain is None else float(limits.turn_gain),
            MAX_POSITION_ERROR_M if limits.max_position_error_m is None
            else float(limits.max_position_error_m))


def acceptance_radius(limits: VehicleLimits) -> float:
    """The vehicle's acceptance radius, metres: ``limits.acceptance_radius_m``, else
    :data:`ACCEPTANCE_RADIUS_M`."""
    return (ACCEPTANCE_RADIUS_M if limits.acceptance_radius_m is None
            else float(limits.acceptance_radius_m))


def timed_limits(limits: VehicleLimits) -> VehicleLimits:
    """``limits`` as a plan is timed with them: PX4's acceptance radius, turn gain and largest
    tracking error where they are unset (None) given PX4's defaults."""
    radius, gain, most_error = _shape(limits)
    return replace(limits, acceptance_radius_m=radius, turn_gain=gain,
                   max_position_error_m=most_error)


def shortest_leg_m(limits: VehicleLimits) -> float:
    """The shortest leg PX4 flies as one, metres: a stop closer to the one before may be
    reached before the leg starts (:data:`HOVER_WANDER_M`), so the two are one stop."""
    return acceptance_radius(limits) + HOVER_WANDER_M


@lru_cache(maxsize=4096)
def _simulate(vertex_bytes: bytes, count: int, speed: float, accel: float,
              jerk: float, shape: tuple[float, float, float]) -> SampledProfile:
    return _flown(vertex_bytes, count, speed, accel, jerk, shape)


@lru_cache(maxsize=4096)
def _reach_time(vertex_bytes: bytes, count: int, speed: float, accel: float,
                jerk: float, shape: tuple[float, float, float]) -> float:
    """:attr:`SampledProfile.hold_start_s` of the leg, its simulation ended there (the
    vehicle's last metres to rest, a slow exponential approach, are most of a leg's steps and
    do not move it)."""
    return _flown(vertex_bytes, count, speed, accel, jerk, shape, until_reached=True)


def _flown(vertex_bytes: bytes, count: int, speed: float, accel: float, jerk: float,
           shape: tuple[float, float, float],
           until_reached: bool = False) -> SampledProfile | float:
    """The simulation of :func:`px4_profile` with ``shape``: the acceptance radius (m), the
    turn gain (MPC_XY_TRAJ_P) and the largest tracking error (MPC_XY_ERR_MAX, m); with
    ``until_reached`` only up to the entry into the last vertex's acceptance radius, and only
    that time."""
    radius, gain, most_error = shape
    vertices = np.frombuffer(vertex_bytes).reshape(count, 2)
    steps = np.diff(vertices, axis=0)
    lengths = np.linalg.norm(steps, axis=1)
    keep = np.concatenate([[True], lengths > 1e-9])
    vertices = vertices[keep]
    steps = np.diff(vertices, axis=0)
    lengths = np.linalg.norm(steps, axis=1)
    if len(lengths) == 0:
        zero = np.zeros(1)
        return 0.0 if until_reached else SampledProfile(zero, zero, 0.0, 0.0, 0.0)
    arc = np.concatenate([[0.0], np.cumsum(lengths)])
    total = float(arc[-1])
    units = steps / lengths[:, None]
    # Per segment: the along-track limits (axes synchronised) and the speed wanted at its end.
    scale = 1.0 / np.maximum(np.abs(units).max(axis=1), 1e-9)
    ends = np.zeros(len(lengths))
    for k in range(len(lengths) - 1):
        interior = math.acos(float(np.clip(-units[k] @ units[k + 1], -1.0, 1.0)))
        after = stopping_speed(float(lengths[k + 1]), 0.0, accel, jerk)
        if lengths[k + 1] > radius:
            ends[k] = min(corner_speed(interior, accel, radius, gain), after, speed)
    # The segment braked for from segment k on: the first turn PX4 cannot fly at the cruise,
    # or the last segment (the stop).
    last = len(lengths) - 1
    braked_for = [last] * len(lengths)
    for j in range(last - 1, -1, -1):
        braked_for[j] = j if ends[j] < speed else braked_for[j + 1]
    # Python floats: the loop below runs thousands of steps a leg, each on a few of them.
    arc, ends, scale = arc.tolist(), ends.tolist(), scale.tolist()
    b = 4.0 * accel * accel / jerk
    # stopping_speed's terms, and the names the loop reads, bound once.
    b_squared, eight_accel = b * b, 8.0 * accel
    end_terms = [4.0 * end * end for end in ends]
    sqrt, lag, step = math.sqrt, TRACKING_LAG_S, _velocity_step
    times, distances = [0.0], [0.0]
    t = s = v = a = 0.0               # the trajectory: along-track distance, speed, accel
    x = u = 0.0                       # the vehicle following it
    k = 0                             # flying towards vertex k + 1
    hold_start = None
    dt = STEP_S
    reach = radius + BRAKING_LEAD_S2 * speed * speed
    while True:
        while k < last and arc[k + 1] - x <= reach:
            k += 1
        if hold_start is None and k == last and total - x <= reach:
            hold_start = t
            if until_reached:
                return hold_start
        # Turns PX4 flies at the cruise cost nothing; brake for the next one it cannot.
        slow = braked_for[k]
        left = arc[slow + 1] - s
        if (hold_start is not None and abs(total - x) <= REST_DISTANCE_M and abs(u) < 0.05
                and abs(v) < 0.05):
            break
        # min(speed, stopping_speed(left, ends[slow], accel, jerk)), written out.
        wanted = 0.5 * (-b + sqrt(b_squared + eight_accel * (left if left >= 0.0 else 0.0)
                                  + end_terms[slow]))
        if wanted >= speed:
            wanted = speed
        behind = lag * v
        x = s - behind
        error = behind / most_error
        stretch = 1.0 - (0.0 if error < 0.0 else 1.0 if error > 1.0 else error)
        if wanted >= speed and abs(v - speed) < 1e-6 and a == 0.0:
            # Cruising, settled: jump to where the braking curve falls below the cruise (the
            # trajectory and the vehicle move at constant speeds until then).
            brake_at = (speed * speed + speed * b - ends[slow] ** 2) / (2.0 * accel)
            jump = left - brake_at - 2.0 * speed * dt
            if hold_start is None and slow == last:
                # Nor past the last vertex's acceptance radius (below about 1.2 m/s PX4
                # brakes inside it): the steps find when the vehicle enters it.
                jump = min(jump, total - reach - x - 2.0 * speed * dt)
            if jump > speed * dt:
                t += jump / (speed * stretch)
                s += jump
                x += jump
                times.append(t)
                distances.append(x)
                continue
        a, v, ds = step(a, v, wanted, accel * scale[k], jerk * scale[k], dt * stretch)
        s += ds
        if s > total:
            s = total
        u = v * stretch
        x = s - lag * v
        t += dt
        times.append(t)
        distances.append(x)
        if t > 1e6:
            raise ArithmeticError(f'PX4 leg of {total:g} m at {speed:g} m/s does not end')
    return SampledProfile(np.array(times), np.clip(np.array(distances), 0.0, total), t, total,
                          hold_start)


def px4_leg_time(vertices: np.ndarray, speed_mps: float, limits: VehicleLimits) -> float:
    """Seconds PX4 moves along ``vertices`` from rest to rest at cruise ``speed_mps``."""
    return px4_profile(vertices, speed_mps, limits).duration_s


def px4_reach_time(vertices: np.ndarray, speed_mps: float, limits: VehicleLimits) -> float:
    """Seconds from rest at the first of ``vertices`` into the acceptance radius of the last,
    at cruise ``speed_mps``: when PX4 reports the leg's end reached."""
    return _reach_time(*_key(vertices, speed_mps, limits))


def px4_speed_for_time(vertices: np.ndarray, duration_s: float, max_speed_mps: float,
                       limits: VehicleLimits) -> float:
    """The cruise (to 0.005 m/s) that reaches the end of ``vertices`` from rest
    (:func:`px4_reach_time`) in ``duration_s`` or less; ``max_speed_mps`` when even that is
    too slow."""
    return slowest_speed_for(lambda speed: px4_reach_time(vertices, speed, limits), duration_s,
                             max_speed_mps, tolerance_mps=0.005)


__all__ = ['ACCEPTANCE_RADIUS_M', 'HOVER_WANDER_M', 'SampledProfile', 'acceptance_radius',
           'corner_speed', 'px4_leg_time', 'px4_profile', 'px4_reach_time', 'px4_speed_for_time',
           'shortest_leg_m', 'stopping_speed', 'timed_limits']
