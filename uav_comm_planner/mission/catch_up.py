"""The plan in force restated after the stream caught it up (a link lost, the vehicle held).

When targets stopped reaching the vehicle (a lost link), it held where the last one put it
while the mission's clock ran on; when they come again the stream flies the same reference
from there, faster where the vehicle can, until the lost time is made up
(:mod:`uav_comm_planner.core.catch_up`). Every point of the plan is flown, later than planned
until the time is made up. What the mission then promises is stated again here, honestly:

- the plan in force's slots that passed while the vehicle held (and the slot in progress)
  count where the vehicle was: across the telemetry's gap, on from the last position before
  it for the few seconds the autopilot follows its last target, then where the first position
  after it found the vehicle (:func:`where_held`); for the slot in progress, where the
  catch-up puts it at the slot's end; these positions stand for those slots' points
  (:attr:`~uav_comm_planner.mission.progress.Segment.restated`);
- the rest of the mission, from the end of the slot in progress, is the reference's positions
  at the slot times as the catch-up flies them, with the power optimal for them over the
  whole mission's budget left (one power step with the data delivered so far,
  :func:`~uav_comm_planner.core.optimizer.plan_along`); it is in force from that moment, with
  no upload (the vehicle holds the plan's own mission, whose path the stream flies, for a
  fallback; the rest's own items are built, for a link made again) and no stop of the
  stream.
"""

from __future__ import annotations

import math

import numpy as np

from uav_comm_planner.core.catch_up import CatchUp
from uav_comm_planner.core.receding import FlownSlots
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.mission.progress import MissionProgress, PoseTrack
from uav_comm_planner.mission.request import InFlight, with_slots
from uav_comm_planner.vehicle.mavlink.guided import STREAM_GAP_S
from uav_comm_planner.vehicle.stream import StreamReference


def caught_up_rest(progress: MissionProgress, track: PoseTrack, scenario: Scenario,
                   reference: StreamReference, catch_up: CatchUp, *, t0_s: float,
                   lost_s: float) -> InFlight | None:
    """The rest of ``progress``'s mission as the stream of ``reference`` from autopilot time
    ``t0_s``, held since ``lost_s`` and caught up by ``catch_up``, flies it (module
    docstring); ``scenario``: the mission's parameters now. None when that stream is not the
    plan in force's, or no slot of it is left."""
    segment = progress.current
    if (segment is None or segment.start_s is None or progress.mission is None
            or not math.isclose(segment.start_s, t0_s, abs_tol=1e-6)):
        return None
    slot_s = segment.result.scenario.slot_s
    resumed_s = t0_s + float(catch_up.clock_s[0])
    begun, count = segment.slots_begun(resumed_s), segment.num_slots
    mission = with_slots(scenario, progress.mission.num_slots)
    if begun >= count or segment.first_slot + count != mission.num_slots:
        return None

    def flown_at(times_s: np.ndarray) -> np.ndarray:
        elapsed = np.asarray(times_s, dtype=float) - t0_s
        return reference.state(catch_up.reference_time(elapsed))[0]

    flown = progress.flown_slots(resumed_s, mission.ground_nodes_m, track)
    times = segment.slot_times_s(begun)
    own = flown.positions_m[len(flown.positions_m) - begun:]
    restated = np.full((begun, 2), np.nan)
    ahead = times > track.latest[0]
    held = (times > lost_s) & ~ahead
    restated[held] = where_held(track, times[held])
    restated[ahead] = flown_at(times[ahead])
    positions = flown.positions_m.copy()
    positions[len(positions) - begun:] = np.where(np.isfinite(restated), restated, own)
    points = flown_at(t0_s + slot_s * np.arange(begun + 1, count + 1))
    start = flown_at(np.array([t0_s + begun * slot_s]))[0]
    return InFlight(
        position_m=(float(start[0]), float(start[1])),
        flown=FlownSlots(flown.power_w, positions), previous_q=points,
        mission_id=progress.mission_id, segment=len(progress.segments) - 1,
        slots_kept=begun, mission_slots=progress.mission.num_slots, warm=True,
        caught_up=points, restated=restated, start_s=t0_s + begun * slot_s)


def where_held(track: PoseTrack, times_s: np.ndarray) -> np.ndarray:
    """Where a vehicle whose targets stopped was at ``times_s`` (K,) (K, 2): between the
    track's samples either side of each time, it went on from the one before for at most
    :data:`~uav_comm_planner.vehicle.mavlink.guided.STREAM_GAP_S` (ArduCopter follows its last
    target that long, GUID_TIMEOUT) to where the one after found it, and held there; a time
    with samples close on both sides is where they put it, a time at or past the track's ends
    where its sample there puts it."""
    before_t, before_m, after_t, after_m, inside = track.around(times_s)
    reach = np.minimum(after_t - before_t, STREAM_GAP_S)
    share = np.clip((np.asarray(times_s, dtype=float) - before_t) / np.maximum(reach, 1e-9),
                    0.0, 1.0)[:, None]
    return np.where(inside[:, None], before_m + share * (after_m - before_m),
                    track.at(times_s)[0])


__all__ = ['caught_up_rest', 'where_held']
