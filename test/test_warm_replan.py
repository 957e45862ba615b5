"""Warm replans in flight: the plan in force, rejoined from where the UAV is, continued instead
of screening the tours again; the full search where it is no start or the nodes changed."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from devtools.replans import replan_mission
from uav_comm_planner import plan, SolverSettings
from uav_comm_planner.core.drops import random_scenario
from uav_comm_planner.core.feasibility import retimed, within_speed_limit
from uav_comm_planner.core.model import average_rates, snr_per_watt
from uav_comm_planner.core.power import conic_power
from uav_comm_planner.core.sca.surrogate import path_length_km
from uav_comm_planner.core.receding import (FlownSlots, PREVIOUS_PLAN_START, receding_problem,
                                            rejoined, replan, WARM_SHORTLIST,
                                            WARM_STARTS)
from uav_comm_planner.mission.pipeline import plan_mission
from uav_comm_planner.mission.progress import planned_position
from uav_comm_planner.mission.request import InFlight, MissionRequest
from uav_comm_planner.ros.battery import BatteryWatch
from uav_comm_planner.ros.flight import MissionFlight
from uav_comm_planner.ros.params import NodeSettings, PlannerConfig
from uav_comm_planner.errors import InfeasibleHorizonError
from uav_comm_planner.mission.progress import MissionProgress
from uav_comm_planner.mission.policy import (plan_for_vehicle, Source, WARM_REPLAN,
                                             WIDER_SEARCH_GAIN)
from uav_comm_planner.vehicle.flyable import schedule_flight
from uav_comm_planner.vehicle.limits import VehicleLimits

SETTINGS = SolverSettings(compute_baselines=False)
#: Eight nodes, 150 slots of 2 s at 10 m/s from (0, 0) to (1200, 1200).
MISSION = random_scenario(8, 150, 3, side_m=1200.0, horizon_s=300.0, max_speed_mps=10.0)


@pytest.fixture(scope='module')
def first():
    return plan(MISSION, SETTINGS)


def flown(result, slots: int) -> FlownSlots:
    return FlownSlots(result.power[:, :slots], result.trajectory[:slots])


def test_rejoined_flies_straight_to_the_first_point_it_reaches_in_time():
    rest = MISSION.replace(start_m=(0.0, 0.0), num_slots=6, horizon_s=12.0,
                           goal_m=(60.0, 0.0))
    step = rest.max_speed_mps * rest.slot_s                # 20 m a slot
    previous = np.array([[0.0, 50.0], [10.0, 50.0], [20.0, 45.0], [30.0, 40.0],
                         [40.0, 25.0], [50.0, 10.0]])
    joined = rejoined(previous, (0.0, 0.0), rest)
    # Point j is reached by slot j when its distance is at most (j + 1) 20 m: (0, 50) is 50 m
    # (> 20), (10, 50) 51 m (> 40), (20, 45) 49.2 m (<= 60): j = 2.
    first_reached = next(j for j, point in enumerate(previous)
                         if math.hypot(*point) <= (j + 1) * step)
    assert first_reached == 2
    np.testing.assert_allclose(joined[:3], [[20 / 3, 15.0], [40 / 3, 30.0], [20.0, 45.0]])
    np.testing.assert_array_equal(joined[3:], previous[3:])
    assert within_speed_limit(joined, rest)


def test_rejoined_is_the_plan_itself_from_its_own_start_and_none_when_out_of_reach():
    rest = MISSION.replace(start_m=(0.0, 0.0), num_slots=3, horizon_s=6.0, goal_m=(30.0, 0.0))
    previous = np.array([[10.0, 0.0], [20.0, 0.0], [30.0, 0.0]])
    np.testing.assert_allclose(rejoined(previous, (0.0, 0.0), rest), previous)
    assert rejoined(previous[:2], (0.0, 0.0), rest) is None           # not the rest's slots
    far = np.array([[500.0, 0.0], [500.0, 10.0], [500.0, 20.0]])
    assert rejoined(far, (0.0, 0.0), rest) is None
    assert rejoined(np.full((3, 2), np.nan), (0.0, 0.0), rest) is None


def test_a_warm_replan_continues_the_plan_in_force_from_off_its_path(first):
    k = 40
    position = first.trajectory[k] + np.array([30.0, 0.0])     # 30 m east of the plan
    args = (MISSION, position, flown(first, k), SETTINGS)
    steps = {True: 0, False: 0}            # plan() asks should_stop between its steps

    def counter(warm: bool):
        def should_stop() -> bool:
            steps[warm] += 1
            return False
        return should_stop
    warm = replan(*args, previous_q=first.trajectory[k:], warm=True,
                  should_stop=counter(True))
    full = replan(*args, previous_q=first.trajectory[k:], should_stop=counter(False))
    assert set(warm.result.start_throughputs) == {*WARM_STARTS, PREVIOUS_PLAN_START}
    assert len(full.result.start_throughputs) > 10                  # the tours screened again
    print(f'steps: warm {steps[True]}, full {steps[False]}; min throughput warm '
          f'{warm.mission_min_throughput:.6f}, full {full.mission_min_throughput:.6f} bit/s')
    assert 0 < 4 * steps[True] < steps[False]
    # The plan in force, rejoined from the position, is one start: the warm replan promises
    # at least what it gives, and stays near the full search.
    assert warm.result.min_throughput >= warm.result.start_throughputs[PREVIOUS_PLAN_START]
    assert warm.mission_min_throughput >= full.mission_min_throughput * (1 - 2e-3)
    np.testing.assert_allclose(warm.result.scenario.start_m, position)
    assert within_speed_limit(warm.result.trajectory, warm.result.scenario)


def test_warm_only_where_the_plan_in_force_is_a_start(first):
    k = 40
    position = first.trajectory[k]
    problem = receding_problem(MISSION, position, flown(first, k),
                               previous_q=first.trajectory[k:], warm=True)
    start = problem.options.start(PREVIOUS_PLAN_START)
    assert start is problem.previous_start
    warm, options = problem.for_scenario(SETTINGS)
    assert warm.screened_tours == 0 and warm.starts == WARM_STARTS
    assert warm.keep_path_length and not SETTINGS.keep_path_length
    assert warm.shortlist == WARM_SHORTLIST == 1 and SETTINGS.shortlist > 1
    assert warm.relative_tolerance == SETTINGS.relative_tolerance
    assert options.start(PREVIOUS_PLAN_START) is start
    np.testing.assert_array_equal(options.offsets, problem.offsets)
    # A slower scenario the plan in force is too fast for gets it retimed, still warm.
    slower = problem.rest.replace(max_speed_mps=0.9 * MISSION.max_speed_mps)
    assert not within_speed_limit(start, slower)
    warm, options = problem.for_scenario(SETTINGS, slower)
    assert warm.screened_tours == 0 and warm.keep_path_length
    np.testing.assert_array_equal(options.start(PREVIOUS_PLAN_START),
                                  retimed(start, slower))
    # So slow that its path no longer fits the horizon: the tours are screened again.
    slowest = problem.rest.replace(max_speed_mps=0.6 * MISSION.max_speed_mps)
    assert retimed(start, slowest) is None
    settings, options = problem.for_scenario(SETTINGS, slowest)
    assert settings is SETTINGS and not options.extra_starts
    cold = receding_problem(MISSION, position, flown(first, k), previous_q=first.trajectory[k:])
    assert not cold.warm and cold.for_scenario(SETTINGS)[0] is SETTINGS
    # No plan in force that can be rejoined: no warm replan, whatever is asked.
    lost = receding_problem(MISSION, position, flown(first, k),
                            previous_q=first.trajectory[k:] + 900.0, warm=True)
    assert not lost.warm and lost.previous_start is None and not lost.options.extra_starts


def test_the_plan_in_force_kept_is_its_start_with_the_power_optimal_for_it(first):
    """RecedingProblem.kept: the rejoined plan in force (retimed for a slower speed), no
    trajectory step, its power max-min optimal (against the exponential-cone program) and its
    rates by the letter's formula counting the offsets; the warm replan never states less."""
    k = 40
    position = first.trajectory[k] + np.array([0.0, 20.0])
    problem = receding_problem(MISSION, position, flown(first, k),
                               previous_q=first.trajectory[k:], warm=True)
    for share in (1.0, 0.9):
        rest = problem.rest.replace(max_speed_mps=share * MISSION.max_speed_mps)
        kept = problem.kept(rest, SETTINGS)
        start = problem.for_scenario(SETTINGS, rest)[1].start(PREVIOUS_PLAN_START)
        np.testing.assert_array_equal(kept.trajectory, start)
        assert within_speed_limit(kept.trajectory, rest)
        assert kept.outer_iterations == 0 and kept.start == PREVIOUS_PLAN_START
        assert kept.power.sum() <= rest.power_budget_w
        a = snr_per_watt(kept.trajectory, rest)
        cone = conic_power(a, rest.power_budget_w, offsets=problem.offsets)
        by_cone = average_rates(kept.trajectory, cone.p, rest, problem.offsets).min()
        assert kept.min_throughput == pytest.approx(by_cone, rel=1e-5)
        per_use = rest.bandwidth_hz / rest.num_nodes
        by_letter = [per_use * (offset + np.mean(np.log2(1 + p * gain)))
                     for offset, p, gain in zip(problem.offsets, kept.power, a)]
        np.testing.assert_allclose(kept.rates, by_letter, rtol=1e-12)
        warm = plan(rest, *problem.for_scenario(SETTINGS, rest)[:1],
                    **problem.for_scenario(SETTINGS, rest)[1].keywords())
        assert warm.min_throughput >= kept.min_throughput
    slowest = problem.rest.replace(max_speed_mps=0.6 * MISSION.max_speed_mps)
    assert problem.kept(slowest, SETTINGS) is None          # its path no longer fits


def test_retimed_keeps_its_path_and_the_slower_limit_and_reaches_qf(first):
    path = np.vstack([MISSION.start_m, first.trajectory, MISSION.goal_m])
    length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
    fits = []
    for share in (0.95, 0.9, 0.8, 0.7, 0.6):
        slower = MISSION.replace(max_speed_mps=share * MISSION.max_speed_mps)
        q = retimed(first.trajectory, slower)
        fits.append(length <= (MISSION.num_slots + 1) * slower.max_step_m)
        if not fits[-1]:
            assert q is None
            continue
        assert q is not None and within_speed_limit(q, slower, slack=0.0)
        # Every retimed point lies on the plan's path.
        distances = [min(distance_to_segment(point, a, b) for a, b in zip(path, path[1:]))
                     for point in q]
        assert max(distances) < 1e-6
    assert any(fits) and not all(fits)
    np.testing.assert_array_equal(retimed(first.trajectory, MISSION), first.trajectory)


def distance_to_segment(point, a, b) -> float:
    ab = b - a
    t = 0.0 if not ab.any() else float(np.clip((point - a) @ ab / (ab @ ab), 0.0, 1.0))
    return float(np.linalg.norm(point - (a + t * ab)))


def test_the_vehicle_aware_pipeline_plans_every_speed_warm_then_the_other_tours(first):
    # After 20 slots the vehicle cannot fly the warm plan nor the plan in force on time (after
    # 40, with the first plan's split searched, it flies the warm plan at once).
    k = 20
    calls = []

    def recording(scenario, settings, **options):
        calls.append((scenario.max_speed_mps, settings.screened_tours,
                      PREVIOUS_PLAN_START in options.get('extra_starts', {})))
        return plan(scenario, settings, **options)

    in_flight = InFlight(position_m=tuple(first.trajectory[k]), flown=flown(first, k),
                         previous_q=np.array(first.trajectory[k:]), mission_id=1, segment=0,
                         slots_kept=k, warm=True)
    planned = plan_mission(MissionRequest(MISSION, SETTINGS, items=False, in_flight=in_flight,
                                          vehicle=VehicleLimits(max_accel_mpss=1.0)),
                           planner=recording)
    print(calls)
    assert calls[0] == (MISSION.max_speed_mps, 0, True)
    assert len(calls) >= 2          # the vehicle's slow starts and stops spoil the first plan
    assert len(set(calls)) == len(calls), 'a search repeated at one speed'
    assert planned.optimised.scenario.max_speed_mps in {speed for speed, _, _ in calls}


def test_the_vehicle_ladder_tries_the_wider_search_unless_a_close_slower_plan_flies():
    """plan_for_vehicle's order with a wider search: the plan at a speed; when the vehicle
    cannot fly it, the plan at the next speed if that flies and states within
    WIDER_SEARCH_GAIN of it, else the wider search at the speed; each planned once."""
    calls = []

    def tagged(tag, slower_share=1.0):
        def planner(scenario, settings):
            calls.append((tag, scenario.max_speed_mps))
            if tag == 'wide':
                return None                              # nothing to add at any speed
            result = plan(scenario, SETTINGS)
            steps = round(MISSION.max_speed_mps - scenario.max_speed_mps)   # 1 m/s a step
            return dataclasses.replace(result, min_throughput=slower_share ** steps)
        return planner

    slow = VehicleLimits(max_accel_mpss=0.5)
    plain = plan_for_vehicle(MISSION, slow, sources=tagged('plan'))
    ladder = [speed for _, speed in calls]
    assert len(ladder) == 3 and ladder == sorted(ladder, reverse=True)    # fast to slow
    assert plain.ideal.scenario.max_speed_mps == ladder[-1]
    first, second, third = ladder
    # The slower plans state as much: the one at the third speed flies and is taken as the
    # look-ahead from the second, without the wider search there.
    calls.clear()
    close = plan_for_vehicle(MISSION, slow, policy=WARM_REPLAN, sources={
        Source.OPTIMISER: tagged('plan'), Source.OTHER_TOURS: tagged('wide')})
    assert calls == [('plan', first), ('plan', second), ('wide', first), ('plan', third)]
    assert close.ideal.scenario.max_speed_mps == third
    # Each speed states more than WIDER_SEARCH_GAIN less than the one before: the wider search
    # runs at each speed first.
    calls.clear()
    far = plan_for_vehicle(MISSION, slow, policy=WARM_REPLAN, sources={
        Source.OTHER_TOURS: tagged('wide'),
        Source.OPTIMISER: tagged('plan', slower_share=1.0 - 2 * WIDER_SEARCH_GAIN)})
    assert calls == [('plan', first), ('plan', second), ('wide', first), ('plan', third),
                     ('wide', second)]
    assert far.ideal.scenario.max_speed_mps == third
    # A wider search that flies, but delivers less as flown than the slower plan that flies
    # beside it, is not taken over it.
    calls.clear()

    def spoilt(scenario, settings):
        calls.append(('wide', scenario.max_speed_mps))
        if scenario.max_speed_mps == first:
            return None
        result = plan(scenario, SETTINGS)
        worse = np.repeat(result.trajectory[:1], len(result.trajectory), axis=0)
        return dataclasses.replace(result, trajectory=worse)      # hovers at its first point
    kept = plan_for_vehicle(MISSION, slow, policy=WARM_REPLAN, sources={
        Source.OTHER_TOURS: spoilt,
        Source.OPTIMISER: tagged('plan', slower_share=1.0 - 2 * WIDER_SEARCH_GAIN)})
    assert ('wide', second) in calls
    assert kept.ideal.scenario.max_speed_mps == third
    spoilt_flown = plan_for_vehicle(MISSION.replace(max_speed_mps=second), slow,
                                    sources=spoilt).flown.min_throughput
    assert spoilt_flown < kept.flown.min_throughput


def test_the_vehicle_ladder_takes_the_plan_in_force_kept_where_it_flies_close():
    """With the plan in force as a source (WARM_REPLAN): where the vehicle cannot fly the warm
    plan at a speed, the plan in force flown on is tried first at that speed and taken when it
    delivers, as flown, within WIDER_SEARCH_GAIN of what the warm plan stated; otherwise the
    ladder goes on and the kept plan is one of those the best flown is chosen from."""
    slow = VehicleLimits(max_accel_mpss=0.5)
    calls = []
    speeds = []

    def measured(scenario, settings):
        speeds.append(scenario.max_speed_mps)
        return plan(scenario, SETTINGS)
    plan_for_vehicle(MISSION, slow, sources=measured)
    first, second, third = speeds                # the vehicle flies the third speed's plan

    def kept(scenario, settings):
        calls.append(('kept', scenario.max_speed_mps))
        flyable = plan(scenario.replace(max_speed_mps=third), SETTINGS)
        return dataclasses.replace(flyable, scenario=scenario)
    held = plan_for_vehicle(MISSION, slow, sources=kept).flown.min_throughput

    def stating(share):
        def planner(scenario, settings):
            calls.append(('plan', scenario.max_speed_mps))
            return dataclasses.replace(plan(scenario, SETTINGS), min_throughput=held / share)
        return planner

    def wide(scenario, settings):
        calls.append(('wide', scenario.max_speed_mps))
        return None
    calls.clear()
    close = plan_for_vehicle(MISSION, slow, policy=WARM_REPLAN, sources={
        Source.OPTIMISER: stating(1 - 0.5 * WIDER_SEARCH_GAIN), Source.OTHER_TOURS: wide,
        Source.PLAN_IN_FORCE: kept})
    assert calls == [('plan', first), ('kept', first)]
    assert close.ideal.scenario.max_speed_mps == first
    assert close.flown.min_throughput == held
    calls.clear()
    far = plan_for_vehicle(MISSION, slow, policy=WARM_REPLAN, sources={
        Source.OPTIMISER: stating(1 - 2 * WIDER_SEARCH_GAIN), Source.OTHER_TOURS: wide,
        Source.PLAN_IN_FORCE: kept})
    # The second speed's plan does not fly and the wider search adds none: the kept plan is
    # the one candidate left, taken over planning a third speed.
    assert calls == [('plan', first), ('kept', first), ('plan', second), ('wide', first)]
    assert far.flown.min_throughput == held and far.ideal.scenario.max_speed_mps == first


class StandInVehicle:
    linked = False
    upload_pending = False


class StandInNode:
    """What MissionFlight asks of its node, recording the replans."""

    def __init__(self, scenario) -> None:
        self.config = PlannerConfig(scenario, SETTINGS, NodeSettings(vehicle_aware=False))
        self.vehicle = StandInVehicle()
        self.vehicle.battery = BatteryWatch(self)
        self.submitted: list[InFlight] = []

    def get_logger(self):
        class Quiet:
            def info(self, *_):
                pass
            warning = error = info
        return Quiet()

    def submit(self, reason: str, in_flight=None) -> None:
        self.submitted.append(in_flight)

    def refuse(self, *_, **__) -> None:
        raise AssertionError('refused')

    def clock_s(self) -> float:
        return 0.0


@pytest.mark.parametrize('nodes_moved', [False, True])
def test_the_node_replans_from_the_optimised_plan_warm_for_the_same_nodes(first, nodes_moved):
    """The flown plan (here the optimised one shifted 3 m, as a vehicle's timing moves it) is
    what the clock and the off-plan test follow; the replan continues the optimiser's plan."""
    nodes = np.asarray(MISSION.ground_nodes_m) + (50.0 if nodes_moved else 0.0)
    node = StandInNode(MISSION.replace(ground_nodes_m=nodes.tolist()))
    flight = MissionFlight(node)
    as_flown = dataclasses.replace(first, trajectory=first.trajectory + np.array([0.0, 3.0]))
    flight.progress.begin(MISSION, as_flown, planned=first)
    flight.progress.start_clock(0.0)
    for t in np.round(np.arange(1, 1200) * 0.1, 6):
        x, y = planned_position(first, t)
        if t >= 60.0:
            y += 5.0 * (t - 60.0)           # pushed north at 5 m/s
        flight.on_position(t, x, y, source='uav_pose')
        if node.submitted:
            break
    assert len(node.submitted) == 1
    rest = node.submitted[0]
    np.testing.assert_array_equal(rest.previous_q, first.trajectory[rest.slots_kept:])
    assert rest.warm is not nodes_moved


def test_a_warm_replan_keeps_its_path_length_and_the_vehicle_flies_it_at_once():
    """The replan mission of seed 5 after 100 slots: the plan in force was planned at 9 m/s
    (ArduCopter's jerk and acceleration make the 10 m/s plans late); continued at 10 m/s free
    to lengthen its path, it would reach qF 9 s late and the ladder would search on. With the
    path kept no longer, the warm plan at full speed is the one flown."""
    scenario = replan_mission(5)
    first_plan = plan_mission(MissionRequest(scenario, items=False))
    assert first_plan.vehicle_plan.ideal.scenario.max_speed_mps < scenario.max_speed_mps
    progress = MissionProgress()
    progress.begin(scenario, first_plan.result, planned=first_plan.optimised)
    progress.start_clock(0.0)
    time_s = 100.5 * scenario.slot_s
    in_flight = progress.in_flight(scenario, time_s, tuple(planned_position(
        first_plan.result, time_s)), None)
    replanned = plan_mission(MissionRequest(scenario, in_flight=in_flight, items=False))
    ideal = replanned.vehicle_plan.ideal
    assert ideal.start == PREVIOUS_PLAN_START
    assert ideal.scenario.max_speed_mps == scenario.max_speed_mps
    # The same warm search with its steps free to lengthen the path: the vehicle is late.
    problem = receding_problem(scenario, in_flight.position_m, in_flight.flown,
                               previous_q=in_flight.previous_q, warm=True)
    settings, options = problem.for_scenario(None)
    free = plan(problem.rest, dataclasses.replace(settings, keep_path_length=False),
                **options.keywords())
    for stop_at_hovers in (True, False):
        with pytest.raises(InfeasibleHorizonError, match='cannot fly this plan on time'):
            schedule_flight(free, VehicleLimits(), stop_at_hovers=stop_at_hovers)
    warm = plan(problem.rest, settings, **options.keywords())
    assert warm.start == PREVIOUS_PLAN_START
    schedule_flight(warm, VehicleLimits())
    start = problem.kept()
    assert (path_length_km(warm.trajectory, warm.scenario)
            <= path_length_km(start.trajectory, start.scenario) * (1 + 1e-9)
            < path_length_km(free.trajectory, free.scenario))
