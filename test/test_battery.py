"""The battery in flight, without SITL: the autopilot's messages read, the energy left and the
decision (keep, replan, end) against computations of their own, the rest planned within the
measured figure, and the node replanning with it.
"""

from __future__ import annotations

import math

import numpy as np
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
import pytest

from uav_comm_planner import paper_scenario, plan, SolverSettings
from uav_comm_planner.core.energy import (Battery, horizon_energy_j, JOULES_PER_WH,
                                          takeoff_landing_j)
from uav_comm_planner.core.receding import (flown_energy_wh, FlownSlots, replan,
                                            rest_of_mission)
from uav_comm_planner.errors import InfeasibleHorizonError, InvalidScenarioError
from uav_comm_planner.mission.battery import (battery_capacity_wh, battery_decision,
                                              consumed_wh, drain_ratio, END,
                                              ENERGY_MARGIN, KEEP, LEAST_SLACK,
                                              MIN_DRAIN_S, MIN_DRAWN_SHARE, path_energy_wh,
                                              plan_rest_energy_wh, REPLAN, rest_allowance_wh,
                                              rest_legs, rest_path, straight_rest_energy_wh)
from uav_comm_planner.ros.diagnostics import ERROR
from uav_comm_planner.ros.params import config_from_parameters
from uav_comm_planner.vehicle.airframe import airframe_named, default_airframe
from uav_comm_planner.vehicle.mavlink.battery import (battery_of, BatteryReport, END_MODES,
                                                      in_end_mode)

ZENG = airframe_named('zeng2019')
SITL_QUAD = default_airframe('ardupilot')
#: Case I at 30 m/s over 200 s in slots of 4 s, Zeng's airframe, a wind.
MISSION = paper_scenario('I', max_speed_mps=30.0, horizon_s=200.0, num_slots=50).replace(
    airframe=ZENG, wind_speed_mps=4.0, wind_from_deg=60.0)
MAV = mavlink2.MAVLink(None)


def battery_status(consumed_hj: int, remaining: int, battery_id: int = 0):
    cells = [4200, 4200, 4200] + [65535] * 7
    return mavlink2.MAVLink_battery_status_message(
        battery_id, 0, 0, 2500, cells, 3150, 1200, consumed_hj, remaining)


def test_battery_status_and_sys_status_are_read_with_their_unknowns():
    report = battery_of(battery_status(1800, 73), 12.5)
    assert report == BatteryReport(12.5, 180000.0, 0.73, 12.6, 31.5, 'BATTERY_STATUS')
    unknown = battery_of(battery_status(-1, -1), 1.0)
    assert unknown is None                  # neither the energy nor the charge is known
    assert math.isnan(battery_of(battery_status(-1, 40), 1.0).consumed_j)
    assert battery_of(battery_status(1800, 73, battery_id=1), 1.0) is None
    system = mavlink2.MAVLink_sys_status_message(0, 0, 0, 500, 11100, -1, 55, 0, 0, 0, 0, 0, 0)
    report = battery_of(system, 3.0)
    assert report.source == 'SYS_STATUS' and report.remaining == 0.55
    assert report.voltage_v == 11.1 and math.isnan(report.current_a)
    assert math.isnan(report.consumed_j)
    assert battery_of(mavlink2.MAVLink_heartbeat_message(2, 3, 0, 0, 0, 3), 1.0) is None


def test_the_end_modes_are_the_autopilots_names():
    assert in_end_mode('rtl', 'RTL') and in_end_mode('land', 'LAND')
    assert in_end_mode('hold', 'BRAKE') and not in_end_mode('land', 'AUTO')
    # PX4's heartbeats as pymavlink names them: AUTO.RTL, AUTO.LAND, AUTO.LOITER.
    px4 = mavlink2.MAV_AUTOPILOT_PX4
    for action, sub_mode in (('rtl', 5), ('land', 6), ('hold', 3)):
        custom = (sub_mode << 24) | (4 << 16)       # main mode AUTO
        beat = mavlink2.MAVLink_heartbeat_message(2, px4, 1, custom, 4, 3)
        assert in_end_mode(action, mavutil.mode_string_v10(beat))
    assert not in_end_mode('rtl', None)
    assert set(END_MODES) == {'rtl', 'land', 'hold'}


@pytest.mark.parametrize('stated, consumed, remaining, expected', [
    (60.0, 8.39, 0.78, 8.39 / 0.22),        # the SITL's 3.3 Ah battery told as 60 Wh
    (60.0, 30.0, 0.60, 60.0),               # the charge says 75 Wh: the stated 60 hold
    (60.0, 2.0, 0.97, 60.0),                # 3 % drawn: too coarse to say
    (60.0, 8.0, math.nan, 60.0),            # no charge reported
    (40.0, 0.0, 0.50, 40.0),                # nothing counted yet
])
def test_the_capacity_is_the_stated_one_or_what_the_vehicle_s_charge_implies(
        stated, consumed, remaining, expected):
    capacity = battery_capacity_wh(stated, consumed, remaining)
    assert capacity == pytest.approx(expected, rel=1e-12)
    assert MIN_DRAWN_SHARE == 0.05


def test_the_allowance_keeps_the_reserve_of_the_capacity_and_pays_the_landing():
    battery = Battery(60.0, 0.2)
    landing = takeoff_landing_j(SITL_QUAD, 100.0)[1] / 3600.0
    allowance, capacity = rest_allowance_wh(battery, 8.39, 0.78, landing)
    # By hand: 8.39 Wh is 22 % of the battery, so it holds 38.136 Wh; 80 % of it usable.
    assert capacity == pytest.approx(38.13636363636, rel=1e-9)
    assert allowance == pytest.approx(0.8 * 38.13636363636 - 8.39 - landing, rel=1e-9)
    assert rest_allowance_wh(battery, 8.39, math.nan, 0.0)[0] == pytest.approx(48.0 - 8.39)


def test_the_rest_s_energy_is_the_horizon_energy_of_the_rest_of_mission():
    """path_energy_wh over the position, the plan's remaining points and qF is the core's
    horizon energy of that rest as rest_of_mission makes it (another path through the code:
    core.model.legs, core.energy.leg_airspeeds)."""
    result = plan(MISSION, SolverSettings(compute_baselines=False))
    k = 12
    position = np.asarray(result.trajectory[k - 1]) + (7.0, -4.0)
    flown = FlownSlots(result.power[:, :k], result.trajectory[:k])
    rest = rest_of_mission(MISSION, position, flown)
    q_rest = np.asarray(result.trajectory[k:])
    expected = horizon_energy_j(q_rest, rest, ZENG) / JOULES_PER_WH
    assert path_energy_wh(rest_path(position, q_rest, MISSION.goal_m), MISSION) == \
        pytest.approx(expected, rel=1e-12)


def test_the_straight_line_energy_is_its_legs_at_one_airspeed():
    position = (400.0, 150.0)
    slots = 20
    legs = slots + 1
    ground = (np.asarray(MISSION.goal_m) - position) / (legs * MISSION.slot_s)
    east, north = MISSION.wind_mps
    airspeed = math.hypot(ground[0] - east, ground[1] - north)
    expected = legs * MISSION.slot_s * float(ZENG.level_power_w(airspeed)) / 3600.0
    energy = straight_rest_energy_wh(MISSION, position, slots)
    assert energy == pytest.approx(expected, rel=1e-12)


def test_the_plan_in_force_needs_the_leg_to_its_next_point_then_its_legs_as_planned():
    result = plan(MISSION, SolverSettings(compute_baselines=False))
    q, delta = np.asarray(result.trajectory), MISSION.slot_s
    wind = np.asarray(MISSION.wind_mps)
    # At its start from q0: the whole horizon's energy.
    assert plan_rest_energy_wh(result, 0.0, MISSION.start_m) == pytest.approx(
        horizon_energy_j(q, MISSION, ZENG) / 3600.0, rel=1e-12)

    def by_hand(k: int, left_s: float, position) -> float:
        first = float(ZENG.level_power_w(np.linalg.norm((q[k] - position) / left_s - wind)))
        path = np.vstack([q[k:], MISSION.goal_m])
        legs = np.linalg.norm(np.diff(path, axis=0) / delta - wind, axis=1)
        return (first * left_s + float(ZENG.level_power_w(legs).sum()) * delta) / 3600.0
    position = np.array([650.0, 120.0])
    # 0.7 of slot 13 left: to q[12] over it; 0.2 left: on to q[13] over 1.2 slots.
    assert plan_rest_energy_wh(result, 12.3 * delta, position) == pytest.approx(
        by_hand(12, 0.7 * delta, position), rel=1e-9)
    assert plan_rest_energy_wh(result, 12.8 * delta, position) == pytest.approx(
        by_hand(13, 1.2 * delta, position), rel=1e-9)
    assert plan_rest_energy_wh(result, (MISSION.num_slots + 1) * delta, MISSION.goal_m) == 0.0


@pytest.mark.parametrize('allowance, needed, least, action, budget', [
    (20.0, 19.0, 15.0, KEEP, 19.4),
    (20.0, 20.0, 15.0, KEEP, 19.4),              # exactly enough is enough
    (18.0, 20.0, 15.0, REPLAN, 17.46),           # 3 % under the energy left
    (15.2, 20.0, 15.0, REPLAN, 15.015),          # the straight line's energy, 0.1 % over
    (15.01, 20.0, 15.0, END, 15.015),            # not even the straight line with its slack
    (-3.0, 20.0, 15.0, END, 15.015),
])
def test_the_decision_keeps_replans_or_ends(allowance, needed, least, action, budget):
    decision = battery_decision(allowance, needed, least)
    assert decision.action == action
    assert decision.budget_wh == pytest.approx(budget, rel=1e-12)
    assert (ENERGY_MARGIN, LEAST_SLACK) == (0.03, 1e-3)
    assert f'{allowance:.2f} Wh left' in decision.reason
    if action == END:
        assert 'cannot reach qF with its reserve' in decision.reason


def test_a_replan_plans_the_rest_with_the_energy_measured_and_keeps_it():
    result = plan(MISSION.replace(energy_budget_wh=40.0),
                  SolverSettings(compute_baselines=False))
    k = 10
    flown = FlownSlots(result.power[:, :k], result.trajectory[:k])
    position = tuple(result.trajectory[k - 1])
    # Predicted: the budget less the model's energy of the flown legs; measured: as given.
    modelled = rest_of_mission(result.scenario, position, flown)
    assert modelled.energy_budget_wh == pytest.approx(
        40.0 - flown_energy_wh(result.scenario, flown), rel=1e-12)
    rest = rest_of_mission(result.scenario, position, flown, energy_left_wh=9.0)
    assert rest.energy_budget_wh == 9.0
    # A mission without a budget of its own gets the measured one.
    free = rest_of_mission(MISSION, position, flown, energy_left_wh=9.0)
    assert free.energy_budget_wh == 9.0
    replanned = replan(MISSION, position, flown, SolverSettings(compute_baselines=False),
                       energy_left_wh=9.0)
    energy = horizon_energy_j(replanned.result.trajectory, replanned.result.scenario, ZENG)
    print(f'rest within 9 Wh: {energy / 3600:.4f} Wh')
    assert energy / 3600.0 <= 9.0 * (1 + 1e-6)
    with pytest.raises(InfeasibleHorizonError, match='no energy is left'):
        rest_of_mission(MISSION, position, flown, energy_left_wh=-1.0)
    with pytest.raises(InfeasibleHorizonError, match='energy left, 1 Wh'):
        rest_of_mission(MISSION, position, flown, energy_left_wh=1.0)


def test_battery_action_is_a_node_parameter_with_its_choices():
    base = {'max_speed_mps': 10.0, 'horizon_s': 400.0, 'num_slots': 100}
    assert config_from_parameters(base).node.battery_action == 'land'
    assert config_from_parameters({**base, 'battery_action': 'rtl'}).node.battery_action == 'rtl'
    with pytest.raises(InvalidScenarioError, match="battery_action must be one of"):
        config_from_parameters({**base, 'battery_action': 'crash'})


def test_the_node_replans_the_rest_within_the_energy_its_battery_report_leaves(harness):
    """Without a link, the battery's report handed to the node as the link hands it: the
    plan in force needs more than the energy left and the straight line less, so the rest is
    replanned within the energy left less the margin, computed here from the report, the
    stated battery and the landing; the plan keeps it, and /diagnostics says so."""
    from std_srvs.srv import Trigger

    from helpers import HORIZON_S, SLOTS
    stated, reserve = 20.0, 0.2
    h = harness(airframe='zeng2019', max_speed_mps=30.0, horizon_s=4 * HORIZON_S,
                num_slots=SLOTS, battery_wh=stated, battery_reserve=reserve)
    h.published(1)
    first = h.node.current_plan
    assert first.result.scenario.airframe == ZENG
    assert h.call('start', Trigger.Request()).success
    h.send_pose(0.0, 0.0)
    h.spin_until(lambda: h.node.flight.track.latest is not None, 'the pose at q0')
    scenario = first.result.scenario
    needed = horizon_energy_j(first.result.trajectory, scenario, ZENG) / 3600.0
    least = straight_rest_energy_wh(scenario, (0.0, 0.0), SLOTS)
    landing = takeoff_landing_j(ZENG, scenario.altitude_m)[1] / 3600.0
    # Used so far: what leaves the rest halfway between the straight line and the plan.
    allowance = (needed + least) / 2
    consumed = stated * (1 - reserve) - landing - allowance
    h.node.vehicle.battery.add(BatteryReport(h.node.clock_s(), consumed * 3600.0, math.nan,
                                             12.0, 20.0, 'BATTERY_STATUS'))
    decision = h.node.vehicle.battery.decision
    print(f'plan {needed:.3f} Wh, straight line {least:.3f} Wh, left {allowance:.3f} Wh: '
          f'{decision.action}')
    assert decision.action == REPLAN
    h.published(2)
    outcome = h.node.current_plan
    budget = allowance * (1 - ENERGY_MARGIN)
    assert outcome.request.reason == 'battery'
    assert outcome.request.mission.in_flight.energy_left_wh == pytest.approx(budget, rel=1e-6)
    rest = outcome.result
    assert rest.scenario.energy_budget_wh == pytest.approx(budget, rel=1e-6)
    energy = horizon_energy_j(rest.trajectory, rest.scenario, ZENG) / 3600.0
    print(f'the rest replanned within {budget:.3f} Wh: {energy:.3f} Wh, min throughput '
          f'{outcome.min_throughput:.4g} bit/s (first plan {first.min_throughput:.4g})')
    assert energy <= budget * (1 + 1e-6) and energy < needed
    level, message, values = h.node.vehicle.battery.status()
    assert values['battery_decision'] == REPLAN and 'replanning the rest within' in message
    assert h.node.vehicle.battery.replans == 1 and not h.node.progress.ended


def test_a_rest_that_cannot_reach_qf_in_time_has_the_legs_that_can():
    """The straight line counts the legs the rest will be lengthened to: ceil(distance /
    (V delta)) when its own slots are too few (here in still air, V = 30 m/s, delta = 4 s)."""
    still = MISSION.replace(wind_speed_mps=0.0)
    assert rest_legs(still, (0.0, 0.0), 30) == 31          # 2000 m in 31 legs: 16 m/s
    assert rest_legs(still, (0.0, 0.0), 10) == math.ceil(2000.0 / 120.0)
    assert rest_legs(still, still.goal_m, 3) == 4
    energy = straight_rest_energy_wh(still, (0.0, 0.0), 10)
    assert energy == pytest.approx(17 * 4.0 * float(ZENG.level_power_w(2000.0 / 68.0)) / 3600,
                                   rel=1e-12)


def test_the_node_ends_a_mission_its_battery_cannot_fly_and_replans_nothing_more(harness):
    """A report that leaves less than the straight line to qF ends the mission: the reason
    once (log, diagnostics), the clock's status says it, a new node set is refused with it;
    ~/replan plans a new mission, which nothing ended."""
    from std_srvs.srv import Trigger

    from helpers import HORIZON_S, NODES_B, SLOTS
    stated = 20.0
    h = harness(airframe='zeng2019', max_speed_mps=30.0, horizon_s=4 * HORIZON_S,
                num_slots=SLOTS, battery_wh=stated)
    h.published(1)
    assert h.call('start', Trigger.Request()).success
    h.send_pose(0.0, 0.0)
    h.spin_until(lambda: h.node.flight.track.latest is not None, 'the pose at q0')
    scenario = h.node.current_plan.result.scenario
    least = straight_rest_energy_wh(scenario, (0.0, 0.0), SLOTS - 1)
    landing = takeoff_landing_j(ZENG, scenario.altitude_m)[1] / 3600.0
    consumed = stated * 0.8 - landing - 0.9 * least     # 90 % of the straight line left
    h.node.vehicle.battery.add(BatteryReport(h.node.clock_s(), consumed * 3600.0, math.nan,
                                             12.0, 20.0, 'BATTERY_STATUS'))
    progress = h.node.progress
    print(progress.ended)
    assert h.node.vehicle.battery.decision.action == END
    assert progress.ended.startswith('battery: mission ended, the vehicle told to land where '
                                     'it is (land)')
    assert 'cannot reach qF with its reserve' in progress.ended
    assert progress.ended in h.node.stats.last_error
    level, message, values = h.node.vehicle.battery.status()
    assert (level, message, values['ended_reason']) == (ERROR, progress.ended, progress.ended)
    assert h.node.diagnostics._clock_status().message == f'mission ended: {progress.ended}'
    errors = h.node.stats.error_count
    h.send_nodes(NODES_B)
    h.spin_until(lambda: h.node.stats.error_count > errors, 'the refusal of the node set')
    assert h.node.stats.last_error.startswith(f'ground_nodes refused: {progress.ended}; the '
                                              f'input applies to the next mission')
    assert h.node.stats.plans_published == 1
    assert h.call('replan', Trigger.Request()).success
    h.published(2)
    assert not h.node.progress.ended and not h.node.progress.started


def test_a_report_without_the_energy_counts_the_charge_drawn_of_the_battery_stated():
    battery = Battery(50.0, 0.2)
    counted = BatteryReport(1.0, 7200.0, 0.9, 12.0, 30.0, 'BATTERY_STATUS')
    uncounted = BatteryReport(1.0, math.nan, 0.9, 12.0, 30.0, 'SYS_STATUS')
    assert consumed_wh(counted, battery) == 2.0
    assert consumed_wh(uncounted, battery) == pytest.approx(5.0, rel=1e-12)
    # Its capacity is then the one stated: the charge is read as a share of it.
    allowance, capacity = rest_allowance_wh(battery, consumed_wh(uncounted, battery), 0.9, 3.0)
    assert capacity == pytest.approx(50.0) and allowance == pytest.approx(40.0 - 5.0 - 3.0)


def test_the_drain_ratio_is_the_battery_s_energy_over_the_model_s_along_the_track():
    """A track at 8 m/s east then hovering, in MISSION's wind: the model's energy by hand,
    step by step; the ratio is what the battery gave over it, never below 1, and 1 on a track
    shorter than MIN_DRAIN_S."""
    times = np.arange(0.0, 40.01, 0.1)
    east = np.where(times <= 20.0, 8.0 * times, 160.0)
    track = np.column_stack([times, east, np.zeros_like(times)])
    wind = np.asarray(MISSION.wind_mps)
    first = float(ZENG.level_power_w(np.linalg.norm(np.array([8.0, 0.0]) - wind))) * 20.0
    second = float(ZENG.level_power_w(np.linalg.norm(wind))) * 20.0
    model_wh = (first + second) / 3600.0
    assert drain_ratio(1.07 * model_wh, track, MISSION) == pytest.approx(1.07, rel=1e-6)
    assert drain_ratio(0.9 * model_wh, track, MISSION) == 1.0
    assert drain_ratio(5.0, track[times < MIN_DRAIN_S - 1.0], MISSION) == 1.0
