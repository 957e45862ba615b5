"""Whether a reported position of the UAV can be true: the one check that every ``uav_pose``
and every telemetry sample passes before it reaches the mission clock.

A sample is refused when a number in it is not finite, when it lies beyond the planning
frame's coordinate range (:data:`~uav_comm_planner.core.scenario.MAX_COORDINATE_M`) or the
height range, or when it is farther from the last accepted sample than the UAV can fly in the
time between them: ``SPEED_MARGIN`` times its top ground speed (the faster of the planning speed
and the vehicle's cruise, plus the wind) times the time, plus ``POSITION_NOISE_M`` of position
noise. A real jump of the position estimate (a GPS fix after none, an EKF reset) is accepted
once ``CONFIRMING_SAMPLES`` samples in a row agree with each other by the same rule, so that a
single glitch never moves the track and a lasting new position is not refused forever.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from uav_comm_planner.core.scenario import MAX_COORDINATE_M

#: Heights beyond this, metres above home, are refused.
MAX_HEIGHT_M = 100_000.0
#: The UAV may be reported this much faster than its top ground speed (gusts, estimate lag).
SPEED_MARGIN = 2.0
#: Position noise allowed between two samples whatever their time apart, metres: an
#: autopilot's fused estimate moves by centimetres between its 10 Hz samples, so a jump of a
#: glitching GPS fix (tens of metres) stands out.
POSITION_NOISE_M = 10.0
#: Samples in a row, consistent with each other, that confirm a jump of the position.
CONFIRMING_SAMPLES = 3

Sample = tuple[float, float, float]


def reach_m(speed_mps: float, elapsed_s: float) -> float:
    """How far apart two samples ``elapsed_s`` apart may be for a UAV of ``speed_mps``."""
    return SPEED_MARGIN * speed_mps * max(elapsed_s, 0.0) + POSITION_NOISE_M


def out_of_range(time_s: float, x_m: float, y_m: float,
                 height_m: float | None = None) -> str | None:
    """Why the sample cannot be a position at all (not finite, beyond the ranges), or None."""
    values = (time_s, x_m, y_m) + (() if height_m is None else (height_m,))
    if not all(math.isfinite(v) for v in values):
        return f'position ({x_m:.6g}, {y_m:.6g}) at {time_s:.6g} s is not finite'
    if max(abs(x_m), abs(y_m)) > MAX_COORDINATE_M:
        return (f'position ({x_m:.6g}, {y_m:.6g}) is beyond the coordinate range (at most '
                f'{MAX_COORDINATE_M:g} m from the origin)')
    if height_m is not None and abs(height_m) > MAX_HEIGHT_M:
        return f'height {height_m:.6g} m is beyond +-{MAX_HEIGHT_M:g} m'
    return None


def too_far(previous: Sample, sample: Sample, speed_mps: float) -> str | None:
    """Why ``sample`` (t, x, y) cannot follow ``previous`` for a UAV of ``speed_mps``, or
    None."""
    elapsed_s = sample[0] - previous[0]
    if elapsed_s < 0:
        return f'its time {sample[0]:.6g} s is before the last sample\'s {previous[0]:.6g} s'
    distance_m = math.hypot(sample[1] - previous[1], sample[2] - previous[2])
    allowed_m = reach_m(speed_mps, elapsed_s)
    if distance_m > allowed_m:
        return (f'position ({sample[1]:.6g}, {sample[2]:.6g}) is {distance_m:.6g} m from the '
                f'last one {elapsed_s:.3g} s before, farther than the UAV flies ({allowed_m:.6g} '
                f'm at up to {SPEED_MARGIN:g} x {speed_mps:.6g} m/s plus {POSITION_NOISE_M:g} m '
                f'of noise)')
    return None


@dataclass
class PositionGate:
    """The check of every position sample (module docstring), keeping what it needs: the last
    accepted sample and the run of refused samples that agree with each other."""

    accepted: Sample | None = None
    candidates: tuple[Sample, ...] = ()

    def check(self, sample: Sample, speed_mps: float, height_m: float | None = None) -> str | None:
        """None when ``sample`` (t s, x m, y m) is accepted, else why it is refused."""
        reason = out_of_range(*sample, height_m)
        if reason is not None:
            return reason
        if self.accepted is None:
            self.accepted = sample
            return None
        reason = too_far(self.accepted, sample, speed_mps)
        if reason is None:
            self.accepted, self.candidates = sample, ()
            return None
        if self.candidates and too_far(self.candidates[-1], sample, speed_mps) is None:
            self.candidates += (sample,)
        else:
            self.candidates = (sample,)
        if len(self.candidates) >= CONFIRMING_SAMPLES:
            self.accepted, self.candidates = sample, ()
            return None
        return reason


__all__ = ['CONFIRMING_SAMPLES', 'MAX_HEIGHT_M', 'POSITION_NOISE_M', 'PositionGate',
           'SPEED_MARGIN', 'out_of_range', 'reach_m', 'too_far']
