"""The mission in flight: its clock, the plan each slot was flown under, and where the UAV was.

The node feeds times (seconds on one clock: the vehicle's boot time with a MAVLink link, the
node's clock without) and positions (metres in the planning frame), and asks what a receding
replan needs (:func:`uav_comm_planner.core.receding.replan`).

A mission is M slots of delta seconds. Its first plan starts when the UAV reaches that plan's
q0 (or on ``~/start``); slot m of a plan covers ((m - 1) delta, m delta] after the plan's start,
with the UAV at q[m] at its end. A replan at time t counts the slots of the plan in force that
have begun, j = ceil((t - start) / delta), as flown under that plan (their power is spent),
and plans the remaining slots; the new plan's slots start when the UAV reaches its q0. In
between, the transmitter schedule has no slot: the energy and the data of the mission are the
sums over the slots of its plans, each cut where the next one took over.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import itertools
import math

import numpy as np

from uav_comm_planner.core.model import flown_path
from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.core.receding import (FlownSlots, lengthened, power_for_nodes,
                                            rest_of_mission)
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.mission.request import InFlight, with_slots

#: Position samples kept for the flown positions (about 20 minutes at 50 Hz).
TRACK_LENGTH = 60_000
#: A slot's flown position is read from the track when a sample lies within this many
#: seconds of the slot's time on each side; otherwise the planned position stands for it.
TRACK_GAP_S = 2.0
#: Samples of the planned path per slot when looking for the nearest planned point.
PATH_SAMPLES_PER_SLOT = 10
#: Tells missions apart: every mission begun gets the next number.
_MISSION_IDS = itertools.count(1)


class PoseTrack:
    """Timed positions of the UAV: (t seconds, x, y metres), in time order, bounded."""

    def __init__(self, length: int = TRACK_LENGTH) -> None:
        self._samples = np.empty((length, 3))
        self._count = 0

    def add(self, time_s: float, x_m: float, y_m: float) -> None:
        """Append a sample; one older than the last is ignored (time goes forward)."""
        if self._count and time_s < self._samples[self._count - 1, 0]:
            return
        if self._count == len(self._samples):
            self._samples[:-1] = self._samples[1:]
            self._count -= 1
        self._samples[self._count] = (time_s, x_m, y_m)
        self._count += 1

    @property
    def samples(self) -> np.ndarray:
        """(K, 3): t seconds, x, y metres."""
        return self._samples[:self._count]

    @property
    def latest(self) -> tuple[float, float, float] | None:
        return tuple(self._samples[self._count - 1]) if self._count else None

    def at(self, times_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions (K, 2) at ``times_s`` (K,), linearly interpolated, and (K,) booleans:
        whether a sample lies within TRACK_GAP_S on each side of the time."""
        times_s = np.asarray(times_s, dtype=float).reshape(-1)
        samples = self.samples
        known = np.zeros(len(times_s), dtype=bool)
        positions = np.full((len(times_s), 2), np.nan)
        if len(samples) < 1:
            return positions, known
        t = samples[:, 0]
        after = np.searchsorted(t, times_s, side='left')
        before = np.clip(after - 1, 0, len(t) - 1)
        after_c = np.clip(after, 0, len(t) - 1)
        exact = t[after_c] == times_s
        known = exact | ((after > 0) & (after < len(t))
                         & (times_s - t[before] <= TRACK_GAP_S)
                         & (t[after_c] - times_s <= TRACK_GAP_S))
        positions[:, 0] = np.interp(times_s, t, samples[:, 1])
        positions[:, 1] = np.interp(times_s, t, samples[:, 2])
        return positions, known

    def around(self, times_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                   np.ndarray, np.ndarray]:
        """For each of ``times_s`` (K,) inside the track (a sample at or before it and one
        after it): the samples either side, as times (K,) and positions (K, 2), and (K,)
        booleans, False outside the track (its values then meaningless)."""
        times_s = np.asarray(times_s, dtype=float).reshape(-1)
        samples = self.samples
        if len(samples) < 2:
            empty = np.zeros(len(times_s))
            return empty, np.zeros((len(times_s), 2)), empty, np.zeros(
                (len(times_s), 2)), np.zeros(len(times_s), dtype=bool)
        t = samples[:, 0]
        after = np.clip(np.searchsorted(t, times_s, side='right'), 1, len(t) - 1)
        inside = (times_s >= t[0]) & (times_s < t[-1])
        return (t[after - 1], samples[after - 1, 1:], t[after], samples[after, 1:], inside)


@dataclass
class Segment:
    """One plan of the mission: it covers mission slots first_slot + 1 .. first_slot + M'.

    result: the plan as flown; start_s: when its clock started (the UAV at its q0), None
    while it waits for that; slots_kept: how many of its slots count (all until a replan cuts
    it); planned: the optimiser's plan that ``result`` flies (a vehicle-aware plan's ideal
    plan; None: ``result`` itself), whose rest a replan continues; restated: (K, 2) positions
    that stand for its first K slots' points where the vehicle could not fly them (a stream
    held by a lost link: where it held), NaN where the plan's point stands.
    """

    result: PlanResult
    first_slot: int
    start_s: float | None = None
    slots_kept: int | None = None
    planned: PlanResult | None = None
    restated: np.ndarray | None = None

    @property
    def optimised(self) -> PlanResult:
        """The optimiser's plan of this segment (:attr:`planned`, else :attr:`result`)."""
        return self.result if self.planned is None else self.planned

    @property
    def num_slots(self) -> int:
        return self.result.scenario.num_slots if self.slots_kept is None else self.slots_kept

    def slots_begun(self, now_s: float) -> int:
        """Slots of this plan that have begun at ``now_s`` (0 before its start)."""
        if self.start_s is None:
            return 0
        begun = math.ceil((now_s - self.start_s) / self.result.scenario.slot_s - 1e-9)
        return int(min(max(begun, 0), self.num_slots))

    def slot_times_s(self, slots: int) -> np.ndarray:
        """Clock times of this plan's first ``slots`` waypoints: start + m delta, (slots,)."""
        return self.start_s + self.result.scenario.slot_s * np.arange(1, slots + 1)

    def points(self, slots: int) -> np.ndarray:
        """The points in force of this plan's first ``slots`` slots (slots, 2): its own, or
        the :attr:`restated` ones."""
        points = np.array(self.result.trajectory[:slots], dtype=float)
        if self.restated is not None:
            rows = min(slots, len(self.restated))
            mine = self.restated[:rows]
            points[:rows] = np.where(np.isfinite(mine), mine, points[:rows])
        return points


@dataclass
class MissionProgress:
    """The plans of the mission in flight, in order, on one clock.

    ``segments[-1]`` is the plan in force (or waiting for its q0). ``mission`` is the whole
    mission's scenario as last planned (the node set and budget of the latest plan);
    ``mission_id`` tells this mission from any other begun before or after it; ``ended`` why
    the mission was ended before its last slot ('' while it was not): it is then over.
    """

    mission: Scenario | None = None
    segments: list[Segment] = field(default_factory=list)
    mission_id: int = 0
    ended: str = ''

    @property
    def started(self) -> bool:
        return bool(self.segments) and self.segments[0].start_s is not None

    @property
    def current(self) -> Segment | None:
        return self.segments[-1] if self.segments else None

    def begin(self, mission: Scenario, result: PlanResult, *,
              planned: PlanResult | None = None) -> None:
        """A new mission whose first plan is ``result`` (optimised as ``planned``,
        :class:`Segment`); its clock is not running yet."""
        self.mission = mission
        self.segments = [Segment(result, 0, planned=planned)]
        self.mission_id = next(_MISSION_IDS)

    def start_clock(self, now_s: float) -> None:
        """The plan in force starts now (the UAV is at its q0)."""
        if self.current is not None and self.current.start_s is None:
            self.current.start_s = now_s

    def flown_slots(self, now_s: float, nodes: tuple, track: PoseTrack | None) -> FlownSlots:
        """Every slot begun by ``now_s``, with its power mapped onto ``nodes`` and its position
        from ``track`` where it covers the slot's time, across a gap in it as
        :func:`across_gaps` places it, else as planned."""
        power, positions = [], []
        for segment in self.segments:
            begun = segment.slots_begun(now_s) if segment is self.current else segment.num_slots
            if begun == 0 or segment.start_s is None:
                continue
            result = segment.result
            planned = np.array(result.trajectory[:begun], dtype=float)
            if track is not None:
                times = segment.slot_times_s(begun)
                tracked, known = track.at(times)
                planned = np.where(known[:, None], tracked,
                                   across_gaps(result, segment.start_s, times, planned, track))
            if segment.restated is not None:
                rows = min(begun, len(segment.restated))
                mine = segment.restated[:rows]
                planned[:rows] = np.where(np.isfinite(mine), mine, planned[:rows])
            power.append(power_for_nodes(result.scenario.ground_nodes_m,
                                         result.power[:, :begun], nodes))
            positions.append(planned)
        if not power:
            return FlownSlots.none(len(nodes))
        return FlownSlots(np.hstack(power), np.vstack(positions))

    def in_flight(self, scenario: Scenario, time_s: float, position_m: tuple[float, float],
                  track: PoseTrack | None, *, energy_left_wh: float | None = None) -> InFlight:
        """What a replan of the rest of this mission from ``position_m`` at ``time_s`` needs
        (``scenario``: the mission's parameters now, lengthened to the mission's slots so
        far): the slots flown (positions from ``track``), the rest of the optimiser's plan in
        force as a start, warm when that plan serves ``scenario``'s nodes. Raises the errors
        of :func:`~uav_comm_planner.core.receding.rest_of_mission` when the rest cannot be
        planned (the horizon over, the budget spent, qF out of reach even lengthened);
        ``energy_left_wh``: the rest's energy budget as the battery measures it."""
        slots = self.mission.num_slots
        mission = with_slots(scenario, slots)
        segment = self.current
        begun = segment.slots_begun(time_s) if segment.start_s is not None else 0
        flown = self.flown_slots(time_s, mission.ground_nodes_m, track)
        rest_of_mission(lengthened(mission, position_m, flown), position_m, flown,
                        energy_left_wh=energy_left_wh)
        planned = segment.optimised
        same_nodes = np.array_equal(np.asarray(planned.scenario.ground_nodes_m, float),
                                    np.asarray(mission.ground_nodes_m, float))
        return InFlight(
            position_m=(float(position_m[0]), float(position_m[1])), flown=flown,
            previous_q=np.array(planned.trajectory[begun:], dtype=float),
            mission_id=self.mission_id, segment=len(self.segments) - 1, slots_kept=begun,
            mission_slots=slots, warm=same_nodes, energy_left_wh=energy_left_wh)

    def cut(self, now_s: float) -> int:
        """End the plan in force after its slots begun by ``now_s``; returns the mission's
        slots counted so far (the next plan's first slot)."""
        segment = self.current
        segment.slots_kept = segment.slots_begun(now_s)
        return segment.first_slot + segment.slots_kept

    def follow_with(self, mission: Scenario, result: PlanResult, first_slot: int, *,
                    planned: PlanResult | None = None) -> None:
        """The next plan of the mission, from mission slot ``first_slot`` + 1."""
        self.mission = mission
        if self.current is not None and self.current.start_s is None:
            # The plan it replaces never started: drop it, it flew no slot.
            self.segments.pop()
        self.segments.append(Segment(result, first_slot, planned=planned))

    def take_over(self, mission_id: int, segment: int, slots_kept: int, mission: Scenario,
                  result: PlanResult, *, planned: PlanResult | None = None,
                  restated: np.ndarray | None = None) -> bool:
        """A replan asked while plan number ``segment`` of mission ``mission_id`` was in force
        takes over after that plan's first ``slots_kept`` slots (``restated``: where some
        of them were flown instead, :attr:`Segment.restated`). False, and nothing changes,
        when the mission is another by now or a later plan has started already."""
        if (mission_id != self.mission_id or not 0 <= segment < len(self.segments)
                or any(later.start_s is not None for later in self.segments[segment + 1:])):
            return False
        del self.segments[segment + 1:]
        kept = self.segments[segment]
        kept.slots_kept = slots_kept
        if restated is not None:
            kept.restated = np.asarray(restated, dtype=float)
        self.follow_with(mission, result, kept.first_slot + slots_kept, planned=planned)
        return True

    def over(self, now_s: float) -> bool:
        """Whether every slot of the mission has begun, or the mission was ended."""
        segment = self.current
        if segment is None or self.mission is None or segment.start_s is None:
            return False
        if self.ended:
            return True
        return segment.first_slot + segment.slots_begun(now_s) >= self.mission.num_slots \
            and segment.slots_begun(now_s) >= segment.num_slots

    def points_in_force(self) -> tuple[np.ndarray, np.ndarray]:
        """Every kept slot's point in force (K, 2) (:meth:`Segment.points`) and its clock
        time (K,), in mission order."""
        kept = [(segment, segment.num_slots) for segment in self.segments
                if segment.start_s is not None]
        if not kept:
            return np.zeros((0, 2)), np.zeros(0)
        return (np.vstack([segment.points(count) for segment, count in kept]),
                np.concatenate([segment.slot_times_s(count) for segment, count in kept]))

    def schedule(self) -> tuple[np.ndarray, list[tuple[Segment, int]]]:
        """The power of every slot kept so far, mapped onto the last plan's nodes: (N, K)
        watts, and each segment with the number of its slots in it."""
        nodes = self.current.result.scenario.ground_nodes_m
        parts, kept = [], []
        for segment in self.segments:
            count = segment.num_slots
            parts.append(power_for_nodes(segment.result.scenario.ground_nodes_m,
                                         segment.result.power[:, :count], nodes))
            kept.append((segment, count))
        return np.hstack(parts), kept


def across_gaps(result: PlanResult, start_s: float, times_s: np.ndarray, planned: np.ndarray,
                track: PoseTrack) -> np.ndarray:
    """Where the UAV was at ``times_s`` (K,) of a plan started at ``start_s``, for times the
    track has no sample near (a telemetry outage): the ``planned`` positions (K, 2) moved by
    the UAV's offset from the plan at the samples either side of the gap, interpolated in
    time; the planned ones outside the track (after its latest sample).

    A vehicle that flew its mission on through the outage is about where the plan puts it at
    both ends, and keeps the planned positions; one that held its last target (a stream cut
    off) is counted where it held, exactly so along a straight stretch of the plan: the
    positions the flight had, not the ones it was promised."""
    before_t, before_m, after_t, after_m, inside = track.around(times_s)
    if not inside.any():
        return planned
    offset_before = before_m - planned_position(result, before_t - start_s).T
    offset_after = after_m - planned_position(result, after_t - start_s).T
    share = ((np.asarray(times_s, dtype=float) - before_t)
             / np.maximum(after_t - before_t, 1e-9))[:, None]
    moved = planned + offset_before + share * (offset_after - offset_before)
    return np.where(inside[:, None], moved, planned)


def planned_position(result: PlanResult, elapsed_s: float | np.ndarray) -> np.ndarray:
    """Where the plan has the UAV ``elapsed_s`` after its start: (2,) metres ((2, K) for K
    times), interpolated along q0, q[1..M], qF (held at the ends)."""
    points = flown_path(result.trajectory, result.scenario)
    times = result.scenario.path_times_s
    return np.array([np.interp(elapsed_s, times, points[:, 0]),
                     np.interp(elapsed_s, times, points[:, 1])])


def off_plan(result: PlanResult, elapsed_s: float, position_m: tuple[float, float], *,
             distance_m: float, delay_s: float) -> str:
    """Why the UAV at ``position_m``, ``elapsed_s`` after the plan's start, is off the plan
    ('' when it is on it).

    Off by distance: no point of the planned path (sampled PATH_SAMPLES_PER_SLOT times a slot)
    lies within ``distance_m``. Off by time: the nearest planned times at which the path passes
    within ``distance_m`` all differ from ``elapsed_s`` by more than ``delay_s``.
    """
    scenario = result.scenario
    points = flown_path(result.trajectory, scenario)
    times = scenario.path_times_s
    fine = np.linspace(0.0, times[-1], PATH_SAMPLES_PER_SLOT * (len(times) - 1) + 1)
    path = np.column_stack([np.interp(fine, times, points[:, 0]),
                            np.interp(fine, times, points[:, 1])])
    gaps = np.linalg.norm(path - np.asarray(position_m, dtype=float), axis=1)
    near = gaps <= distance_m
    if not near.any():
        return f'{gaps.min():.1f} m from the planned path (replan_distance_m {distance_m:g})'
    lag = np.abs(fine[near] - elapsed_s).min()
    if lag > delay_s:
        return f'{lag:.1f} s off the planned time (replan_delay_s {delay_s:g})'
    return ''


__all__ = ['MissionProgress', 'PoseTrack', 'Segment', 'across_gaps', 'off_plan',
           'planned_position']
