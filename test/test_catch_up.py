"""Catching up a timed path after a hold (core/catch_up.py) against closed forms, the stream's
targets while catching up (a recording link), and the plan in force restated after a catch-up
(mission/catch_up.py) against the track and the reference."""

from __future__ import annotations

import math
from types import SimpleNamespace

from helpers import two_node_stream_reference
import numpy as np
import pytest

from uav_comm_planner import paper_scenario
from uav_comm_planner.core.catch_up import (catch_up, CATCH_UP_SPEED_SHARE, ground_speed,
                                            MAX_RATE, turn_speeds)
from uav_comm_planner.core.optimizer import plan_along
from uav_comm_planner.core.receding import delivered_bits
from uav_comm_planner.core.scenario import SolverSettings
from uav_comm_planner.mission.catch_up import caught_up_rest, where_held
from uav_comm_planner.mission.policy import plan_for_vehicle
from uav_comm_planner.mission.progress import MissionProgress, off_plan, PoseTrack
from uav_comm_planner.ros.flight import MissionFlight, SOURCE_TELEMETRY
from uav_comm_planner.ros.params import NodeSettings, PlannerConfig
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink.guided import STREAM_GAP_S, StreamEvent, StreamJob
from uav_comm_planner.vehicle.stream import stream_reference

#: The plan of ``helpers.two_node_stream_reference``.
TWO_NODES = paper_scenario('I', ground_nodes_m=((200.0, 150.0), (500.0, -100.0)),
                           goal_m=(700.0, 0.0), max_speed_mps=10.0, horizon_s=120.0,
                           num_slots=30)


def line_path(speed_mps: float, hover: tuple[float, float] | None = None):
    """Along x at ``speed_mps``, standing still over ``hover`` (from, to) seconds."""
    def at(tau: np.ndarray) -> np.ndarray:
        tau = np.asarray(tau, dtype=float)
        moving = tau if hover is None else (np.minimum(tau, hover[0])
                                            + np.maximum(tau - hover[1], 0.0))
        return np.column_stack([speed_mps * moving, np.zeros_like(tau)])
    return at


def test_a_straight_path_is_caught_up_where_the_faster_vehicle_meets_the_plan():
    # Held at tau 20 (100 m) until the clock read 30: at 10 m/s against the plan's 5 the
    # vehicle meets the plan where 100 + 10 (e - 30) = 5 e, e = 40.
    found = catch_up(line_path(5.0), 100.0, 20.0, 30.0, ground_speed(10.0))
    assert found.lag_s == pytest.approx(10.0)
    assert found.caught_s == pytest.approx(40.0, abs=0.06)
    # Meanwhile at 10 m/s: at e = 35 the path's time is (100 + 50) / 5 = 30, twice as fast.
    assert float(found.reference_time(35.0)) == pytest.approx(30.0, abs=1e-6)
    assert float(found.rate(35.0)[0]) == pytest.approx(2.0, abs=1e-6)
    # Held before the resumption; the path's own time after the catch-up.
    assert float(found.reference_time(29.0)) == pytest.approx(20.0)
    assert float(found.rate(29.0)[0]) == 0.0
    assert float(found.reference_time(60.0)) == 60.0 and float(found.rate(60.0)[0]) == 1.0
    assert np.all(np.diff(found.clock_s) > 0) and np.all(np.diff(found.reference_s) >= 0)


def test_a_hover_is_passed_at_the_greatest_rate_and_a_path_too_short_is_not_caught_up():
    # Moving to 100 m by tau 20, hovering until 40, then on. Held at 15 (75 m) until 25: 25 m
    # at 10 m/s reach the hover at e = 27.5, which then runs 20 times faster than planned,
    # e = 27.5 + (tau - 20) / 20, meeting the plan when tau = e: tau = 26.5 / 0.95.
    found = catch_up(line_path(5.0, (20.0, 40.0)), 80.0, 15.0, 25.0, ground_speed(10.0))
    assert MAX_RATE == 20.0
    assert found.caught_s == pytest.approx(26.5 / 0.95, abs=0.06)
    # A lag of 60 s on a path of 5 m/s that ends 40 s later at 10 m/s: never made up.
    assert catch_up(line_path(5.0), 100.0, 0.0, 60.0, ground_speed(10.0)) is None
    # No lag: the path's own time at once.
    none = catch_up(line_path(5.0), 100.0, 30.0, 30.0, ground_speed(10.0))
    assert float(none.reference_time(50.0)) == 50.0


def test_a_turn_is_caught_up_no_faster_than_the_vehicle_turns():
    # A circle of radius 50 m flown at 2 m/s: kappa = 1 / 50, so 2.5 m/s/s of turning allows
    # sqrt(2.5 * 50) = 11.18 m/s; with 10 m/s available the vehicle flies 10, with 5 m/s/s
    # the turn allows 15.8.
    def circle(tau):
        angle = 2.0 * np.asarray(tau, dtype=float) / 50.0
        return 50.0 * np.column_stack([np.cos(angle), np.sin(angle)])
    points = circle(np.linspace(0.0, 10.0, 201))
    assert turn_speeds(points, 2.5) == pytest.approx(np.full(200, math.sqrt(125.0)), rel=1e-3)
    slow = catch_up(circle, 200.0, 20.0, 30.0, ground_speed(20.0), accel_mpss=2.5)
    # From rest at 2.5 m/s/s to V = sqrt(125) (V / 2.5 s, V^2 / 5 m), then at V against the
    # plan's 2 m/s: the lag of 10 s goes when 40 + V^2 / 5 + V (e - 30 - V / 2.5) = 2 e.
    speed = math.sqrt(125.0)
    assert slow.caught_s == pytest.approx(
        (speed * (30.0 + speed / 2.5) - 40.0 - speed ** 2 / 5.0) / (speed - 2.0), abs=0.1)
    # The first second: from rest, 2.5 m/s/s: 1.25 m along the circle, tau 20 + 1.25 / 2.
    assert float(slow.reference_time(31.0)) == pytest.approx(20.625, abs=0.03)
    assert np.all(np.isinf(turn_speeds(np.column_stack([np.arange(5.0), np.zeros(5)]), 1.0)))


@pytest.mark.parametrize('heading_deg', [0.0, 45.0, 90.0, 180.0, 270.0])
def test_the_ground_speed_in_wind_keeps_the_airspeed_exactly(heading_deg):
    wind = np.array([-6.0, 1.0])
    d = np.array([[math.cos(math.radians(heading_deg)), math.sin(math.radians(heading_deg))]])
    speed = float(ground_speed(20.0, wind, 9.0)(d)[0])
    assert np.linalg.norm(speed * d[0] - wind) == pytest.approx(9.0)
    assert float(ground_speed(5.0, wind, 9.0)(d)[0]) == min(5.0, speed)
    assert float(ground_speed(7.0)(d)[0]) == 7.0


@pytest.fixture(scope='module')
def reference():
    return two_node_stream_reference()


def test_the_stream_flies_its_own_path_from_where_the_vehicle_held_faster(reference):
    job = StreamJob(reference, 100.0, 100.0, 'auto', lambda elapsed_s: 3)
    caught, message = job.caught_up(120.0, 135.0)      # held at 20 s after q0 until 35
    assert caught is not None and 'caught up' in message and '15.0 s behind' in message
    position, velocity, _ = caught.state(35.0)
    assert position == pytest.approx(reference.state(20.0)[0][0])
    speed = CATCH_UP_SPEED_SHARE * reference.bounds.speed_mps / 1.05
    # Never slower than the reference, never faster than the catch-up's speed where the
    # reference is slower than it.
    e = np.linspace(35.0, caught.catch_up.caught_s - 0.1, 200)
    speeds = np.array([np.linalg.norm(caught.state(t)[1]) for t in e])
    own = np.array([np.linalg.norm(reference.state(caught.reference_s(t))[1][0]) for t in e])
    # From rest at the acceleration; then never slower than the reference.
    ramp = e - 35.0 < (reference.bounds.speed_mps
                       / (CATCH_UP_SPEED_SHARE * reference.bounds.accel_mpss))
    assert np.all(speeds[ramp] <= CATCH_UP_SPEED_SHARE * reference.bounds.accel_mpss
                  * (e[ramp] - 35.0) * 1.05 + 1.0)
    assert np.all(speeds[~ramp] >= own[~ramp] * (1 - 1e-9))
    # (within the map's steps, 1 / SAMPLES_PER_S of the reference, where its speed changes)
    assert np.all(speeds <= np.maximum(own, speed) * 1.05)
    assert np.any(speeds > own * 1.5)                   # faster where it can
    # The targets' velocity is their positions' rate of change.
    steps = np.diff(np.vstack([caught.state(t)[0] for t in e]), axis=0) / (e[1] - e[0])
    middle = np.array([caught.state(t)[1] for t in (e[:-1] + e[1:]) / 2])
    assert np.median(np.linalg.norm(steps - middle, axis=1)) < 0.05 * speed
    # Every point of the path after the hold is passed, in order: the reference's time
    # covers all of it.
    assert caught.reference_s(e[-1] + 0.1) == pytest.approx(caught.catch_up.caught_s, abs=0.1)
    after = caught.catch_up.caught_s + 1.0
    assert caught.state(after)[0] == pytest.approx(reference.state(after)[0][0])
    # A vehicle that flew on past the last target before it held (ArduCopter follows it for
    # GUID_TIMEOUT) is taken up where it is, not flown back.
    on, _ = job.caught_up(120.0, 135.0, reference.state(23.0)[0][0] + 0.3)
    assert on.state(35.0)[0] == pytest.approx(reference.state(23.0)[0][0], abs=0.5)
    assert on.catch_up.lag_s == pytest.approx(12.0, abs=0.1)
    # Too little of the plan left to make the time up: the stream stops as before.
    late, why = job.caught_up(100.0 + reference.duration_s - 5.0, 100.0 + reference.duration_s)
    assert late is None and 'cannot be made up' in why


def test_where_a_held_vehicle_was_follows_its_last_target_then_holds_up_to_the_tracks_end():
    track = PoseTrack()
    track.add(10.0, 0.0, 0.0)
    track.add(30.0, 30.0, 40.0)                 # found 50 m on after the gap
    where = where_held(track, np.array([10.0, 11.5, 13.0, 20.0, 30.0, 31.0]))
    assert STREAM_GAP_S == 3.0
    assert where == pytest.approx(np.array([[0.0, 0.0], [15.0, 20.0], [30.0, 40.0],
                                            [30.0, 40.0], [30.0, 40.0], [30.0, 40.0]]))


def test_the_plan_in_force_is_restated_where_the_vehicle_held_and_where_it_catches_up(
        reference):
    result = plan_for_vehicle(TWO_NODES, VehicleLimits()).flown
    assert stream_reference(result, VehicleLimits()).positions == pytest.approx(
        reference.positions)
    progress = MissionProgress()
    progress.begin(result.scenario, result)
    progress.start_clock(0.0)
    track = PoseTrack()
    held = reference.state(41.0)[0][0]
    for t in np.arange(0.0, 41.0, 0.1):                       # on the plan until 41 s
        track.add(t, *reference.state(t)[0][0])
    track.add(51.0, *held)                          # held since; the link back at 51 s
    job = StreamJob(reference, 0.0, 100.0, 'auto', lambda elapsed_s: 3)
    caught, _ = job.caught_up(41.0, 51.0)
    rest = caught_up_rest(progress, track, result.scenario, reference, caught.catch_up,
                          t0_s=0.0, lost_s=41.0)
    slot_s = result.scenario.slot_s
    begun = math.ceil(51.0 / slot_s)
    assert rest.slots_kept == begun and rest.start_s == begun * slot_s
    # Slots before the loss stand as planned; those while held where the track puts the
    # vehicle; the slot in progress where the catch-up has it at the slot's end.
    assert np.all(np.isnan(rest.restated[:10]))
    assert rest.restated[10:begun - 1] == pytest.approx(np.tile(held, (begun - 11, 1)),
                                                        abs=1e-6)
    expected = reference.state(caught.reference_s(begun * slot_s))[0][0]
    assert rest.restated[begun - 1] == pytest.approx(expected)
    assert rest.position_m == pytest.approx(tuple(expected))
    # The rest: the reference where the catch-up puts it at every later slot time.
    times = slot_s * np.arange(begun + 1, result.scenario.num_slots + 1)
    assert rest.caught_up == pytest.approx(np.vstack(
        [reference.state(caught.reference_s(t))[0][0] for t in times]))
    # The data so far count the restated positions with the plan's power.
    assert rest.flown.positions_m[10:begun - 1] == pytest.approx(
        np.tile(held, (begun - 11, 1)), abs=1e-6)
    assert rest.flown.power_w == pytest.approx(result.power[:, :begun])
    assert delivered_bits(result.scenario, rest.flown).shape == (2,)
    # Taken over: the points in force are the restated ones, then the rest's.
    rest_plan = plan_along(result.scenario.replace(num_slots=len(times),
                                                   horizon_s=len(times) * slot_s,
                                                   start_m=rest.position_m),
                           rest.caught_up, name='caught up')
    assert progress.take_over(rest.mission_id, rest.segment, rest.slots_kept,
                              result.scenario, rest_plan, restated=rest.restated)
    progress.start_clock(rest.start_s)
    points, when = progress.points_in_force()
    assert len(points) == result.scenario.num_slots
    assert when == pytest.approx(slot_s * np.arange(1, result.scenario.num_slots + 1))
    assert points[:10] == pytest.approx(np.asarray(result.trajectory)[:10])
    assert points[begun:] == pytest.approx(rest.caught_up)


class _Logger:
    def info(self, message: str) -> None:
        pass


class _StandInNode:
    """What MissionFlight asks of its node: a link, and the replans it submits recorded."""

    def __init__(self, scenario, **settings) -> None:
        self.config = PlannerConfig(scenario, SolverSettings(compute_baselines=False),
                                    NodeSettings(vehicle_aware=False, **settings))
        self.vehicle = SimpleNamespace(linked=True, upload_pending=False, mode='GUIDED',
                                       speed_mps=0.0, flying_mission=True)
        self.submitted: list[tuple[str, object]] = []

    def get_logger(self) -> _Logger:
        return _Logger()

    def submit(self, reason: str, in_flight=None) -> None:
        self.submitted.append((reason, in_flight))

    def refuse(self, request: str, message: str, *, nodes=None) -> None:
        pass                # a position that jumps (the stand-in's vehicle does) is refused

    def clock_s(self) -> float:
        return 0.0


#: Off the plan this far, the stand-in node replans (the parameter's default is 20 m).
REPLAN_DISTANCE_M = 8.0


def test_the_node_asks_for_the_caught_up_rest_and_replans_nothing_meanwhile(reference):
    result = plan_for_vehicle(TWO_NODES, VehicleLimits()).flown
    node = _StandInNode(TWO_NODES, replan_distance_m=REPLAN_DISTANCE_M)
    flight = MissionFlight(node)
    flight.progress.begin(TWO_NODES, result)
    flight.progress.start_clock(0.0)
    for t in np.round(np.arange(0.1, 41.0, 0.1), 6):          # on the plan until 41 s
        flight.on_position(float(t), *reference.state(t)[0][0], source=SOURCE_TELEMETRY,
                           height_m=100.0)
    # The link back at 52.1 s, the vehicle held 3 s of path past the last target: 8 s late,
    # off the plan by time, but the first positions after a gap wait as any others do.
    held = reference.state(44.0)[0][0]
    for t in (52.1, 52.2, 52.3):
        flight.on_position(t, *held, source=SOURCE_TELEMETRY, height_m=100.0)
    assert node.submitted == []
    job = StreamJob(reference, 0.0, 100.0, 'auto', lambda elapsed_s: 3)
    caught, message = job.caught_up(41.0, 52.1, held)
    flight.on_catch_up(StreamEvent('caught up', message, job=caught, lost_s=41.0))
    (reason, rest), = node.submitted
    assert 'caught up' in reason and rest.caught_up is not None and rest.start_s == 56.0
    # Taken over as the node takes it: in force from the end of the slot in progress, when
    # the vehicle, flying the catch-up, is still short of the rest's q0: no replan till then,
    # nor while the rest is planned.
    rest_plan = plan_along(TWO_NODES.replace(num_slots=len(rest.caught_up),
                                             horizon_s=4.0 * len(rest.caught_up),
                                             start_m=rest.position_m),
                           rest.caught_up, name='caught up')
    assert flight.progress.take_over(rest.mission_id, rest.segment, rest.slots_kept,
                                     TWO_NODES, rest_plan, restated=rest.restated)
    flight.progress.current.start_s = rest.start_s
    # Still at its hold until the rest's slot (the mode taken late), off the rest's path.
    assert off_plan(rest_plan, 0.0, held, distance_m=REPLAN_DISTANCE_M, delay_s=5.0)
    for t in np.round(np.arange(52.4, 55.95, 0.1), 6):
        flight.on_position(float(t), *held, source=SOURCE_TELEMETRY, height_m=100.0)
    assert len(node.submitted) == 1
    # Flying the catch-up, the vehicle is on the rest's plan once it is in force.
    for t in np.round(np.arange(56.0, 90.0, 0.1), 6):
        flight.on_position(float(t), *caught.state(float(t))[0], source=SOURCE_TELEMETRY,
                           height_m=100.0)
    assert len(node.submitted) == 1
