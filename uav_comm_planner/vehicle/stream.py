"""The streamed trajectory: the plan as position, velocity and acceleration targets in time.

A waypoint mission leaves the timing between waypoints to the autopilot; a streamed
trajectory (ArduCopter GUIDED, PX4 OFFBOARD) gives the vehicle where to be at every instant,
so it keeps the plan's time by construction while the airframe can fly it. The reference here
passes through the plan's slot points (q0, q[1..M], qF; for a vehicle-aware plan the points
its stated throughput is computed at) exactly at their slot times, and between them is the
least-acceleration C1 piecewise cubic within the vehicle's speed, acceleration and jerk (and,
in wind, the plan's airspeed): :mod:`uav_comm_planner.core.smooth_motion`. When the jerk bound
cannot be kept with the points given, the reference keeps the others and says so
(``jerk_limited`` False). When the points need more acceleration than the vehicle's waypoint
acceleration, a firmware whose streamed targets are followed beyond it (PX4's OFFBOARD) gets the
least acceleration that passes them, up to :data:`STREAM_ACCEL_ALLOWANCE` times the vehicle's,
and the reference says so (``accel_raised``). Times are seconds from the start of the plan's
clock (the vehicle at q0).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math
from typing import Sequence

import numpy as np

from uav_comm_planner.core.model import flown_path
from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.core.smooth_motion import (hermite_state, least_acceleration, MotionBounds,
                                                 PIECES_PER_SLOT, smooth_motion)
from uav_comm_planner.errors import InfeasibleHorizonError
from uav_comm_planner.vehicle.limits import VehicleLimits

#: Samples per second of :meth:`StreamReference.track`.
TRACK_RATE_HZ = 10.0
#: The reference may be this much faster than the vehicle's cruise speed (share of it): a
#: smooth curve through points that the cruise speed joins along a polyline is a little longer
#: than the polyline (measured: 0.5 % over the cruise on the letter's case I at 10 m/s).
STREAM_SPEED_MARGIN = 0.05
#: How many times the vehicle's waypoint acceleration (``vehicle_max_accel_mpss``) a streamed
#: reference may ask for, by firmware. PX4's OFFBOARD follows position, velocity and
#: acceleration targets with its position controller alone: MPC_ACC_HOR shapes only the
#: trajectories PX4 makes itself (AUTO), the tilt limit MPC_TILTMAX_AIR (45 degrees by
#: default, about 9.8 m/s/s) bounds what it follows; twice MPC_ACC_HOR stays well inside it.
#: ArduCopter's GUIDED shapes the targets it is given within WPNAV_ACCEL again: nothing more.
STREAM_ACCEL_ALLOWANCE = {'ardupilot': 1.0, 'px4': 2.0}
#: The raised acceleration is the least one found times this: the conic solver's accuracy.
RAISED_ACCEL_HEADROOM = 1.02


@dataclass(frozen=True)
class StreamReference:
    """A timed reference: knot ``positions`` and ``velocities`` (K', 2) every ``knot_s``
    seconds, of which every ``pieces``-th is a plan point (slot ``slot_s``); ``bounds`` it
    keeps; ``jerk_limited`` whether the jerk bound is among them; ``accel_raised`` whether its
    acceleration bound is above the vehicle's (module docstring)."""

    positions: np.ndarray
    velocities: np.ndarray
    slot_s: float
    pieces: int
    bounds: MotionBounds
    jerk_limited: bool
    accel_raised: bool = False

    @property
    def knot_s(self) -> float:
        return self.slot_s / self.pieces

    @property
    def points(self) -> np.ndarray:
        """The plan's points (M + 2, 2): q0, q[1..M], qF."""
        return self.positions[::self.pieces]

    @property
    def duration_s(self) -> float:
        """From q0 to qF, seconds: (M + 1) delta."""
        return (len(self.positions) - 1) * self.knot_s

    def state(self, t_s: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position (m), velocity (m/s), acceleration (m/s/s) at ``t_s`` seconds after q0,
        each (len(t), 2); at rest at q0 before 0 and at qF after :attr:`duration_s`."""
        return hermite_state(self.positions, self.velocities, self.knot_s, t_s)

    def track(self, rate_hz: float = TRACK_RATE_HZ) -> np.ndarray:
        """The reference's line, sampled (K, 2) from q0 to qF."""
        count = max(int(math.ceil(self.duration_s * rate_hz)), 1) + 1
        return self.state(np.linspace(0.0, self.duration_s, count))[0]


def stream_bounds(result: PlanResult, limits: VehicleLimits, *,
                  jerk: bool = True) -> MotionBounds:
    """What the reference of ``result`` keeps: the vehicle's cruise speed (or the plan's own
    speed limit when faster) with :data:`STREAM_SPEED_MARGIN`, its acceleration and jerk, and
    in wind the plan's airspeed disc with the vehicle's gust margin (the airspeed the airframe
    holds)."""
    scenario = result.scenario
    speed = max(limits.cruise_speed_mps, scenario.max_speed_mps) * (1 + STREAM_SPEED_MARGIN)
    airspeed = (scenario.airspeed_mps + limits.gust_margin_mps if scenario.airspeed_limited
                else None)
    return MotionBounds(speed_mps=speed, accel_mpss=limits.max_accel_mpss,
                        jerk_mpsss=limits.max_jerk_mpsss if jerk else math.inf,
                        wind_mps=tuple(float(w) for w in scenario.wind_mps),
                        airspeed_mps=airspeed)


def stream_reference(result: PlanResult, limits: VehicleLimits = VehicleLimits(), *,
                     accel_allowance: float = 1.0) -> StreamReference:
    """The reference that flies ``result`` (module docstring): within the vehicle's
    acceleration, else (``accel_allowance`` > 1, :data:`STREAM_ACCEL_ALLOWANCE`) within the
    least acceleration that passes the points, at most ``accel_allowance`` times the
    vehicle's. Raises :class:`~uav_comm_planner.errors.InfeasibleHorizonError` when no motion
    within the vehicle's speed and that acceleration passes the plan's points at their
    times."""
    scenario = result.scenario
    points = flown_path(np.asarray(result.trajectory, dtype=float), scenario)
    try:
        bounds = stream_bounds(result, limits)
        positions, velocities = smooth_motion(points, scenario.slot_s, bounds)
    except InfeasibleHorizonError:
        bounds = stream_bounds(result, limits, jerk=False)
        try:
            positions, velocities = smooth_motion(points, scenario.slot_s, bounds)
        except InfeasibleHorizonError as exc:
            if accel_allowance <= 1.0:
                raise
            bounds = _raised_accel(points, scenario.slot_s, bounds, accel_allowance, exc)
            positions, velocities = smooth_motion(points, scenario.slot_s, bounds)
    return StreamReference(positions, velocities, scenario.slot_s, PIECES_PER_SLOT, bounds,
                           math.isfinite(bounds.jerk_mpsss),
                           bounds.accel_mpss > limits.max_accel_mpss)


def _raised_accel(points: np.ndarray, slot_s: float, bounds: MotionBounds, allowance: float,
                  refusal: InfeasibleHorizonError) -> MotionBounds:
    """``bounds`` with the least acceleration that passes ``points`` (with headroom), or the
    ``refusal`` said again with what it would take when that is more than ``allowance``
    times the vehicle's."""
    allowed = bounds.accel_mpss * allowance
    needed = least_acceleration(points, slot_s, bounds) * RAISED_ACCEL_HEADROOM
    if needed > allowed:
        raise InfeasibleHorizonError(
            f'{refusal}; the points need {needed:.3g} m/s/s, more than the {allowed:.3g} '
            f'm/s/s ({allowance:g} times the vehicle\'s) a stream may ask of this firmware')
    return replace(bounds, accel_mpss=needed)


def resume_item(waypoints: Sequence[tuple[int, np.ndarray]], reference: StreamReference,
                elapsed_s: float) -> int:
    """The mission item to go on from in AUTO when the stream stops ``elapsed_s`` after q0:
    the first waypoint (sequence number, east-north position) that the reference reaches
    after ``elapsed_s``, taking the waypoints in mission order; the last one when all are
    behind."""
    times = np.linspace(0.0, reference.duration_s,
                        max(int(reference.duration_s * TRACK_RATE_HZ), 1) + 1)
    line = reference.state(times)[0]
    earliest = 0
    for seq, position in waypoints:
        distance = np.linalg.norm(line[earliest:] - np.asarray(position, dtype=float), axis=1)
        earliest += int(np.argmin(distance))
        if times[earliest] > elapsed_s:
            return seq
    return waypoints[-1][0]


__all__ = ['RAISED_ACCEL_HEADROOM', 'STREAM_ACCEL_ALLOWANCE', 'STREAM_SPEED_MARGIN',
           'StreamReference', 'TRACK_RATE_HZ', 'resume_item',
           'stream_bounds', 'stream_reference']
