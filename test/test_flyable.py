"""Vehicle-aware plans: the autopilot's leg timing, the flight schedule, what it delivers.

The S-curve figures are checked against an independent integration of a jerk-limited profile
and against the closed forms of ArduPilot's SCurve (T = L / V + V / A + A / J + tj for a leg
that reaches its speed; L_min = V (V / A + A / J + tj)). Whether ArduCopter really flies the
schedule on time is the business of test_sitl_flight.py, on the real autopilot.
"""

from __future__ import annotations

import math
import re

from helpers import random_six_nodes
import numpy as np
import pytest

from uav_comm_planner import InfeasibleHorizonError, InvalidScenarioError, paper_scenario
from uav_comm_planner import Scenario
from uav_comm_planner.core.model import leg_lengths
from uav_comm_planner.vehicle.evaluation import distance_to_polyline, evaluate_flight
from uav_comm_planner.core.optimizer import plan_along, PlanResult
from uav_comm_planner.mission.policy import plan_for_vehicle
from uav_comm_planner.vehicle.flyable import check_speed, MAX_TURN_DEG, schedule_flight
from uav_comm_planner.vehicle.waypoints import simplify, turn_angles_deg
from uav_comm_planner.vehicle.leg_models import MIN_STOP_HOLD_S
from uav_comm_planner.vehicle.limits import read_parameter_file, VehicleLimits
from uav_comm_planner.vehicle.timing import (LEG_LATENCY_S, leg_time, peak_speed, Profile,
                                             ramp_distance, slowest_speed_for,
                                             speed_for_time)

DEFAULTS = VehicleLimits()
A, J, TJ = DEFAULTS.max_accel_mpss, DEFAULTS.max_jerk_mpsss, DEFAULTS.jerk_time_s


def multirotor_case_one(**overrides) -> Scenario:
    """The letter's case I flown at a multirotor's 10 m/s: 400 s in 100 slots of 4 s."""
    settings = {'max_speed_mps': 10.0, 'horizon_s': 400.0, 'num_slots': 100, **overrides}
    return paper_scenario('I', **settings)


@pytest.fixture(scope='module')
def case_one():
    return plan_for_vehicle(multirotor_case_one())


def arducopter_ramp(speed_mps, accel, jerk, jerk_time_s, dt=1e-4):
    """Rest to ``speed_mps`` as ArduPilot's SCurve shapes it, integrated numerically: a jerk
    pulse rising as a raised cosine over tj, held, falling over tj; constant acceleration; the
    mirrored pulse. Returns (seconds, metres)."""
    tj = jerk_time_s
    t2 = accel / jerk - tj
    t4 = (speed_mps - accel * tj - accel ** 2 / jerk) / accel

    def pulse(sign):
        rise = [sign * jerk / 2 * (1 - math.cos(math.pi * t / tj)) for t in np.arange(0, tj, dt)]
        return rise + [sign * jerk] * round(t2 / dt) + rise[::-1]

    jerks = np.array(pulse(1.0) + [0.0] * round(t4 / dt) + pulse(-1.0))
    a = np.cumsum(jerks) * dt
    v = np.cumsum(a) * dt
    return len(jerks) * dt, float(v.sum() * dt)


def test_ramps_are_arducopter_scurve_durations():
    # ArduPilot's SCurve: reaching V takes V / A + A / J + tj; tj = 0.3 s by default.
    assert TJ == 0.3
    assert leg_time(1000.0, 10.0, DEFAULTS) == pytest.approx(100.0 + 4.0 + 2.5 + 0.3)
    assert 2 * ramp_distance(10.0, DEFAULTS) == pytest.approx(10.0 * (4.0 + 2.5 + 0.3))
    assert peak_speed(68.0, 10.0, DEFAULTS) == pytest.approx(10.0)
    assert peak_speed(48.0, 10.0, DEFAULTS) < 9.0


@pytest.mark.parametrize('speed_mps', [7.5, 10.0, 12.0, 15.0])
def test_ramps_match_arducopters_raised_cosine_jerk_integrated(speed_mps):
    seconds, metres = arducopter_ramp(speed_mps, A, J, TJ)
    assert seconds == pytest.approx(speed_mps / A + A / J + TJ, abs=1e-3)
    assert metres == pytest.approx(ramp_distance(speed_mps, DEFAULTS), rel=1e-3)
    # A long leg: both ramps and the cruise between them, and the same positions throughout.
    assert leg_time(1000.0, speed_mps, DEFAULTS) == pytest.approx(
        2 * seconds + (1000.0 - 2 * metres) / speed_mps, abs=1e-2)
    profile = Profile.rest_to_rest(1000.0, speed_mps, DEFAULTS)
    assert profile.distance(np.array([seconds]))[0] == pytest.approx(metres, abs=1e-2)


@pytest.mark.parametrize('length_m', [0.1, 0.5, 4.0, 12.0, 30.0, 50.0, 68.0, 300.0])
@pytest.mark.parametrize('speed_mps', [0.5, 2.0, 10.0, 15.0])
def test_every_scurve_branch_is_a_rest_to_rest_leg_within_the_limits(length_m, speed_mps):
    """Short legs and slow speeds take SCurve's reduced branches; each must still be a motion
    from rest to rest over exactly the leg, within the speed and acceleration limits."""
    profile = Profile.rest_to_rest(length_m, speed_mps, DEFAULTS)
    t = np.linspace(0.0, profile.duration_s, 4001)
    s = profile.distance(t)
    v = np.gradient(s, t)
    a = np.gradient(v, t)
    assert s[0] == 0.0 and s[-1] == pytest.approx(length_m, rel=1e-6)
    assert np.all(np.diff(s) >= -1e-9)
    assert v.max() <= speed_mps * (1 + 1e-3) and abs(v[-1]) <= 1e-2 * max(speed_mps, 1)
    assert np.abs(a[2:-2]).max() <= A * 1.01
    assert v.max() == pytest.approx(peak_speed(length_m, speed_mps, DEFAULTS), rel=1e-2)
    assert profile.duration_s == pytest.approx(leg_time(length_m, speed_mps, DEFAULTS))


def test_speed_for_time_inverts_leg_time():
    for length_m, duration_s in [(200.0, 40.0), (12.0, 12.0), (500.0, 70.0)]:
        speed = speed_for_time(length_m, duration_s, 10.0, DEFAULTS)
        assert leg_time(length_m, speed, DEFAULTS) == pytest.approx(duration_s, abs=1e-6)
    assert speed_for_time(500.0, 10.0, 10.0, DEFAULTS) == 10.0   # too little time: at most V


def test_the_slowest_speed_for_a_time_is_found_to_its_tolerance_on_a_stepped_clock():
    """A leg's time a + b / v read off a clock that ticks every 0.02 s (as the PX4 model's):
    the speed found makes the time and the speed one tolerance below does not, as a plain
    bisection over the same clock decides, in fewer timings."""
    rng = np.random.default_rng(5)
    searched = bisected = 0
    for _ in range(50):
        a, b, top = rng.uniform(0.0, 20.0), rng.uniform(10.0, 2000.0), rng.uniform(2.0, 15.0)
        duration = a + b / top * rng.uniform(1.01, 6.0)
        timed = []

        def seconds_at(v: float) -> float:
            timed.append(v)
            return math.ceil((a + b / v) / 0.02) * 0.02

        speed = slowest_speed_for(seconds_at, duration, top, tolerance_mps=0.005)
        searched += len(timed)
        assert speed <= top and seconds_at(speed) <= duration
        assert seconds_at(speed - 0.005) > duration
        low, high = 0.0, top                # the bisection, independently
        while high - low > 0.005:
            bisected += 1
            middle = 0.5 * (low + high)
            low, high = (low, middle) if seconds_at(middle) <= duration else (middle, high)
        assert abs(speed - high) <= 0.005
    assert searched < 0.7 * bisected
    assert slowest_speed_for(lambda v: 100.0 / v, 5.0, 10.0) == 10.0   # at most the top speed


def test_limits_are_validated_and_read_from_ground_station_files(tmp_path):
    with pytest.raises(InvalidScenarioError, match='max_accel_mpss'):
        VehicleLimits(max_accel_mpss=0.0)
    with pytest.raises(InvalidScenarioError, match='max_speed_mps'):
        VehicleLimits(max_speed_mps=True)
    mission_planner = tmp_path / 'copter.param'
    mission_planner.write_text('# saved\nWPNAV_SPEED,1200\nWPNAV_ACCEL,500\nWPNAV_JERK,5\n'
                               'ATC_INPUT_TC,0.2\nFENCE_ENABLE,0\n')
    limits = read_parameter_file(mission_planner)
    assert (limits.max_speed_mps, limits.max_accel_mpss, limits.max_jerk_mpsss,
            limits.jerk_time_s) == pytest.approx((12.0, 5.0, 5.0, 0.4))
    qgc = tmp_path / 'vehicle.params'
    qgc.write_text('# Onboard parameters\n1\t1\tMPC_XY_CRUISE\t8.5\t9\n1\t1\tMPC_ACC_HOR\t3\t9\n')
    limits = read_parameter_file(qgc, firmware='px4')
    assert (limits.max_speed_mps, limits.max_accel_mpss, limits.max_jerk_mpsss) == \
        pytest.approx((8.5, 3.0, 1.0))
    spaced = tmp_path / 'spaced.parm'
    spaced.write_text('WPNAV_SPEED 800\n')
    assert read_parameter_file(spaced).max_speed_mps == pytest.approx(8.0)
    bad = tmp_path / 'bad.param'
    bad.write_text('WPNAV_SPEED,fast\n')
    with pytest.raises(InvalidScenarioError, match=r'bad.param:1: WPNAV_SPEED'):
        read_parameter_file(bad)
    with pytest.raises(InvalidScenarioError, match='sets none of'):
        read_parameter_file(spaced, firmware='px4')
    with pytest.raises(InvalidScenarioError, match='cannot read'):
        read_parameter_file(tmp_path / 'missing.param')


def test_a_speed_above_the_vehicles_is_refused_with_the_numbers():
    with pytest.raises(InfeasibleHorizonError, match=r'12 m/s .* 10 m/s \(the waypoint speed'):
        check_speed(multirotor_case_one(max_speed_mps=12.0), DEFAULTS)
    with pytest.raises(InfeasibleHorizonError, match=r"10.3 m/s \(the airframe's top speed"):
        check_speed(multirotor_case_one(max_speed_mps=10.5),
                    VehicleLimits(max_speed_mps=12.0, airframe_speed_mps=10.3))
    with pytest.raises(InfeasibleHorizonError, match=r'faster than the vehicle'):
        plan_for_vehicle(paper_scenario('I'))   # the letter's 100 m/s


def test_a_horizon_too_short_for_the_stops_is_refused_with_the_numbers():
    # 2000 m at 10 m/s takes 200 s plus the ramps: 201 s of horizon cannot be flown, and not
    # even the straight line fits; the horizon it names is enough, a tenth of a second less
    # is not.
    scenario = multirotor_case_one(horizon_s=201.0, num_slots=201)
    with pytest.raises(InfeasibleHorizonError,
                       match=r'even the straight line from q0 to qF \(2000\.0 m, heading 90 '
                             r'degrees\) takes \d+\.\d s from rest to rest .* the horizon ends '
                             r'at 202 s: lengthen horizon_s to (\d+\.\d) s or more') as refused:
        plan_for_vehicle(scenario)
    needed = float(re.search(r'lengthen horizon_s to (\d+\.\d) s', str(refused.value))[1])
    assert plan_for_vehicle(multirotor_case_one(horizon_s=needed, num_slots=201)).schedule
    with pytest.raises(InfeasibleHorizonError, match='even the straight line'):
        plan_for_vehicle(multirotor_case_one(horizon_s=needed - 0.2, num_slots=201))


def test_the_schedule_keeps_every_limit(case_one):
    scenario, schedule = case_one.ideal.scenario, case_one.schedule
    end_s = scenario.slot_s * (scenario.num_slots + 1)
    assert schedule.arrival_s <= end_s + 0.25 * scenario.slot_s
    holds = [stop.hold_s for stop in schedule.stops]
    assert all(float(hold).is_integer() for hold in holds)          # ArduPilot: whole seconds
    assert min(holds[1:-1]) >= MIN_STOP_HOLD_S                      # a hover stops the vehicle
    minimum_step = 2 * ramp_distance(DEFAULTS.max_speed_mps, DEFAULTS)
    for leg in schedule.legs:
        assert leg.speed_mps <= DEFAULTS.cruise_speed_mps
        steps = np.linalg.norm(np.diff(leg.vertices, axis=0), axis=1)
        assert len(steps) == 1 or steps.min() >= 2 * ramp_distance(leg.speed_mps, DEFAULTS) - 1e-6
        assert steps.min() <= max(minimum_step, steps.min())
        assert np.all(turn_angles_deg(leg.vertices) <= MAX_TURN_DEG)
    # Three hovers, one over each node, and nothing else stops the vehicle.
    assert len(schedule.stops) == 5


def test_the_flown_plan_is_the_predicted_flight_with_its_optimal_power(case_one):
    scenario, flown = case_one.ideal.scenario, case_one.flown
    q = case_one.schedule.flight.positions(scenario.times_s)
    assert np.array_equal(flown.trajectory, q)
    assert leg_lengths(flown.trajectory, scenario).max() <= \
        scenario.max_speed_mps * scenario.slot_s * (1 + 1e-9)
    assert flown.power.sum() == pytest.approx(scenario.power_budget_w, rel=1e-9)
    # It loses little to the ideal plan, and still beats both of the letter's baselines.
    assert flown.min_throughput >= 0.995 * case_one.ideal.min_throughput
    assert flown.min_throughput > max(case_one.ideal.baselines.values())


def test_a_random_plan_is_flyable_and_beats_the_baselines():
    vehicle_plan = plan_for_vehicle(random_six_nodes(1))
    scenario = vehicle_plan.ideal.scenario
    assert vehicle_plan.schedule.arrival_s <= scenario.slot_s * (scenario.num_slots + 1.25)
    assert vehicle_plan.flown.min_throughput > max(vehicle_plan.ideal.baselines.values())


def straight_pieces(*pieces) -> PlanResult:
    """The plan that flies ``pieces``, (displacement (dx, dy) m, slots) each, from (0, 0) at
    10 m/s in slots of 2 s, with the power optimal for it."""
    path = [np.zeros(2)]
    for displacement, slots in pieces:
        path += [path[-1] + np.asarray(displacement, float) * k / slots
                 for k in range(1, slots + 1)]
    q = np.array(path[1:-1])
    scenario = paper_scenario('I', max_speed_mps=10.0, horizon_s=2.0 * len(q),
                              num_slots=len(q), goal_m=tuple(path[-1]))
    return plan_along(scenario, q, name='given')


def scurve_s(length_m: float, speed_mps: float) -> float:
    """ArduPilot's SCurve closed form for a leg that reaches its speed: L / V + V / A + A / J
    + tj."""
    return length_m / speed_mps + speed_mps / A + A / J + TJ


def test_a_leg_behind_the_plan_is_flown_faster_to_end_where_the_plan_ends_it():
    # 1000 m at exactly 10 m/s, 8 s of hover, 1000 m in 120 s, 20 s of hover, 500 m in 60 s:
    # the first leg is late by what starting and stopping cost, more than the hover's 7 s
    # spare; the second, fitted to its 120 s, would end 2 s after the plan's 228 s (with time
    # to spare after it). Flown faster from where it starts, it ends when the plan does, and
    # the third leaves on the plan's time.
    result = straight_pieces(((1000.0, 0.0), 50), ((0.0, 0.0), 4), ((1000.0, 0.0), 60),
                             ((0.0, 0.0), 10), ((500.0, 0.0), 30))
    schedule = schedule_flight(result, DEFAULTS)
    first, second, third = schedule.legs
    assert first.speed_mps == DEFAULTS.cruise_speed_mps
    behind_s = first.start_s + scurve_s(1000.0, 10.0) + LEG_LATENCY_S + 1.0 - 108.0
    assert behind_s > 1.0
    assert second.speed_mps > speed_for_time(1000.0, 120.0, 10.0, DEFAULTS)
    assert second.start_s + scurve_s(1000.0, second.speed_mps) == pytest.approx(228.0, abs=0.1)
    assert third.start_s == pytest.approx(248.0, abs=1.0)
    assert schedule.arrival_s <= 308.0 + 1e-6


def test_a_leg_the_later_legs_need_time_from_leaves_on_time_and_flies_faster():
    # 20 s of hover at q0, 1000 m in 150 s, then a right-angle turn (a stop) and 1000 m at
    # exactly 10 m/s, which starting and stopping make late: the first leg leaves q0 when the
    # plan does and makes up the time by its speed, instead of leaving early.
    result = straight_pieces(((0.0, 0.0), 10), ((1000.0, 0.0), 75), ((0.0, 1000.0), 50))
    schedule = schedule_flight(result, DEFAULTS)
    first, second = schedule.legs
    assert first.start_s == pytest.approx(20.0 - LEG_LATENCY_S / 2, abs=1.0)
    assert first.speed_mps > speed_for_time(1000.0, 150.0, 10.0, DEFAULTS)
    assert second.speed_mps == DEFAULTS.cruise_speed_mps
    assert schedule.arrival_s <= 270.0 + 1e-6
    assert second.start_s + scurve_s(1000.0, 10.0) + LEG_LATENCY_S / 2 == pytest.approx(
        270.0, abs=0.1)


def test_simplify_keeps_every_point_within_the_tolerance():
    rng = np.random.default_rng(0)
    t = np.linspace(0, 1, 60)
    points = np.column_stack([1000 * t, 80 * np.sin(3 * t) + rng.normal(0, 0.2, 60)])
    kept = simplify(points, 1.0)
    assert kept[0] == 0 and kept[-1] == 59 and len(kept) < 20
    assert distance_to_polyline(points, points[kept]).max() <= 1.0


def test_distance_to_polyline_matches_a_dense_sampling():
    vertices = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 50.0]])
    dense = np.vstack([np.linspace(a, b, 20001) for a, b in zip(vertices, vertices[1:])])
    points = np.random.default_rng(1).uniform(-20, 120, (50, 2))
    brute = np.linalg.norm(points[:, None] - dense[None], axis=2).min(axis=1)
    assert distance_to_polyline(points, vertices) == pytest.approx(brute, abs=0.01)


def test_a_track_that_is_the_prediction_scores_as_the_plan(case_one):
    flight = case_one.schedule.flight
    times = np.arange(-5.0, flight.end_s + 5.0, 0.1)
    report = evaluate_flight(case_one.flown, flight.track(), times + 1000.0,
                             flight.positions(times), 1000.0)
    assert report.worst_reach_slots <= 0.05
    assert report.cross_track_m <= 1e-6
    assert report.flown_to_stated == pytest.approx(1.0, abs=1e-6)
    late = evaluate_flight(case_one.flown, flight.track(), times + 1020.0,
                           flight.positions(times), 1000.0)
    assert late.worst_reach_slots >= 4.0 and late.flown_to_stated < 1.0


def test_a_planner_that_refuses_every_speed_gives_its_own_typed_error():
    def refusing(scenario, settings):
        raise InfeasibleHorizonError('no plan at this speed')
    with pytest.raises(InfeasibleHorizonError, match='no plan at this speed'):
        plan_for_vehicle(multirotor_case_one(), sources=refusing)
