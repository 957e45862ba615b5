"""Wind in the optimiser: the airspeed disc ||v - w|| <= V_air beside the speed limit.

Each figure is checked independently: the legs of every plan against both discs with numpy,
the fast path against the cvxpy reference, the reach of the goal against the closed form of
the fastest ground speed, and still air against the letter's plan exactly.
"""

from __future__ import annotations

import math

from helpers import random_scenario
import numpy as np
import pytest

from uav_comm_planner import InfeasibleHorizonError, paper_scenario, plan, SolverSettings
from uav_comm_planner.core.feasibility import project_onto_speed_limit, within_speed_limit
from uav_comm_planner.core.initial import hover_and_fly, straight_line
from uav_comm_planner.core.model import legs

FAST = SolverSettings(compute_baselines=False)


def windy(case: str = 'I', speed: float = 6.0, from_deg: float = 90.0, **changes):
    """The letter's case I at a multirotor's 10 m/s over 600 s, in wind, airspeed 10 m/s."""
    settings = dict(max_speed_mps=10.0, horizon_s=600.0, num_slots=150, wind_speed_mps=speed,
                    wind_from_deg=from_deg, max_airspeed_mps=10.0)
    settings.update(changes)
    return paper_scenario(case, **settings)


def assert_within_both_discs(q, scenario, slack=1e-7):
    steps = legs(q, scenario)
    ground = np.linalg.norm(steps, axis=1) / scenario.slot_s
    # The air's velocity, written from the weather report's convention independently.
    theta = math.radians(scenario.wind_from_deg)
    wind = -scenario.wind_speed_mps * np.array([math.sin(theta), math.cos(theta)])
    air = np.linalg.norm(steps / scenario.slot_s - wind, axis=1)
    assert ground.max() <= scenario.max_speed_mps * (1 + slack)
    assert air.max() <= scenario.airspeed_mps * (1 + slack)


def test_the_wind_blows_from_where_weather_reports_say():
    east = windy(from_deg=90.0)
    np.testing.assert_allclose(east.wind_mps, [-6.0, 0.0], atol=1e-12)     # towards the west
    north = windy(from_deg=0.0)
    np.testing.assert_allclose(north.wind_mps, [0.0, -6.0], atol=1e-12)
    # Against the wind the UAV makes V_air - |w|, with it V (its ground limit).
    assert east.fastest_ground_speed_mps((1.0, 0.0)) == pytest.approx(4.0)
    assert east.fastest_ground_speed_mps((-1.0, 0.0)) == pytest.approx(10.0)
    # Across it: sqrt(V_air^2 - |w|^2).
    assert east.fastest_ground_speed_mps((0.0, 1.0)) == pytest.approx(8.0)


def test_still_air_is_the_letters_problem_exactly():
    letter = plan(paper_scenario('I'))
    calm = plan(paper_scenario('I', wind_speed_mps=0.0, wind_from_deg=123.0))
    np.testing.assert_array_equal(calm.trajectory, letter.trajectory)
    assert calm.min_throughput == letter.min_throughput
    assert not paper_scenario('I', max_airspeed_mps=100.0).airspeed_limited


@pytest.mark.parametrize('from_deg', [0.0, 90.0, 180.0, 270.0, 45.0])
def test_every_plan_and_start_keeps_both_discs_and_the_objective_climbs(from_deg):
    scenario = windy(from_deg=from_deg)
    for q in (straight_line(scenario), hover_and_fly(scenario)):
        assert_within_both_discs(q, scenario, slack=1e-12)
    result = plan(scenario, FAST)
    assert_within_both_discs(result.trajectory, scenario)
    values = [step.min_throughput for step in result.history]
    assert all(b >= a for a, b in zip(values, values[1:]))


@pytest.mark.parametrize('seed', range(4))
def test_the_fast_path_and_the_reference_agree_in_wind(seed):
    rng = np.random.default_rng(seed)
    scenario = random_scenario(seed, nodes=4, slots=40, side_m=800.0, max_speed_mps=15.0,
                               horizon_s=200.0, wind_speed_mps=float(rng.uniform(2.0, 8.0)),
                               wind_from_deg=float(rng.uniform(0.0, 360.0)),
                               max_airspeed_mps=12.0)
    # The same steps on both paths: full SCA loops at the tight tolerance, no screening.
    same_steps = SolverSettings(compute_baselines=False, screened_tours=0, fast_steps=False)
    fast = plan(scenario, same_steps)
    reference = plan(scenario, same_steps, power_method='conic', trajectory_method='cvxpy')
    assert fast.min_throughput == pytest.approx(reference.min_throughput, rel=1e-6)
    for result in (fast, reference):
        assert_within_both_discs(result.trajectory, scenario)


def test_a_headwind_makes_the_goal_unreachable_and_says_the_horizon_needed():
    # 2000 m east against 6 m/s at 10 m/s airspeed: 4 m/s, so 101 legs need 495 s.
    with pytest.raises(InfeasibleHorizonError, match=r'raise horizon_s to 495\.0 s'):
        windy(horizon_s=400.0, num_slots=100)
    fits = windy(horizon_s=495.1, num_slots=100)
    assert within_speed_limit(straight_line(fits), fits)


def test_a_wind_the_uav_cannot_hold_against_is_refused():
    with pytest.raises(InfeasibleHorizonError, match='cannot hold its position'):
        windy(speed=10.0)


def test_the_projection_keeps_both_discs():
    scenario = windy(from_deg=45.0)
    rng = np.random.default_rng(4)
    wiggled = straight_line(scenario) + rng.normal(0.0, 40.0, (scenario.num_slots, 2))
    assert not within_speed_limit(wiggled, scenario)
    projected = project_onto_speed_limit(wiggled, scenario)
    assert_within_both_discs(projected, scenario, slack=1e-12)
