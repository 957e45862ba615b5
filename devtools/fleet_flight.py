"""A fleet's plan flown on ArduCopter SITL, every vehicle at once, each on its own instance.

Each UAV's part of the plan (:func:`~uav_comm_planner.mission.fleet.uav_result`) is flown as
the streamed mode flies a single plan: its smooth reference through the plan's points at their
times (:func:`~uav_comm_planner.vehicle.stream.stream_reference`, within the vehicle's speed,
acceleration and jerk), sent as GUIDED position, velocity and acceleration targets, one per
position report, in autopilot time (:func:`~uav_comm_planner.vehicle.mavlink.guided.
send_target`). Each vehicle starts at its own q0 (its simulator's home), takes off, holds q0,
and its plan clock starts when its stream starts; the vehicles' simulations run side by side,
each on its own clock, so the flights are put together on plan time.

Judged together (:class:`FleetFlight`): each vehicle's position at every slot time against its
plan; the minimum throughput the plan's power schedule gives at the positions flown at the
slot times (node n's throughput summed over the vehicles) against the stated one; and the
least distance between two vehicles, at the slot times and over the whole flight (sampled at
the telemetry's times).
"""

from __future__ import annotations

from dataclasses import dataclass
import itertools
from pathlib import Path
import threading

import numpy as np

from devtools.sitl import open_link, set_parameter, start_sitl, take_off
from uav_comm_planner.core.fleet.model import fleet_rates
from uav_comm_planner.core.fleet.planner import FleetPlan
from uav_comm_planner.errors import VehicleLinkError
from uav_comm_planner.mission.fleet import uav_result
from uav_comm_planner.vehicle.geodesy import enu_to_geodetic, Home
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink.guided import send_target, set_mode, StreamJob
from uav_comm_planner.vehicle.mavlink.telemetry import global_position_enu, request_telemetry
from uav_comm_planner.vehicle.stream import stream_reference, StreamReference

#: Autopilot seconds the vehicle holds q0 (streamed at rest) before its plan clock starts.
HOLD_S = 5.0
#: The stream goes on this long after qF (autopilot seconds).
AFTER_S = 2.0
#: Speed-up of the simulators: two at once, each streamed from Python at its telemetry rate.
FLEET_SPEEDUP = 5


@dataclass(frozen=True)
class VehicleTrack:
    """One vehicle's flight on its plan clock: times (K,) seconds after its q0, positions
    (K, 2) metres in the planning frame."""

    times_s: np.ndarray
    positions_m: np.ndarray

    def at(self, times_s: np.ndarray) -> np.ndarray:
        """Positions (len(times), 2) at plan times, interpolated."""
        return np.column_stack([np.interp(times_s, self.times_s, self.positions_m[:, axis])
                                for axis in range(2)])


@dataclass(frozen=True)
class FleetFlight:
    """The fleet's flights against its plan (module docstring)."""

    plan: FleetPlan
    tracks: tuple[VehicleTrack, ...]

    @property
    def slot_positions_m(self) -> np.ndarray:
        """Every vehicle's position at the slot times: (K, M, 2) metres."""
        return np.stack([track.at(self.plan.times) for track in self.tracks])

    @property
    def slot_errors_m(self) -> np.ndarray:
        """Distance of each vehicle from its planned point at each slot time: (K, M) m."""
        return np.linalg.norm(self.slot_positions_m - self.plan.trajectories, axis=-1)

    @property
    def flown_min_throughput(self) -> float:
        """min_n R_n with the plan's power at the positions flown, bit/s."""
        return float(fleet_rates(self.slot_positions_m, self.plan.power, self.plan.fleet).min())

    @property
    def closest_at_slots_m(self) -> float:
        """The least distance between two vehicles at the slot times, metres."""
        q = self.slot_positions_m
        return float(min(np.linalg.norm(q[j] - q[k], axis=1).min()
                         for j, k in itertools.combinations(range(len(q)), 2)))

    @property
    def closest_m(self) -> float:
        """The least distance between two vehicles over the whole flight, at every telemetry
        time of either (the other interpolated), metres."""
        end = self.plan.fleet.scenario.slot_s * (self.plan.fleet.scenario.num_slots + 1)
        closest = np.inf
        for j, k in itertools.combinations(range(len(self.tracks)), 2):
            times = np.union1d(self.tracks[j].times_s, self.tracks[k].times_s)
            times = times[(times >= 0.0) & (times <= end)]
            gap = np.linalg.norm(self.tracks[j].at(times) - self.tracks[k].at(times), axis=1)
            closest = min(closest, float(gap.min()))
        return closest


def _stream(link, reference: StreamReference, home: Home, altitude_m: float,
            timeout_s: float) -> VehicleTrack:
    """Hold q0 for :data:`HOLD_S`, then stream the reference; record the positions."""
    job = StreamJob(reference, 0.0, altitude_m, 'hold', lambda elapsed_s: 0)
    request_telemetry(link)
    set_mode(link, 'GUIDED')
    times, latitudes, longitudes, altitudes = [], [], [], []
    first_s = None
    duration = reference.duration_s
    while True:
        message = link.recv_match(type='GLOBAL_POSITION_INT', blocking=True, timeout=10.0)
        if message is None:
            raise VehicleLinkError('a vehicle went silent during the fleet flight')
        clock_s = message.time_boot_ms / 1000.0
        first_s = clock_s if first_s is None else first_s
        elapsed = clock_s - first_s - HOLD_S
        if elapsed > duration + AFTER_S:
            break
        if clock_s - first_s > timeout_s:
            raise VehicleLinkError('the fleet flight took too long')
        send_target(link, job, max(elapsed, 0.0), home, None)
        times.append(elapsed)
        latitudes.append(message.lat)
        longitudes.append(message.lon)
        altitudes.append(message.relative_alt)
    east, north, _ = global_position_enu(latitudes, longitudes, altitudes, home)
    times = np.array(times)
    kept = times >= 0.0
    return VehicleTrack(times[kept], np.column_stack([east, north])[kept])


def _fly_one(reference: StreamReference, start_m: np.ndarray, folder: Path, home: Home,
             altitude_m: float, instances: tuple[int, int], out: dict, key: int) -> None:
    """One vehicle, on its own simulator started at its q0; its track (or its error) into
    ``out[key]``."""
    try:
        latitude, longitude, _ = enu_to_geodetic(np.array([start_m[0]]),
                                                 np.array([start_m[1]]), 0.0, home)
        spawn = Home(float(latitude[0]), float(longitude[0]), home.altitude_m)
        folder.mkdir(parents=True, exist_ok=True)
        vehicle = start_sitl(folder, spawn, speedup=FLEET_SPEEDUP, instances=instances)
        try:
            link = open_link(vehicle)
            set_parameter(link, 'FENCE_ENABLE', 0)
            take_off(link, altitude_m)
            request_telemetry(link)
            while True:         # climb first: the stream is horizontal at the plan's altitude
                message = link.recv_match(type='GLOBAL_POSITION_INT', blocking=True,
                                          timeout=10.0)
                if message is None:
                    raise VehicleLinkError('a vehicle went silent while climbing')
                if message.relative_alt / 1000.0 >= altitude_m - 1.0:
                    break
            horizon = reference.duration_s + HOLD_S + AFTER_S
            out[key] = _stream(link, reference, home, altitude_m, timeout_s=2 * horizon + 60)
            link.close()
        finally:
            vehicle.stop()
    except Exception as exc:        # reported by fly_fleet on the caller's thread
        out[key] = exc


def fly_fleet(plan: FleetPlan, folder: Path, *, home: Home,
              limits: VehicleLimits = VehicleLimits(),
              instances: tuple[int, int] = (20, 29)) -> FleetFlight:
    """Fly every vehicle of ``plan`` at once (module docstring) on SITL instances within
    ``instances``; raises the first vehicle's error, if any."""
    references = [stream_reference(uav_result(plan, k), limits)
                  for k in range(plan.fleet.num_uavs)]
    out: dict = {}
    # Each vehicle its own share of the instances: two threads never pick the same one.
    share = (instances[1] - instances[0] + 1) // len(references)
    threads = [threading.Thread(target=_fly_one, args=(
        reference, np.asarray(plan.fleet.starts_m[k]), folder / f'uav{k + 1}', home,
        plan.fleet.scenario.altitude_m,
        (instances[0] + k * share, instances[0] + (k + 1) * share - 1), out, k))
        for k, reference in enumerate(references)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for k in range(len(threads)):
        if isinstance(out.get(k), Exception):
            raise out[k]
    return FleetFlight(plan, tuple(out[k] for k in range(len(threads))))


__all__ = ['FleetFlight', 'fly_fleet', 'VehicleTrack']
