"""What a flight delivered: a recorded track held against the plan it flew.

A plan is worth what the nodes receive when the vehicle flies it. Given the positions a
vehicle reported (autopilot time, planning frame) and the moment the plan's clock started
(the vehicle at q0), :func:`evaluate_flight` measures

- when each planned point was reached: the recorded time nearest to the point's planned time
  at which the vehicle was within ``radius_m`` of it (a hover point is reached all the while
  the vehicle hovers there);
- the cross-track error: the largest distance of the track from the planned line;
- the throughput the plan's power schedule gives at the positions flown at the planned slot
  times, R_n = (1/T) sum_m delta (B/N) log2(1 + p_n[m] a_n(x(t0 + m delta))), against the
  throughput the plan states.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uav_comm_planner.core.model import average_rates, flown_path, vector_lengths
from uav_comm_planner.core.optimizer import PlanResult

#: A planned point counts as reached within this distance (ArduCopter's WPNAV_RADIUS).
REACH_RADIUS_M = 2.0


@dataclass(frozen=True)
class FlightReport:
    """A flight against its plan; times in seconds, distances in metres, rates in bit/s.

    reach_errors_s: (M + 2,) |reached - planned| for q0, q[1..M], qF (inf if never reached);
    cross_track_m: the track's largest distance from the planned line; flown_rates: (N,) the
    plan's power at the flown positions; stated: the plan's own min throughput.
    """

    slot_s: float
    reach_errors_s: np.ndarray
    cross_track_m: float
    flown_rates: np.ndarray
    stated: float

    @property
    def flown(self) -> float:
        return float(self.flown_rates.min())

    @property
    def flown_to_stated(self) -> float:
        return self.flown / self.stated

    @property
    def worst_reach_slots(self) -> float:
        return float(self.reach_errors_s.max() / self.slot_s)

    @property
    def median_reach_slots(self) -> float:
        return float(np.median(self.reach_errors_s) / self.slot_s)

    def summary(self) -> str:
        return (f'reached within {self.worst_reach_slots:.2f} slot (median '
                f'{self.median_reach_slots:.2f}), cross-track {self.cross_track_m:.2f} m, '
                f'flown {self.flown:.6g} bit/s = {100 * self.flown_to_stated:.2f} % of the '
                f'stated {self.stated:.6g}')


def distance_to_polyline(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Distance (K,) of each point (K, 2) from the polyline through ``vertices`` (V, 2)."""
    if len(vertices) == 1:
        return vector_lengths(points - vertices[0], axis=1)
    a, b = vertices[:-1], vertices[1:]
    ab = b - a
    length2 = np.maximum((ab * ab).sum(axis=1), 1e-300)
    t = np.minimum(np.maximum(((points[:, None, :] - a[None]) * ab[None]).sum(axis=2)
                              / length2, 0.0), 1.0)
    nearest = a[None] + t[..., None] * ab[None]
    return vector_lengths(points[:, None, :] - nearest, axis=2).min(axis=1)


def positions_at(times_s: np.ndarray, track_times_s: np.ndarray,
                 track_m: np.ndarray) -> np.ndarray:
    """The track (K, 2) at ``times_s``, linearly interpolated between its samples."""
    return np.column_stack([np.interp(times_s, track_times_s, track_m[:, axis])
                            for axis in (0, 1)])


def evaluate_flight(result: PlanResult, line_m: np.ndarray, track_times_s: np.ndarray,
                    track_m: np.ndarray, start_s: float, *,
                    radius_m: float = REACH_RADIUS_M) -> FlightReport:
    """Hold a recorded track against ``result``.

    line_m: (V, 2) the planned line (a schedule's ``flight.track()``); track_times_s: (K,)
    autopilot seconds; track_m: (K, 2) east, north metres; start_s: the autopilot time at which
    the plan's clock started. Only the samples from ``start_s`` to the end of the horizon
    count.
    """
    scenario = result.scenario
    times = np.asarray(track_times_s, dtype=float) - start_s
    track = np.asarray(track_m, dtype=float)
    path = flown_path(np.asarray(result.trajectory, dtype=float), scenario)
    planned = scenario.slot_s * np.arange(len(path), dtype=float)
    inside = (times >= -scenario.slot_s) & (times <= planned[-1] + 2 * scenario.slot_s)
    times, track = times[inside], track[inside]
    errors = np.full(len(path), np.inf)
    for index, (point, when) in enumerate(zip(path, planned)):
        near = np.linalg.norm(track - point, axis=1) <= radius_m
        if near.any():
            errors[index] = float(np.abs(times[near] - when).min())
    flying = (times >= 0) & (times <= planned[-1])
    cross_track = float(distance_to_polyline(track[flying], line_m).max())
    flown = positions_at(scenario.times_s, times, track)
    rates = average_rates(flown, np.asarray(result.power, dtype=float), scenario)
    return FlightReport(scenario.slot_s, errors, cross_track, rates,
                        float(result.min_throughput))


#: A planned point with an altitude is reached only with the vehicle also this close to it
#: vertically (metres).
REACH_ALTITUDE_M = 1.0


def reach_errors_3d(points_m: np.ndarray, heights_m: np.ndarray, planned_s: np.ndarray,
                    track_times_s: np.ndarray, track_m: np.ndarray, track_up_m: np.ndarray,
                    start_s: float, *, radius_m: float = REACH_RADIUS_M,
                    altitude_m: float = REACH_ALTITUDE_M) -> np.ndarray:
    """|reached - planned| (K,) seconds for points (K, 2) at altitudes (K,) planned at
    ``planned_s`` (K,) from ``start_s``: the recorded time nearest the planned one at which the
    vehicle was within ``radius_m`` horizontally and ``altitude_m`` vertically (inf if never).
    The track: times (J,) autopilot s, east-north (J, 2) and up (J,) metres."""
    times = np.asarray(track_times_s, dtype=float) - start_s
    track = np.asarray(track_m, dtype=float)
    up = np.asarray(track_up_m, dtype=float)
    errors = np.full(len(points_m), np.inf)
    for index, (point, height, when) in enumerate(zip(points_m, heights_m, planned_s)):
        near = ((np.linalg.norm(track - point, axis=1) <= radius_m)
                & (np.abs(up - height) <= altitude_m))
        if near.any():
            errors[index] = float(np.abs(times[near] - when).min())
    return errors
