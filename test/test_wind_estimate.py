"""The wind measured in flight: WIND and WIND_COV decoded into the air's velocity, the
exponential smoothing against its closed form, the scenario's terms, and the target stream's
messages and fallbacks against a recording link (no vehicle needed)."""

from __future__ import annotations

import math
from types import SimpleNamespace

from helpers import NODES_B, two_node_stream_reference
import numpy as np
from pymavlink import mavutil
import pytest

from uav_comm_planner import paper_scenario
from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.mission.wind import WindEstimate
from uav_comm_planner.vehicle.geodesy import geodetic_to_enu, Home
from uav_comm_planner.vehicle.mavlink.guided import (COPTER_MODES, MODE_TRIES, STREAM_GAP_S,
                                                     StreamJob, TargetStream)
from uav_comm_planner.vehicle.mavlink.items import Q0_SEQ
from uav_comm_planner.vehicle.mavlink.telemetry import wind_of

MAV = mavutil.mavlink
HOME = Home(-35.363262, 149.165237, 584.0)


def message(kind: str, **fields):
    return SimpleNamespace(get_type=lambda: kind, **fields)


def test_ardupilots_wind_comes_from_its_direction_and_px4s_is_the_airs_velocity():
    # SIM_WIND_DIR 90 (from the east) was reported as direction 90 by ArduCopter SITL.
    wind = wind_of(message('WIND', direction=90.0, speed=6.0, speed_z=0.0), 12.5)
    assert (wind.time_s, wind.east_mps, wind.north_mps) == pytest.approx((12.5, -6.0, 0.0))
    wind = wind_of(message('WIND', direction=-180.0, speed=2.0, speed_z=0.0), 0.0)
    assert (wind.east_mps, wind.north_mps) == pytest.approx((0.0, 2.0))   # from the south
    # What ArduCopter sends without its drag model: no estimate (the parameter's wind holds).
    assert wind_of(message('WIND', direction=-180.0, speed=0.0, speed_z=0.0), 3.0) is None
    wind = wind_of(message('WIND_COV', wind_x=3.0, wind_y=-4.0), 1.0)       # north, east
    assert (wind.east_mps, wind.north_mps) == pytest.approx((-4.0, 3.0))
    assert wind_of(message('WIND_COV', wind_x=math.nan, wind_y=0.0), 1.0) is None


def test_the_smoothing_is_the_exponential_filter_and_gives_the_scenarios_terms():
    estimate = WindEstimate(time_constant_s=10.0)
    assert not estimate.known and estimate.speed_mps == 0.0
    estimate.add(0.0, 0.0, 0.0)
    steps = np.arange(1, 301) * 0.5                 # 2 Hz for 150 s of a steady east wind
    for t in steps:
        estimate.add(t, -6.0, 0.0)
    # The same first-order filter in closed form at 2 Hz: w(t) = -6 (1 - exp(-t / tau)).
    assert estimate.velocity_mps[0] == pytest.approx(-6.0 * (1 - math.exp(-150.0 / 10.0)),
                                                     rel=1e-9)
    assert estimate.from_deg == pytest.approx(90.0)
    scenario = paper_scenario('I', max_speed_mps=10.0, horizon_s=600.0, num_slots=100)
    windy = estimate.for_scenario(scenario)
    assert windy.wind_speed_mps == pytest.approx(6.0, abs=1e-3)
    np.testing.assert_allclose(windy.wind_mps, estimate.velocity_mps, atol=1e-2)
    assert estimate.differs_from(scenario, 1.0) and not estimate.differs_from(windy, 0.1)
    with pytest.raises(InvalidScenarioError, match='time constant'):
        WindEstimate(0.0)


def test_a_sample_after_a_lost_link_weighs_as_one_after_a_telemetry_gap_not_the_whole_gap():
    """A link down for 24 s of autopilot time: no estimate heard is no evidence of the wind,
    so the first sample after it (one gust of a turbulent wind) weighs as one TRACK_GAP_S
    after the last, not as 24 s of wind (1 - exp(-2.4) = 0.91 of the weight at tau 10 s)."""
    from uav_comm_planner.mission.progress import TRACK_GAP_S

    tau = 10.0
    estimate = WindEstimate(time_constant_s=tau)
    for t in np.arange(0, 121) * 0.25:                  # 4 Hz for 30 s: 6 m/s from the east
        estimate.add(float(t), -6.0, 0.0)
    before = estimate.velocity_mps
    estimate.add(30.0 + 24.0, -7.0, 0.0)                # the first sample after the gap
    expected = before[0] + (1 - math.exp(-TRACK_GAP_S / tau)) * (-7.0 - before[0])
    print(f'after the gap: {estimate.velocity_mps[0]:.4f} m/s east (the whole gap would give '
          f'{before[0] + (1 - math.exp(-24.0 / tau)) * (-7.0 - before[0]):.4f})')
    assert estimate.velocity_mps[0] == pytest.approx(expected, rel=1e-12)
    assert estimate.speed_mps < 6.2
    # Steps within a telemetry gap are the exponential filter unchanged.
    estimate.add(54.0 + TRACK_GAP_S, -6.0, 0.0)
    assert estimate.velocity_mps[0] == pytest.approx(
        expected + (1 - math.exp(-TRACK_GAP_S / tau)) * (-6.0 - expected), rel=1e-12)


class RecordingLink:
    """What a TargetStream sends, recorded: targets, mode changes, current items."""

    target_system = 1
    target_component = 1

    def __init__(self) -> None:
        self.targets, self.modes, self.currents = [], [], []
        self.mav = SimpleNamespace(
            set_position_target_global_int_send=lambda *a: self.targets.append(a),
            set_mode_send=lambda system, flags, mode: self.modes.append(mode),
            mission_set_current_send=lambda system, component, seq: self.currents.append(seq))


def heartbeat(mode: str):
    return SimpleNamespace(base_mode=MAV.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                           custom_mode=COPTER_MODES[mode])


@pytest.fixture(scope='module')
def reference():
    return two_node_stream_reference()


def test_targets_are_the_reference_at_the_autopilot_time_and_the_plan_end_falls_back(
        reference):
    events = []
    stream = TargetStream(HOME, events.append)
    link = RecordingLink()
    t0 = 100.0
    stream.start(StreamJob(reference, t0, 100.0, 'auto', lambda elapsed_s: 7))
    stream.tick(link, t0)
    assert link.modes == [COPTER_MODES['GUIDED']]
    stream.on_heartbeat(heartbeat('GUIDED'))
    stream.tick(link, t0 + 0.01)
    assert link.modes == [COPTER_MODES['GUIDED']]          # not asked again once it holds
    for t in t0 + np.arange(1, int((reference.duration_s + 1.0) / 0.05)) * 0.05:
        stream.tick(link, float(t))
    assert [event.kind for event in events] == ['started']
    # Target k is the reference at its autopilot time, north-east-down.
    target = link.targets[101]          # (after the ticks at t0 and t0 + 0.01)
    elapsed = 100 * 0.05
    position, velocity, accel = (v[0] for v in reference.state(elapsed))
    east, north, _ = geodetic_to_enu(np.array([target[5] / 1e7]), np.array([target[6] / 1e7]),
                                     HOME.altitude_m, HOME)
    assert (float(east[0]), float(north[0])) == pytest.approx(tuple(position), abs=0.02)
    assert target[7] == 100.0
    assert target[8:10] == pytest.approx((velocity[1], velocity[0]))
    assert target[11:13] == pytest.approx((accel[1], accel[0]))
    # At the plan's end (and a settling time) the vehicle goes on in AUTO, once, and the
    # node says how far from qF it is (here held 30 m east of it).
    stream.position_m = reference.state(reference.duration_s)[0][0] + np.array([30.0, 0.0])
    for t in t0 + reference.duration_s + 1.0 + np.arange(0, 6, 0.05):
        stream.tick(link, float(t))
    assert [event.kind for event in events] == ['started', 'stopped']
    assert 'reached qF, the vehicle 30.0 m from it' in events[-1].message
    assert 'item 7' in events[-1].message
    assert link.currents == [7] and link.modes[-1] == COPTER_MODES['AUTO']
    assert not stream.active


def test_a_gap_in_the_targets_holds_and_a_pilot_taking_over_ends_the_stream(reference):
    events = []
    stream = TargetStream(HOME, events.append)
    link = RecordingLink()
    stream.start(StreamJob(reference, 0.0, 100.0, 'hold', lambda elapsed_s: 3))
    stream.on_heartbeat(heartbeat('GUIDED'))
    stream.tick(link, 1.0)
    # The link was down meanwhile, early in the plan: the stream catches it up, on.
    stream.tick(link, 1.0 + STREAM_GAP_S + 0.5)
    assert events[0].kind == 'caught up' and 'link was down' in events[0].message
    assert stream.active and len(link.targets) == 2 and link.modes == []
    # Down again until too little of the plan is left to make the time up: held.
    end = reference.duration_s - 1.0
    stream.tick(link, end)
    assert 'link was down' in events[-1].message and 'BRAKE' in events[-1].message
    assert 'cannot be made up' in events[-1].message
    # A vehicle that left the streamed mode meanwhile (PX4's failsafe) is not caught up.
    events.clear()
    stream.start(StreamJob(reference, 0.0, 100.0, 'hold', lambda elapsed_s: 3))
    stream.on_heartbeat(heartbeat('GUIDED'))
    stream.tick(link, 1.0)
    stream.on_heartbeat(heartbeat('BRAKE'))
    stream.tick(link, 1.0 + STREAM_GAP_S + 0.5)
    assert [event.kind for event in events] == ['stopped']
    assert 'link was down' in events[-1].message and not stream.active
    assert link.modes[-1] == COPTER_MODES['BRAKE'] and link.currents == []

    events.clear()
    stream.start(StreamJob(reference, 10.0, 100.0, 'auto', lambda elapsed_s: 3))
    stream.on_heartbeat(heartbeat('GUIDED'))
    stream.tick(link, 10.0)
    stream.tick(link, 12.0)
    assert events[-1].kind == 'started'
    modes = len(link.modes)
    stream.on_heartbeat(heartbeat('AUTO'))                # someone else switched it
    stream.tick(link, 12.1)
    assert 'left GUIDED' in events[-1].message and len(link.modes) == modes
    assert not stream.active


def test_a_link_closing_mid_stream_resumes_the_mission_at_the_item_ahead_not_the_last(
        reference):
    events, asked = [], []
    stream = TargetStream(HOME, events.append)
    link = RecordingLink()

    def resume_item(elapsed_s):
        asked.append(elapsed_s)
        return 4

    stream.start(StreamJob(reference, 50.0, 100.0, 'auto', resume_item))
    stream.on_heartbeat(heartbeat('GUIDED'))
    for t in 50.0 + np.arange(0, 41) * 0.05:       # two seconds of targets
        stream.tick(link, float(t))
    # The vehicle answers the mode change before the link goes.
    answer = heartbeat('AUTO')
    answer.get_srcSystem = lambda: link.target_system
    link.recv_match = lambda **kwargs: answer
    stream.close(link)
    assert asked[-1] == pytest.approx(2.0)       # the last target's time, not the plan's end
    assert link.currents == [4] and link.modes[-1] == COPTER_MODES['AUTO']
    assert 'closing' in events[-1].message


#: PX4's custom modes, from px4_custom_mode (main mode in byte 2, sub mode in byte 3).
PX4_OFFBOARD = 0x00060000
PX4_AUTO_MISSION = 0x04040000
PX4_AUTO_LOITER = 0x03040000


def px4_heartbeat(custom_mode: int):
    return SimpleNamespace(base_mode=MAV.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                           custom_mode=custom_mode)


def test_px4_gets_targets_before_offboard_is_asked_and_goes_on_in_its_mission_after(
        reference):
    events = []
    stream = TargetStream(HOME, events.append)
    stream.vehicle_home = Home(HOME.latitude_deg, HOME.longitude_deg, 600.5)
    link = RecordingLink()
    link.vehicle_autopilot = MAV.MAV_AUTOPILOT_PX4
    stream.on_heartbeat(px4_heartbeat(PX4_AUTO_MISSION))     # holding q0 in its mission
    t0 = 20.0
    stream.start(StreamJob(reference, t0, 100.0, 'auto', lambda elapsed_s: 7))
    ticks = t0 + np.arange(0, 40) * 0.05
    for t in ticks[:10]:                                    # 0.45 s of targets: no mode yet
        stream.tick(link, float(t))
    assert len(link.targets) == 10 and link.modes == []
    stream.tick(link, float(ticks[10]))                     # 0.5 s: OFFBOARD asked
    assert link.modes == [PX4_OFFBOARD]
    stream.on_heartbeat(px4_heartbeat(PX4_OFFBOARD))
    for t in ticks[11:]:
        stream.tick(link, float(t))
    assert link.modes == [PX4_OFFBOARD] and [event.kind for event in events] == ['started']
    assert 'OFFBOARD' in events[0].message
    # Above mean sea level: the vehicle's home altitude and the plan's 100 m.
    target = link.targets[-1]
    assert target[3] == MAV.MAV_FRAME_GLOBAL_INT and target[7] == pytest.approx(700.5)
    assert target[4] == (MAV.POSITION_TARGET_TYPEMASK_YAW_IGNORE
                         | MAV.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE)
    for t in t0 + reference.duration_s + 2.5 + np.arange(0, 1, 0.05):
        stream.tick(link, float(t))
    # PX4 numbers its items without the home row: ArduPilot's item 7 is its item 6.
    assert link.currents == [6] and link.modes[-1] == PX4_AUTO_MISSION
    assert 'reached qF' in events[-1].message
    assert 'back in AUTO.MISSION from mission item 6' in events[-1].message


def test_px4_refusing_offboard_ends_the_stream_once_held_in_loiter(reference):
    events = []
    stream = TargetStream(HOME, events.append)
    link = RecordingLink()
    link.vehicle_autopilot = MAV.MAV_AUTOPILOT_PX4
    stream.on_heartbeat(px4_heartbeat(PX4_AUTO_MISSION))
    stream.start(StreamJob(reference, 0.0, 100.0, 'hold', lambda elapsed_s: 3))
    for t in np.arange(0, 8, 0.05):                         # it never shows OFFBOARD
        stream.tick(link, float(t))
    assert link.modes.count(PX4_OFFBOARD) == MODE_TRIES
    assert [event.kind for event in events] == ['error']
    assert f'did not enter OFFBOARD after {MODE_TRIES} requests' in events[0].message
    assert 'held in AUTO.LOITER' in events[0].message
    assert link.modes[-1] == PX4_AUTO_LOITER and link.currents == [] and not stream.active
    # Without the vehicle's home its targets are above home (PX4 takes them too).
    assert link.targets[0][3] == MAV.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    assert link.targets[0][7] == 100.0


def test_a_replan_resumes_px4_at_its_q0_item_in_its_own_numbering_once_uploaded(reference):
    events = []
    stream = TargetStream(HOME, events.append)
    link = RecordingLink()
    link.vehicle_autopilot = MAV.MAV_AUTOPILOT_PX4
    stream.start(StreamJob(reference, 0.0, 100.0, 'hold', lambda elapsed_s: 5))
    stream.on_heartbeat(px4_heartbeat(PX4_OFFBOARD))
    for t in np.arange(0, 2, 0.05):
        stream.tick(link, float(t))
    stream.stop('a new plan is in force', resume_seq=Q0_SEQ, mission='replan')
    stream.tick(link, 2.0)                  # streamed on until the replan is on board
    assert stream.active and link.currents == []
    stream.uploaded(link, 2.05, 'replan', True)
    assert link.currents == [Q0_SEQ - 1] and link.modes[-1] == PX4_AUTO_MISSION
    assert f'back in AUTO.MISSION from mission item {Q0_SEQ - 1}' in events[-1].message


def test_the_node_plans_for_the_wind_measured_publishes_it_and_keeps_its_parameter_else(
        harness):
    from geometry_msgs.msg import Vector3Stamped

    from uav_comm_planner.ros.wind import TOPIC_WIND, WIND_QOS
    h = harness()
    winds = []
    h.probe.create_subscription(Vector3Stamped, TOPIC_WIND, winds.append, WIND_QOS)
    h.published(1)
    assert h.node.current_plan.request.scenario.wind_speed_mps == 0.0   # the parameter's
    tracker = h.node.vehicle.wind
    tracker.add(0.0, -6.0, 0.0)                         # 6 m/s from the east
    tracker.add(0.5, -6.0, 0.0)                         # the same: no second replan
    h.published(2)
    assert tracker.replans == 1
    scenario = h.node.current_plan.request.scenario
    assert (scenario.wind_speed_mps, scenario.wind_from_deg) == pytest.approx((6.0, 90.0),
                                                                              abs=0.01)
    assert h.node.current_plan.request.reason == 'wind estimate'
    h.spin_until(lambda: winds and winds[-1].vector.x < -5.9, 'wind_estimate')
    assert winds[-1].header.frame_id == 'map' and abs(winds[-1].vector.y) < 1e-9
    # A wind the vehicle cannot fly in is refused, once; the plan in force stays.
    # After 1000 s of silence a sample weighs as one a telemetry gap later (0.095 of it at
    # tau 20 s): the estimate about 148 m/s.
    tracker.add(1000.0, -1500.0, 0.0)
    h.spin_until(lambda: any('wind estimate refused' in line for line in h.error_logs),
                 'refusal of the wind')
    assert h.node.stats.plans_published == 2 and tracker.replans == 1
    # Another request meanwhile is planned, for the parameter's wind, and says so.
    h.send_nodes(NODES_B)
    h.published(3)
    assert h.node.current_plan.request.scenario.wind_speed_mps == 0.0
    assert any('wind estimate: not planned for' in line for line in h.error_logs)
