"""The plans a mission tries are data: a policy's speeds, fallbacks and last resort change
what plan_for_vehicle does, and the options a plan is asked for are typed."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from uav_comm_planner import plan, SolverSettings
from uav_comm_planner.core.drops import random_scenario
from uav_comm_planner.core.plan_options import PlanOptions
from uav_comm_planner.errors import InfeasibleHorizonError, InvalidScenarioError
from uav_comm_planner.mission.policy import (Fallback, FIRST_PLAN, plan_for_vehicle,
                                             PlanningPolicy, Source, WARM_REPLAN)
from uav_comm_planner.vehicle.flyable import schedule_flight
from uav_comm_planner.vehicle.limits import VehicleLimits

SETTINGS = SolverSettings(compute_baselines=False)
MISSION = random_scenario(8, 150, 3, side_m=1200.0, horizon_s=300.0, max_speed_mps=10.0)
#: A slow vehicle: it cannot fly MISSION's plan at the full planning speed on time.
SLOW = VehicleLimits(max_accel_mpss=0.5)


def recording(calls):
    def optimiser(scenario, settings):
        calls.append(scenario.max_speed_mps)
        return plan(scenario, SETTINGS)
    return optimiser


def test_the_speeds_tried_are_the_policy_s():
    calls = []
    flown = plan_for_vehicle(MISSION, SLOW, sources=recording(calls))
    assert calls == [share * MISSION.max_speed_mps
                     for share in FIRST_PLAN.speed_shares[:len(calls)]]
    assert len(calls) >= 2 and flown.ideal.scenario.max_speed_mps == calls[-1]
    # Another list of speeds, another ladder: every other speed.
    calls.clear()
    sparse = PlanningPolicy(speed_shares=FIRST_PLAN.speed_shares[::2])
    flown = plan_for_vehicle(MISSION, SLOW, sources=recording(calls), policy=sparse)
    assert calls == [share * MISSION.max_speed_mps
                     for share in sparse.speed_shares[:len(calls)]]
    schedule_flight(flown.ideal, SLOW)                    # what it returns flies on time


def test_without_slower_speeds_the_straight_line_is_the_last_resort_or_none():
    calls = []
    line = plan_for_vehicle(MISSION, SLOW, sources=recording(calls),
                            policy=PlanningPolicy(speed_shares=(1.0,)))
    # The optimiser's plan at 10 m/s does not fly; the straight line q0 -> qF does, planned
    # at exactly its own ground speed.
    distance = math.dist(MISSION.start_m, MISSION.goal_m)
    assert calls[0] == MISSION.max_speed_mps
    assert calls[1] == pytest.approx(distance / (MISSION.num_slots + 1) / MISSION.slot_s,
                                     rel=1e-6)
    legs = np.diff(np.vstack([MISSION.start_m, line.ideal.trajectory, MISSION.goal_m]), axis=0)
    across = legs[:, 0] * MISSION.goal_m[1] - legs[:, 1] * MISSION.goal_m[0]
    np.testing.assert_allclose(across, 0.0, atol=1e-6 * distance ** 2)
    with pytest.raises(InfeasibleHorizonError, match='cannot fly this plan on time'):
        plan_for_vehicle(MISSION, SLOW, sources=recording([]),
                         policy=PlanningPolicy(speed_shares=(1.0,), straight_line=False))


def test_a_fallback_the_policy_does_not_list_is_never_asked():
    asked = []
    flyable = plan_for_vehicle(MISSION, SLOW, sources=recording([])).ideal

    def plan_in_force(scenario, settings):     # a plan the vehicle flies, whatever the speed
        asked.append(scenario.max_speed_mps)
        return dataclasses.replace(flyable, scenario=scenario)

    sources = {Source.OPTIMISER: recording([]), Source.PLAN_IN_FORCE: plan_in_force}
    plan_for_vehicle(MISSION, SLOW, sources=sources, policy=FIRST_PLAN)
    assert asked == []
    # Listed, it is asked at the first speed the optimiser's plan does not fly at, and taken
    # there: with no share to be within, it is the best (the only) one flown.
    taken = plan_for_vehicle(MISSION, SLOW, sources=sources, policy=PlanningPolicy(
        fallbacks=(Fallback(Source.PLAN_IN_FORCE),)))
    assert asked == [MISSION.max_speed_mps]
    assert taken.ideal.scenario.max_speed_mps == MISSION.max_speed_mps
    assert WARM_REPLAN.sources == frozenset(Source)


def test_a_fallback_is_checked_when_it_is_made():
    with pytest.raises(InvalidScenarioError, match='judged'):
        Fallback(Source.OTHER_TOURS, judged='promised')
    with pytest.raises(InvalidScenarioError, match='slower'):
        Fallback(Source.OPTIMISER, slower=-1)


def test_plan_options_are_typed_and_give_only_what_is_set():
    assert PlanOptions().keywords() == {}
    start = np.zeros((3, 2))
    options = PlanOptions(offsets=np.ones(2)).with_starts(previous=start)
    keywords = options.keywords()
    assert set(keywords) == {'offsets', 'extra_starts'} and keywords['extra_starts'] == {
        'previous': start}
    assert options.start('previous') is start and options.start('other') is None
    with pytest.raises(TypeError):
        options.extra_starts['other'] = start               # read-only once made
    with pytest.raises(dataclasses.FrozenInstanceError):
        options.offsets = None
    with pytest.raises(InvalidScenarioError, match='callable'):
        PlanOptions(should_stop=True)
