"""The mission bookkeeping of the closed loop, without ROS: the pose track, the off-plan
test and the slots each plan keeps across replans."""

from __future__ import annotations

import numpy as np
import pytest

from uav_comm_planner import paper_scenario, plan, PlanResult, SolverSettings
from uav_comm_planner.core.receding import delivered_bits, replan
from uav_comm_planner.mission.progress import (MissionProgress, off_plan, planned_position,
                                               PoseTrack, TRACK_GAP_S)

FAST = SolverSettings(compute_baselines=False)


@pytest.fixture(scope='module')
def mission_and_plan():
    mission = paper_scenario('I', num_slots=20, horizon_s=40.0)
    return mission, plan(mission, FAST)


def test_track_interpolates_and_knows_its_gaps():
    track = PoseTrack(length=4)
    for t, x in ((0.0, 0.0), (1.0, 10.0), (2.0, 20.0), (10.0, 100.0), (1.5, -1.0)):
        track.add(t, x, 0.0)
    assert len(track.samples) == 4                 # the late (1.5 s) sample is ignored
    positions, known = track.at(np.array([0.5, 1.5, 6.0, 10.0, 11.0]))
    np.testing.assert_allclose(positions[:2, 0], [5.0, 15.0])
    assert known.tolist() == [True, True, False, True, False]
    assert 10.0 - 2.0 > TRACK_GAP_S
    track.add(11.0, 110.0, 0.0)                    # full: the oldest sample goes
    assert track.samples[0, 0] == 1.0 and track.latest == (11.0, 110.0, 0.0)


def test_off_plan_by_distance_and_by_time(mission_and_plan):
    _, result = mission_and_plan
    on = tuple(planned_position(result, 10.0))
    assert off_plan(result, 10.0, on, distance_m=20.0, delay_s=5.0) == ''
    far = (on[0], on[1] + 500.0)
    assert 'm from the planned path' in off_plan(result, 10.0, far, distance_m=20.0,
                                                 delay_s=5.0)
    late = tuple(planned_position(result, 2.0))
    if np.linalg.norm(np.subtract(late, on)) > 20.0:
        assert 's off the planned time' in off_plan(result, 10.0, late, distance_m=20.0,
                                                    delay_s=5.0)


def test_replans_keep_the_slots_begun_and_count_them_once(mission_and_plan):
    mission, first = mission_and_plan
    progress = MissionProgress()
    progress.begin(mission, first)
    assert not progress.started
    progress.start_clock(100.0)
    # 5.5 slots of 2 s after the start: 6 slots have begun.
    now = 100.0 + 11.0
    flown = progress.flown_slots(now, mission.ground_nodes_m, None)
    assert flown.num_slots == 6
    np.testing.assert_array_equal(flown.power_w, first.power[:, :6])
    np.testing.assert_array_equal(flown.positions_m, first.trajectory[:6])
    rest = replan(mission, first.trajectory[5], flown, FAST, previous_q=first.trajectory[6:])
    segment = progress.current
    segment.slots_kept = segment.slots_begun(now)
    progress.follow_with(mission, rest.result, 6)
    progress.start_clock(120.0)
    schedule, kept = progress.schedule()
    assert [count for _, count in kept] == [6, 14]
    assert schedule.shape == (3, 20)
    assert schedule.sum() <= mission.power_budget_w * (1 + 1e-9)
    assert progress.over(120.0 + 14 * 2.0)
    assert not progress.over(120.0 + 13 * 2.0 - 0.5)
    # Flown positions come from the track where it covers a slot's time.
    track = PoseTrack()
    for t in np.arange(100.0, 113.0, 0.1):
        track.add(t, 1.0, 2.0)
    later = progress.flown_slots(130.0, mission.ground_nodes_m, track)
    assert later.num_slots == 6 + 5
    np.testing.assert_allclose(later.positions_m[:6], [(1.0, 2.0)] * 6)
    np.testing.assert_array_equal(later.positions_m[6:], rest.result.trajectory[:5])
    assert np.all(delivered_bits(mission, later) > 0)


def straight_plan(mission) -> PlanResult:
    """``mission`` flown at constant speed along the line from q0 to qF."""
    start, goal = np.asarray(mission.start_m), np.asarray(mission.goal_m)
    shares = np.arange(1, mission.num_slots + 1) / (mission.num_slots + 1)
    q = start + shares[:, None] * (goal - start)
    power = np.full((len(mission.ground_nodes_m), mission.num_slots), 0.1)
    return PlanResult(scenario=mission, trajectory=q, times=mission.times_s, power=power,
                      rates=np.ones(len(mission.ground_nodes_m)), min_throughput=1.0,
                      history=())


def test_slots_in_a_telemetry_outage_count_where_the_vehicle_was_not_where_planned(
        mission_and_plan):
    mission, _ = mission_and_plan
    result = straight_plan(mission)
    progress = MissionProgress()
    progress.begin(mission, result)
    progress.start_clock(100.0)
    slot_s = mission.slot_s

    def on_plan(t):
        return planned_position(result, t - 100.0)
    # On the plan until 110 s; the link then cut for 20 s, the vehicle holding its last
    # target (a stream cut off) at the plan's position at 110 s; heard again from 130 s.
    held = on_plan(110.0)
    track = PoseTrack()
    for t in np.arange(100.0, 110.05, 0.1):
        track.add(t, *on_plan(t))
    for t in np.arange(130.0, 131.05, 0.1):
        track.add(t, *held)
    flown = progress.flown_slots(131.0, mission.ground_nodes_m, track)
    times = 100.0 + slot_s * np.arange(1, flown.num_slots + 1)
    outage = (times > 110.0 + TRACK_GAP_S) & (times < 130.0 - TRACK_GAP_S)
    assert outage.sum() >= 5
    # Every slot of the outage where the vehicle held, none where the plan had it.
    np.testing.assert_allclose(flown.positions_m[outage], [held] * outage.sum(), atol=1e-6)
    assert np.all(np.linalg.norm(flown.positions_m[outage] - result.trajectory[:len(times)][
        outage], axis=1) > 1.0)
    # A vehicle that flew its mission on through the same outage keeps the planned positions.
    track = PoseTrack()
    for t in np.concatenate([np.arange(100.0, 110.05, 0.1), np.arange(130.0, 131.05, 0.1)]):
        track.add(t, *on_plan(t))
    flown = progress.flown_slots(131.0, mission.ground_nodes_m, track)
    np.testing.assert_allclose(flown.positions_m, result.trajectory[:flown.num_slots],
                               atol=1e-6)
    # After the latest sample nothing is known: the plan's positions.
    later = progress.flown_slots(140.0, mission.ground_nodes_m, track)
    np.testing.assert_allclose(later.positions_m[flown.num_slots + 1:],
                               result.trajectory[flown.num_slots + 1:later.num_slots])
