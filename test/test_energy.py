"""Propulsion energy: the airframe's power (Zeng 2019, eq. (12)), the horizon's energy, and the
energy budget as a block of the trajectory step, against independent computations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from uav_comm_planner import paper_scenario, plan, SolverSettings
from uav_comm_planner.core.energy import (Battery, horizon_allowance_wh, horizon_energy_j,
                                          takeoff_landing_j)
from uav_comm_planner.core.initial import straight_line
from uav_comm_planner.core.model import snr_per_watt
from uav_comm_planner.core.power import waterfilling_power
from uav_comm_planner.core.propulsion import Airframe, ZENG2019
from uav_comm_planner.core.sca.block import Expansion, Frame
from uav_comm_planner.core.sca.energy import EnergyBudget, induced_slack
from uav_comm_planner.core.sca.fast import trajectory_step_clarabel
from uav_comm_planner.core.sca.program import cone_program, step_blocks
from uav_comm_planner.core.sca.reference import certify, trajectory_step_cvxpy
from uav_comm_planner.errors import InfeasibleHorizonError, InvalidScenarioError


def zeng_power(speed: float) -> float:
    """Eq. (12) of Zeng, Xu and Zhang (2019) as printed, with Table I's numbers."""
    p0, pi, u_tip, v0, d0, rho, s, a = 79.86, 88.63, 120.0, 4.03, 0.6, 1.225, 0.05, 0.503
    return (p0 * (1 + 3 * speed ** 2 / u_tip ** 2)
            + pi * math.sqrt(math.sqrt(1 + speed ** 4 / (4 * v0 ** 4))
                             - speed ** 2 / (2 * v0 ** 2))
            + 0.5 * d0 * rho * s * a * speed ** 3)


def test_zeng_table_one_hover_and_least_power():
    assert ZENG2019.hover_power_w == pytest.approx(168.49, abs=1e-9)
    speed, power = ZENG2019.least_power()
    # The paper: about 126 W near 10.2 m/s.
    assert speed == pytest.approx(10.2, abs=0.05) and power == pytest.approx(126.0, abs=0.05)
    for v in (0.0, 1.0, 4.03, 10.2, 18.0, 30.0):
        assert float(ZENG2019.level_power_w(v)) == pytest.approx(zeng_power(v), rel=1e-12)


def test_an_airframe_refuses_bad_numbers():
    fields = dict(name='x', blade_profile_power_w=80.0, induced_power_w=90.0,
                  tip_speed_mps=120.0, induced_velocity_mps=4.0, fuselage_drag_ratio=0.6,
                  air_density_kg_per_m3=1.225, rotor_solidity=0.05, rotor_disc_area_m2=0.5,
                  top_airspeed_mps=20.0)
    Airframe(**fields)
    for name, value in (('tip_speed_mps', 0.0), ('induced_power_w', -1.0),
                        ('rotor_disc_area_m2', math.nan), ('top_airspeed_mps', 'fast')):
        with pytest.raises(InvalidScenarioError, match=name):
            Airframe(**{**fields, name: value})


def windy(**changes):
    return paper_scenario('I', max_speed_mps=30.0, horizon_s=200.0, num_slots=50,
                          airframe=ZENG2019, wind_speed_mps=4.0, wind_from_deg=60.0, **changes)


def test_the_horizon_energy_is_each_leg_at_its_airspeed_over_one_slot():
    scenario = windy()
    rng = np.random.default_rng(2)
    q = straight_line(scenario) + rng.uniform(-20, 20, (scenario.num_slots, 2))
    path = [scenario.start_m, *map(tuple, q), scenario.goal_m]
    wind = scenario.wind_speed_mps * np.array([math.sin(math.radians(60.0 + 180.0)),
                                               math.cos(math.radians(60.0 + 180.0))])
    expected = 0.0
    for a, b in zip(path, path[1:]):
        velocity = (np.array(b) - np.array(a)) / scenario.slot_s
        expected += zeng_power(float(np.hypot(*(velocity - wind)))) * scenario.slot_s
    assert horizon_energy_j(q, scenario, ZENG2019) == pytest.approx(expected, rel=1e-12)


def test_the_airframe_bounds_the_airspeed_and_a_budget_below_the_least_energy_is_refused():
    slow = Airframe(**{**ZENG2019.__dict__, 'name': 'slow', 'top_airspeed_mps': 12.0})
    assert paper_scenario('I', max_speed_mps=30.0, horizon_s=200.0, num_slots=50,
                          airframe=slow).airspeed_mps == 12.0
    least_wh = 51 * 4.0 * ZENG2019.least_power()[1] / 3600.0
    with pytest.raises(InfeasibleHorizonError, match='below what any flight of this horizon'):
        windy(energy_budget_wh=0.99 * least_wh)
    with pytest.raises(InvalidScenarioError, match='needs an airframe'):
        paper_scenario('I', energy_budget_wh=10.0)


def test_the_tangent_bound_of_the_induced_slack_is_above_the_true_slack():
    """The slack y solving the linearised constraint at (y_k, a_k) is at least the true
    y(V) everywhere and equal at a_k: the planned energy is an upper bound, tight at q^k."""
    scenario = windy(energy_budget_wh=20.0)
    block = EnergyBudget(Frame.of(scenario))
    q_k = straight_line(scenario)
    point = block.at(Expansion(q_k, np.zeros((3, 50))))
    y, _ = block.slack_root(point, point.a_k)
    np.testing.assert_allclose(y, point.y_k, rtol=1e-12)
    rng = np.random.default_rng(0)
    for _ in range(20):
        a = point.a_k + rng.normal(scale=2.0, size=point.a_k.shape)
        y, _ = block.slack_root(point, a)
        assert np.all(y >= induced_slack(np.linalg.norm(a, axis=1)) * (1 - 1e-12))


def energy_case(share: float):
    """Case I at 30 m/s over 200 s with Zeng's airframe and a budget ``share`` of the way from
    the straight line's energy to the unconstrained step's."""
    free_scenario = windy()
    q_k = straight_line(free_scenario)
    p = waterfilling_power(snr_per_watt(q_k, free_scenario), free_scenario.power_budget_w).p
    free = trajectory_step_clarabel(q_k, p, free_scenario)
    line = horizon_energy_j(q_k, free_scenario, ZENG2019)
    step = horizon_energy_j(free.q, free_scenario, ZENG2019)
    budget_wh = (line + share * (step - line)) / 3600.0
    return windy(energy_budget_wh=budget_wh), q_k, p, free


@pytest.mark.parametrize('share', [0.2, 0.6])
def test_both_steps_keep_the_energy_budget_and_agree(share):
    scenario, q_k, p, free = energy_case(share)
    reference = trajectory_step_cvxpy(q_k, p, scenario)
    fast = trajectory_step_clarabel(q_k, p, scenario)
    budget_j = scenario.energy_budget_wh * 3600.0
    for step in (reference, fast):
        assert horizon_energy_j(step.q, scenario, ZENG2019) <= budget_j * (1 + 1e-9)
        assert step.bound < free.bound
    assert fast.bound == pytest.approx(reference.bound, rel=1e-6)
    np.testing.assert_allclose(fast.q / 1000.0, reference.q / 1000.0, atol=1e-4)


def test_the_energy_rows_are_the_block_s_cones_and_tangent_for_any_point():
    scenario, q_k, p, _ = energy_case(0.5)
    frame = Frame.of(scenario)
    blocks = step_blocks(frame)
    assert [type(b).__name__ for b in blocks] == ['NodeRates', 'LegLimits', 'EnergyBudget']
    block = blocks[2]
    program = cone_program(blocks)
    data = [b.at(Expansion(q_k, p)) for b in blocks]
    from uav_comm_planner.core.sca.fast import ClarabelTrajectoryStep
    values, b = ClarabelTrajectoryStep(scenario).cone_data(data)
    a_matrix = program.matrix(values)
    rng = np.random.default_rng(4)
    z = frame.km(q_k + rng.normal(scale=30.0, size=q_k.shape))
    x = rng.uniform(0.1, 2.0, program.num_columns)
    x[1:1 + 2 * scenario.num_slots] = z.ravel()
    slack = (b - a_matrix @ x)[program.first_rows[2]:]
    legs = scenario.num_slots + 1
    own = x[program.first_columns[2]:].reshape(legs, 6)
    speed, u, c, y, h, r = own.T
    a = block.airspeeds(z)
    cones = slack[:15 * legs].reshape(5, legs, 3)
    np.testing.assert_allclose(cones[0], np.column_stack([speed, a]), atol=1e-9)
    np.testing.assert_allclose(cones[1], np.column_stack([(u + 1) / 2, speed, (u - 1) / 2]),
                               atol=1e-12)
    np.testing.assert_allclose(cones[2], np.column_stack([(c + speed) / 2, u, (c - speed) / 2]),
                               atol=1e-12)
    np.testing.assert_allclose(cones[3], np.column_stack([(h + y) / 2, np.ones(legs),
                                                          (h - y) / 2]), atol=1e-12)
    np.testing.assert_allclose(cones[4], np.column_stack([(r + 1) / 2, h, (r - 1) / 2]),
                               atol=1e-12)
    point = data[2]
    tangent = (2 * point.y_k * y - point.y_k ** 2 + 2 * (point.a_k * a).sum(axis=1)
               - (point.a_k ** 2).sum(axis=1) - r)
    np.testing.assert_allclose(slack[15 * legs:16 * legs], tangent, atol=1e-9)
    blade, induced, parasite = block.coefficients
    assert slack[16 * legs] == pytest.approx(
        block.budget - blade * u.sum() - induced * y.sum() - parasite * c.sum(), abs=1e-9)
    # Its certificate refuses a point over the budget.
    over = frame.km(q_k + rng.normal(scale=400.0, size=q_k.shape))
    assert certify(blocks, over, data, [np.ones(3), [np.zeros(legs), np.zeros(legs)],
                                        [np.zeros(1), np.zeros(legs)]]) is None


def test_plans_keep_the_budget_give_up_throughput_and_agree_on_both_paths():
    scenario, _, _, _ = energy_case(0.5)
    settings = SolverSettings.letter(compute_baselines=False)
    free = plan(scenario.replace(energy_budget_wh=None), settings)
    assert horizon_energy_j(free.trajectory, scenario, ZENG2019) > \
        scenario.energy_budget_wh * 3600.0
    fast = plan(scenario, settings)
    reference = plan(scenario, settings, power_method='conic', trajectory_method='cvxpy')
    for result in (fast, reference):
        assert horizon_energy_j(result.trajectory, scenario, ZENG2019) <= \
            scenario.energy_budget_wh * 3600.0 * (1 + 1e-9)
        assert result.min_throughput < free.min_throughput
    assert fast.min_throughput == pytest.approx(reference.min_throughput, rel=1e-5)
    default = plan(scenario, SolverSettings(compute_baselines=False))
    assert horizon_energy_j(default.trajectory, scenario, ZENG2019) <= \
        scenario.energy_budget_wh * 3600.0 * (1 + 1e-9)
    assert default.min_throughput >= fast.min_throughput


def test_a_budget_no_start_keeps_is_refused_with_the_straight_line_s_energy():
    free = windy()
    line_wh = horizon_energy_j(straight_line(free), free, ZENG2019) / 3600.0
    least_wh = 51 * 4.0 * ZENG2019.least_power()[1] / 3600.0
    assert least_wh < 0.99 * line_wh
    scenario = windy(energy_budget_wh=0.99 * line_wh)
    with pytest.raises(InfeasibleHorizonError, match='no start keeps the energy budget'):
        plan(scenario, SolverSettings.letter(compute_baselines=False))


def test_the_battery_pays_takeoff_and_landing_before_the_horizon():
    up, down = takeoff_landing_j(ZENG2019, 100.0)
    # Hovering power (no vertical term in Table I): 40 s up at 2.5 m/s; 60 s down at 1.5 m/s
    # to 10 m, then 20 s at 0.5 m/s.
    assert up == pytest.approx(168.49 * 40.0) and down == pytest.approx(168.49 * 80.0)
    battery = Battery(41.58)
    assert battery.available_wh == pytest.approx(41.58 * 0.8)
    assert horizon_allowance_wh(battery, ZENG2019, 100.0) == pytest.approx(
        41.58 * 0.8 - 168.49 * 120.0 / 3600.0)
    for bad in (dict(usable_wh=0.0), dict(usable_wh=10.0, reserve=1.0),
                dict(usable_wh=math.inf)):
        with pytest.raises(InvalidScenarioError, match='battery'):
            Battery(**bad)


def test_the_node_s_parameters_name_the_airframe_and_cap_the_horizon():
    """airframe, energy_budget_wh and battery_wh (0: none) through the node's one conversion
    of parameters into settings."""
    from uav_comm_planner.ros.params import config_from_parameters

    base = {'max_speed_mps': 30.0, 'horizon_s': 200.0, 'num_slots': 50,
            'vehicle_aware': False}
    plain = config_from_parameters({**base, 'airframe': 'none'})
    assert plain.scenario.airframe is None and plain.scenario.energy_budget_wh is None
    capped = config_from_parameters({**base, 'airframe': 'zeng2019', 'energy_budget_wh': 12.0,
                                     'battery_wh': 30.0})
    allowance = horizon_allowance_wh(Battery(30.0), ZENG2019, 100.0)
    assert capped.scenario.airframe == ZENG2019
    assert capped.scenario.energy_budget_wh == pytest.approx(min(12.0, allowance))
    with pytest.raises(InvalidScenarioError, match='needs an airframe'):
        config_from_parameters({**base, 'airframe': 'none', 'battery_wh': 30.0})
    with pytest.raises(InfeasibleHorizonError, match='the battery cannot fly this mission'):
        config_from_parameters({**base, 'airframe': 'zeng2019', 'battery_wh': 12.0})
    with pytest.raises(InvalidScenarioError, match='battery_reserve'):
        config_from_parameters({**base, 'airframe': 'zeng2019', 'battery_reserve': 1.0})


def test_a_replan_keeps_the_energy_left_after_the_slots_flown():
    """The rest of a mission with an energy budget gets the budget less the flown legs'
    energy (each flown slot a leg from the position before it, at its airspeed), and a rest
    the energy left cannot fly is refused."""
    from uav_comm_planner.core.receding import FlownSlots, rest_of_mission

    mission = windy(energy_budget_wh=12.0)
    line = straight_line(mission)
    k = 20
    flown = FlownSlots(np.zeros((3, k)), line[:k])
    rest = rest_of_mission(mission, line[k - 1], flown)
    path = [mission.start_m, *map(tuple, line[:k])]
    towards = math.radians(60.0 + 180.0)
    wind = 4.0 * np.array([math.sin(towards), math.cos(towards)])
    used_j = sum(zeng_power(float(np.linalg.norm((np.subtract(b, a)) / 4.0 - wind))) * 4.0
                 for a, b in zip(path, path[1:]))
    assert rest.num_slots == mission.num_slots - k
    assert rest.energy_budget_wh == pytest.approx(12.0 - used_j / 3600.0, rel=1e-12)
    zigzag = FlownSlots(np.zeros((3, k)), line[:k] + np.array([0.0, 300.0]) * (
        np.arange(k)[:, None] % 2))
    with pytest.raises(InfeasibleHorizonError, match='the energy budget is spent'):
        rest_of_mission(mission.replace(energy_budget_wh=9.0), line[k - 1], zigzag)
    # 7.2 Wh flies the whole horizon at the least power (7.14 Wh), but after the 20 slots
    # flown less is left than the other 31 slots' 32 legs take at it.
    least_rest_wh = 32 * 4.0 * ZENG2019.least_power()[1] / 3600.0
    assert 7.2 - used_j / 3600.0 < least_rest_wh
    with pytest.raises(InfeasibleHorizonError, match='energy budget left is too little'):
        rest_of_mission(mission.replace(energy_budget_wh=7.2), line[k - 1], flown)
