"""A fleet's plan flown on ArduCopter SITL, every vehicle at once, each on its own instance.

Each UAV's part of the plan (:func:`~uav_comm_planner.mission.fleet.uav_result`) is streamed
by the single vehicle's own code: a :class:`~uav_comm_planner.vehicle.mavlink.telemetry.
VehicleBridge` running a :class:`~uav_comm_planner.vehicle.mavlink.guided.TargetStream` of its
smooth reference through the plan's points at their times (:func:`~uav_comm_planner.vehicle.
stream.stream_reference`, within the vehicle's speed, acceleration and jerk), one GUIDED
position, velocity and acceleration target per position report, in autopilot time; after a gap
in the targets (a lost link) the stream catches its plan up (:mod:`uav_comm_planner.core.
catch_up`) as it does for one vehicle. The bridge reaches the vehicle's second MAVLink port
(TCP 5762 + 10 I) through a :class:`~devtools.link_proxy.LinkProxy` whose link can be cut; the
flight is recorded on the first port (5760 + 10 I), a link of its own that is never cut, in
autopilot time (``time_boot_ms``). Each vehicle starts at its own q0 (its simulator's home),
takes off, climbs, and once its stream's link is up holds q0 for :data:`HOLD_S`; its plan clock
starts then. The vehicles' simulations run side by side, each on its own clock, so the flights
are put together on plan time.

A :class:`LinkCut` cuts one vehicle's stream link at a time of its plan clock for a span of its
autopilot time; at the cut and at the restoration every vehicle's plan time then (its latest
sample) is noted (:attr:`VehicleTrack.outage_s`), so that the others' flight during the outage
is judged on their own clocks.

Judged together (:class:`FleetFlight`): each vehicle's position at every slot time against its
plan; the minimum throughput the plan's power schedule gives at the positions flown at the
slot times (node n's throughput summed over the vehicles) against the stated one, and each
vehicle's own share of it; and the least distance between two vehicles, at the slot times and
over the whole flight (sampled at the telemetry's times).
"""

from __future__ import annotations

from dataclasses import dataclass
import itertools
import math
from pathlib import Path
import threading

import numpy as np

from devtools.link_proxy import LinkProxy
from devtools.sitl import BASE_PORT, open_link, set_parameter, start_sitl, take_off
from uav_comm_planner.core.catch_up import CatchUp
from uav_comm_planner.core.fleet.model import fleet_rates
from uav_comm_planner.core.fleet.planner import FleetPlan
from uav_comm_planner.core.model import average_rates
from uav_comm_planner.errors import InvalidScenarioError, VehicleLinkError
from uav_comm_planner.mission.fleet import uav_result
from uav_comm_planner.vehicle.geodesy import enu_to_geodetic, Home
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink.guided import StreamEvent, StreamJob, TargetStream
from uav_comm_planner.vehicle.mavlink.telemetry import (global_position_enu, LinkEvent,
                                                        request_telemetry, VehicleBridge)
from uav_comm_planner.vehicle.stream import stream_reference, StreamReference

#: Autopilot seconds the vehicle holds q0 (streamed at rest) before its plan clock starts.
HOLD_S = 5.0
#: The recording goes on this long after qF (autopilot seconds).
AFTER_S = 2.0
#: Speed-up of the simulators: two at once, each streamed from Python at its telemetry rate.
FLEET_SPEEDUP = 5
#: The second MAVLink port of an instance (SERIAL1, TCP 5762 + 10 I): the stream's link.
STREAM_PORT_OFFSET = 2


@dataclass(frozen=True)
class LinkCut:
    """Vehicle ``uav``'s (0-based) stream link cut ``at_s`` seconds of its plan clock after
    q0, for ``for_s`` seconds of its autopilot time."""

    uav: int
    at_s: float
    for_s: float


@dataclass(frozen=True)
class VehicleTrack:
    """One vehicle's flight on its plan clock: times (K,) seconds after its q0, positions
    (K, 2) metres in the planning frame; its stream's and link's events in order
    (:class:`StreamEvent`, :class:`LinkEvent`); the plan times of its own clock at which a
    cut began and ended (None: no cut in the flight)."""

    times_s: np.ndarray
    positions_m: np.ndarray
    events: tuple = ()
    outage_s: tuple[float, float] | None = None

    def at(self, times_s: np.ndarray) -> np.ndarray:
        """Positions (len(times), 2) at plan times, interpolated."""
        return np.column_stack([np.interp(times_s, self.times_s, self.positions_m[:, axis])
                                for axis in range(2)])

    def said(self, kind: str) -> list[str]:
        """The messages of its events of ``kind`` ('lost', 'connected', 'caught up'...)."""
        return [event.message for event in self.events if event.kind == kind]

    @property
    def catch_up(self) -> CatchUp | None:
        """How its stream caught its plan up after a gap (the first time), None if never."""
        return next((event.job.catch_up for event in self.events
                     if isinstance(event, StreamEvent) and event.kind == 'caught up'), None)


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

    def own_rates(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Vehicle k's own share of each node's throughput (N,), bit/s: at the positions it
        flew at the slot times with its power, and as its plan states it."""
        flown = average_rates(self.slot_positions_m[k], self.plan.power[k],
                              self.plan.fleet.vehicle(k))
        return flown, np.asarray(uav_result(self.plan, k).rates)

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


class _Clocks:
    """Every vehicle's latest plan time (NaN before its clock starts), shared by the vehicles'
    threads, and each one's plan times at a cut's start and end."""

    def __init__(self, count: int) -> None:
        self._lock = threading.Lock()
        self.now = [math.nan] * count
        self.outage: list[list[float]] = [[] for _ in range(count)]

    def tick(self, key: int, elapsed_s: float) -> None:
        with self._lock:
            self.now[key] = elapsed_s

    def mark(self) -> None:
        """Note every vehicle's plan time now (the cut's start, then its end)."""
        with self._lock:
            for times, now in zip(self.outage, self.now):
                times.append(now)


@dataclass
class _Vehicle:
    """One vehicle's flight (its thread): ``reference`` streamed at ``altitude_m`` from its
    q0 ``start_m`` on a SITL within ``instances``; its track (or its error) into
    ``out[key]``."""

    reference: StreamReference
    start_m: np.ndarray
    folder: Path
    home: Home
    altitude_m: float
    instances: tuple[int, int]
    key: int
    clocks: _Clocks
    cut: LinkCut | None

    def fly(self, out: dict) -> None:
        try:
            latitude, longitude, _ = enu_to_geodetic(np.array([self.start_m[0]]),
                                                     np.array([self.start_m[1]]), 0.0,
                                                     self.home)
            spawn = Home(float(latitude[0]), float(longitude[0]), self.home.altitude_m)
            self.folder.mkdir(parents=True, exist_ok=True)
            vehicle = start_sitl(self.folder, spawn, speedup=FLEET_SPEEDUP,
                                 instances=self.instances)
            try:
                link = open_link(vehicle)
                try:
                    out[self.key] = self._flight(link, vehicle.instance)
                finally:
                    link.close()
            finally:
                vehicle.stop()
        except Exception as exc:        # reported by fly_fleet on the caller's thread
            out[self.key] = exc

    def _flight(self, link, instance: int) -> VehicleTrack:
        """Take off and climb on the recording link, then stream through the proxy while
        recording; the track."""
        set_parameter(link, 'FENCE_ENABLE', 0)
        take_off(link, self.altitude_m)
        request_telemetry(link)
        while True:         # climb first: the stream is horizontal at the plan's altitude
            if self._position(link).relative_alt / 1000.0 >= self.altitude_m - 1.0:
                break
        events: list = []

        def keep(event) -> None:
            if isinstance(event, (LinkEvent, StreamEvent)):
                events.append(event)
        proxy = LinkProxy(BASE_PORT + 10 * instance + STREAM_PORT_OFFSET)
        stream = TargetStream(self.home, keep)
        bridge = VehicleBridge(proxy.url, self.home, keep, stream=stream)
        try:
            while not any(event.kind == 'connected' for event in events):
                self._position(link)
            t0 = self._position(link).time_boot_ms / 1000.0 + HOLD_S
            stream.start(StreamJob(self.reference, t0, self.altitude_m, 'hold',
                                   lambda elapsed_s: 0))
            times, latitudes, longitudes, altitudes = self._record(link, proxy, stream, t0)
        finally:
            bridge.stop()
            proxy.close()
        east, north, _ = global_position_enu(latitudes, longitudes, altitudes, self.home)
        outage = self.clocks.outage[self.key]
        return VehicleTrack(np.array(times), np.column_stack([east, north]), tuple(events),
                            (outage[0], outage[1]) if len(outage) == 2 else None)

    def _record(self, link, proxy: LinkProxy, stream: TargetStream,
                t0_s: float) -> tuple[list, list, list, list]:
        """The positions from the plan clock's start to :data:`AFTER_S` after qF and the end
        of the stream (it ends itself at qF, on its own link's positions); the cut, when it is
        this vehicle's, at its times."""
        duration = self.reference.duration_s
        times, latitudes, longitudes, altitudes = [], [], [], []
        phase = 0 if self.cut is not None and self.cut.uav == self.key else 2
        cut_s = math.inf
        while True:
            message = self._position(link)
            elapsed = message.time_boot_ms / 1000.0 - t0_s
            if elapsed > duration + AFTER_S and not stream.active:
                return times, latitudes, longitudes, altitudes
            if elapsed > 2 * (duration + HOLD_S + AFTER_S) + 60.0:
                raise VehicleLinkError('the fleet flight took too long')
            if elapsed < 0.0:
                continue
            self.clocks.tick(self.key, elapsed)
            if phase == 0 and elapsed >= self.cut.at_s:
                proxy.cut()
                self.clocks.mark()
                phase, cut_s = 1, elapsed
            elif phase == 1 and elapsed >= cut_s + self.cut.for_s:
                proxy.restore()
                self.clocks.mark()
                phase = 2
            times.append(elapsed)
            latitudes.append(message.lat)
            longitudes.append(message.lon)
            altitudes.append(message.relative_alt)

    @staticmethod
    def _position(link):
        message = link.recv_match(type='GLOBAL_POSITION_INT', blocking=True, timeout=10.0)
        if message is None:
            raise VehicleLinkError('a vehicle went silent during the fleet flight')
        return message


def fly_fleet(plan: FleetPlan, folder: Path, *, home: Home,
              limits: VehicleLimits = VehicleLimits(),
              instances: tuple[int, int] = (20, 29), cut: LinkCut | None = None) -> FleetFlight:
    """Fly every vehicle of ``plan`` at once (module docstring) on SITL instances within
    ``instances``, with ``cut`` (None: no cut); raises the first vehicle's error, if any."""
    count = plan.fleet.num_uavs
    if cut is not None and not 0 <= cut.uav < count:
        raise InvalidScenarioError(f'the cut is on UAV {cut.uav + 1} of a fleet of {count}')
    clocks, out = _Clocks(count), {}
    # Each vehicle its own share of the instances: two threads never pick the same one.
    share = (instances[1] - instances[0] + 1) // count
    vehicles = [_Vehicle(stream_reference(uav_result(plan, k), limits),
                         np.asarray(plan.fleet.starts_m[k]), folder / f'uav{k + 1}', home,
                         plan.fleet.scenario.altitude_m,
                         (instances[0] + k * share, instances[0] + (k + 1) * share - 1), k,
                         clocks, cut) for k in range(count)]
    threads = [threading.Thread(target=vehicle.fly, args=(out,)) for vehicle in vehicles]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for k in range(count):
        if isinstance(out.get(k), Exception):
            raise out[k]
    return FleetFlight(plan, tuple(out[k] for k in range(count)))


__all__ = ['FleetFlight', 'fly_fleet', 'LinkCut', 'VehicleTrack']
