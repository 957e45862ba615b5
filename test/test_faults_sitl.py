"""The closed loop on ArduCopter SITL when things fail: the link to the vehicle closed for 20 s
mid-flight, a 33 m GPS glitch for 0.2 s, a mission planned for another home.

The node flies the letter's case I (V = 10 m/s, T = 400 s, M = 100) on its own link; the test
holds the SITL's first port and measures in autopilot time (``time_boot_ms``): when the node's
clock started and where the vehicle was then, the whole mission's throughput at the positions
the vehicle occupied at the slot times (the test's own telemetry), and the energy scheduled.
SITL instances 40-49. The 20 s cut in stream mode flies a held-out mission in a 6 m/s wind the
node estimates (instances 30-39, speed-up 5): the stream catches the plan in force up and the
node restates its promise; every point in force must be passed within a slot of its time,
every point of the plan at the cut flown, the time made up, and 99 % of the first promise
delivered.
"""

from __future__ import annotations

import math
import subprocess
import sys
import time
from typing import Callable

from diagnostic_msgs.msg import DiagnosticStatus
import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from sitl_node import DRAG, flights, HELD_OUT, HOME, LinkedNode, Telemetry

from devtools.sitl import MAV, open_link, start_sitl, why_not_runnable
from uav_comm_planner import paper_scenario, plan, SolverSettings
from uav_comm_planner.core.receding import mission_rates_flown
from uav_comm_planner.ros.diagnostics import VEHICLE_LINK
from uav_comm_planner.ros.flight import HOLD_SPEED_MPS, START_HEIGHT_M, START_RADIUS_M
from uav_comm_planner.ros.node import PlannerNode
from uav_comm_planner.ros.wind import PREFLIGHT_RESOLUTION_MPS
from uav_comm_planner.vehicle.evaluation import REACH_RADIUS_M
from uav_comm_planner.vehicle.geodesy import default_home, Home
from uav_comm_planner.vehicle.mavlink.files import export_mission
from uav_comm_planner.vehicle.mavlink.link import download_mission

SPEED_MPS = 10.0
HORIZON_S = 400.0
SLOTS = 100
#: The node's mission parameters for the letter's case I.
CASE_I = {'max_speed_mps': SPEED_MPS, 'horizon_s': HORIZON_S, 'num_slots': SLOTS}
INSTANCES = (40, 49)
#: Wall-clock limit of one flight, generous: it takes about 25 s at the SITL's speedup 20.
WALL_LIMIT_S = 240.0
#: The link is cut this many autopilot seconds into the mission, for OUTAGE_S.
CUT_AT_S = 120.0
OUTAGE_S = 20.0
#: The GPS glitch: GLITCH_M north for GLITCH_S, GLITCH_AT_S into the mission (mid-leg).
GLITCH_AT_S = 100.0
GLITCH_M = 33.0
GLITCH_S = 0.2
METRES_PER_DEGREE = 111_320.0       # SIM_GPS1_GLTCH_X is a latitude offset in degrees
CLI = [sys.executable, '-m', 'uav_comm_planner.tools.cli']

pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(bool(why_not_runnable()), reason=why_not_runnable())]


class Flight(LinkedNode):
    """A SITL and the node linked to it (through a relay when ``proxy``), flying ``mission``
    (case I unless given)."""

    def __init__(self, ros_context, folder, *, proxy: bool = False, mission: dict | None = None,
                 sitl_parameters: dict | None = None, instances: tuple[int, int] = INSTANCES,
                 speedup: int | None = None, **parameters) -> None:
        super().__init__(ros_context, folder,
                         {**(mission or CASE_I), 'compute_baselines': False, **parameters},
                         instances=instances, sitl_parameters=sitl_parameters, speedup=speedup,
                         proxy=proxy, limit_s=WALL_LIMIT_S)

    @property
    def link_states(self) -> list[tuple[bytes, str]]:
        """The vehicle link's /diagnostics level and message."""
        return [(level, message) for level, message, _ in self.states_of(VEHICLE_LINK)]

    def check_flight(self, recorder: Telemetry) -> None:
        """The clock started with the vehicle holding q0; the energy and the throughput."""
        node = self.node
        start = recorder.at(np.array([node.progress.segments[0].start_s]))[0]
        print(f'clock started at {start[0]:.2f} s: vehicle {math.hypot(start[1], start[2]):.2f}'
              f' m from q0, {start[3]:.2f} m up, {start[4]:.2f} m/s')
        assert math.hypot(start[1], start[2]) <= START_RADIUS_M + 0.5
        assert abs(start[3] - 100.0) <= START_HEIGHT_M + 0.5
        assert start[4] <= HOLD_SPEED_MPS + 0.5
        outcome = node.current_plan
        schedule, kept = node.progress.schedule()
        mission = paper_scenario('I', max_speed_mps=SPEED_MPS, horizon_s=HORIZON_S,
                                 num_slots=SLOTS)
        energy = schedule.sum()
        print(f'energy {energy:.12g} W (P_T {mission.power_budget_w:g} W) in {len(kept)} plans')
        assert energy <= mission.power_budget_w * (1 + 1e-9)
        times = np.concatenate([segment.slot_times_s(count) for segment, count in kept])
        flown = mission_rates_flown(mission, schedule, recorder.at(times)[:, 1:3])
        stated = (outcome.receding.mission_rates if outcome.receding is not None
                  else np.asarray(outcome.result.rates))
        print('flown / stated throughput:', flown / stated)
        assert np.all(flown / stated >= 0.99)


@pytest.fixture
def flight(ros_context, tmp_path):
    yield from flights(ros_context, tmp_path, Flight)


def cut_for_20_s(f: Flight, at_s: float = CUT_AT_S
                 ) -> tuple[dict[str, float], Callable[[float, Telemetry], None]]:
    """What ``f.fly`` calls to cut the node's link ``at_s`` into the mission for OUTAGE_S of
    autopilot time, and what it notes of the cut (autopilot and wall times)."""
    vehicle = f.node.vehicle
    cut: dict[str, float] = {}

    def during(mission_s: float, recorder: Telemetry) -> None:
        now = recorder.rows[-1][0]
        if 'at' not in cut and mission_s >= at_s:
            cut.update(at=now, errors=len(f.errors), requests=f.node.stats.requests_made)
            f.proxy.cut()
            while vehicle.link_up:
                assert time.monotonic() - f.proxy.cut_at < 3.0, 'the loss was not detected'
                time.sleep(0.01)
            cut['detected_wall_s'] = time.monotonic() - f.proxy.cut_at
        elif 'at' in cut and 'restored' not in cut and now - cut['at'] >= OUTAGE_S:
            cut['restored'] = now
            f.proxy.restore()
        elif 'restored' in cut and 'up_wall_s' not in cut and vehicle.link_up:
            cut['up_wall_s'] = time.monotonic() - f.proxy.restored_at
            cut['up_at'] = now
    return cut, during


def test_a_link_closed_for_20_s_mid_flight_is_said_once_and_the_flight_completes(flight):
    f = flight(proxy=True)
    vehicle = f.node.vehicle
    cut, during = cut_for_20_s(f)
    recorder = f.fly(during)
    print(f'link cut at {cut["at"]:.1f} s for {cut["restored"] - cut["at"]:.1f} s (autopilot '
          f'time); detected {cut["detected_wall_s"]:.3f} s after the cut, link up again '
          f'{cut["up_wall_s"]:.2f} s (wall) after it was restored; '
          f'{f.proxy.refused} reconnection attempts refused meanwhile')
    said = f.errors[cut['errors']:]
    print('said:', said)
    assert len(said) == 1 and 'vehicle link lost' in said[0]
    assert 'EOF' in said[0]
    # On planner_status, once; on /diagnostics, the link in ERROR while down, then OK again.
    assert [m for m in f.statuses if 'vehicle link' in m] == [f'refused: {said[0]}']
    errors = [k for k, (level, message) in enumerate(f.link_states)
              if level == DiagnosticStatus.ERROR and 'vehicle link lost' in message]
    assert errors and any(level == DiagnosticStatus.OK
                          for level, _ in f.link_states[errors[-1]:])
    assert f.proxy.connections >= 2 and vehicle.link_up
    assert vehicle.telemetry_gaps >= 1 and vehicle.last_gap_s >= OUTAGE_S - 1.0
    print(f'telemetry gap said: {vehicle.last_gap_s:.1f} s')
    # The clock ran on in autopilot time: the node's time is the vehicle's again.
    assert abs(f.node.clock_s() - recorder.rows[-1][0]) < 2.0
    assert f.node.stats.requests_made == cut['requests'], 'the outage made the node replan'
    f.check_flight(recorder)


#: A point counts as reached on time when the vehicle passes within this of it within one slot
#: of its time: the streamed vehicle tracks its targets within REACH_RADIUS_M at speed-up 5,
#: a little over it at 20 on a loaded machine.
ON_TIME_RADIUS_M = 2.0 * REACH_RADIUS_M


def closest_in_slot(progress, recorder: Telemetry,
                    slot_s: float) -> tuple[np.ndarray, np.ndarray]:
    """For every point in force (every plan's slot points kept, as the node states them:
    ``MissionProgress.points_in_force``), how close the vehicle came to it within one slot of
    its time (metres), and the points' times."""
    rows = np.array(recorder.rows)
    points, times = progress.points_in_force()
    closest = []
    for point, when in zip(points, times):
        near = np.abs(rows[:, 0] - when) <= slot_s
        closest.append(np.hypot(rows[near, 1] - point[0], rows[near, 2] - point[1]).min())
    return np.array(closest), times


def lateness_after(points: np.ndarray, times: np.ndarray, recorder: Telemetry,
                   radius_m: float) -> np.ndarray:
    """For each point (K, 2) planned at ``times`` (K,): how late (seconds) the vehicle first
    came within ``radius_m`` of it at or after a slot before its time (inf: never)."""
    rows = np.array(recorder.rows)
    late = []
    for point, when in zip(points, times):
        after = rows[:, 0] >= when - SLOT_S
        near = np.hypot(rows[after, 1] - point[0], rows[after, 2] - point[1]) <= radius_m
        late.append(rows[after, 0][near][0] - when if near.any() else np.inf)
    return np.array(late)


SLOT_S = 4.0
#: A 6 m/s wind from the east with 2 m/s turbulence that the planner is not told: the autopilot
#: estimates it with the simulated quad's drag model, and the node plans for its estimate.
UNTOLD_WIND = {'SIM_WIND_SPD': 6.0, 'SIM_WIND_DIR': 90.0, 'SIM_WIND_TURB': 2.0, **DRAG}
#: The streamed cut comes 64 s into the held-out mission (slot 16 of 54).
STREAM_CUT_AT_S = 64.0
#: Instances of the streamed cut's vehicle (MAVLink TCP 5760 + 10 I).
STREAM_INSTANCES = (30, 39)


def test_a_link_cut_for_20_s_in_stream_mode_is_caught_up_and_the_promise_restated_honestly(
        flight):
    f = flight(proxy=True, flight_mode='stream', mission=HELD_OUT, sitl_parameters=UNTOLD_WIND,
               instances=STREAM_INSTANCES, speedup=5)
    cut, during = cut_for_20_s(f, STREAM_CUT_AT_S)
    node = f.node

    def planned_for_the_wind() -> bool:
        estimate, plan = node.vehicle.wind.estimate, node.current_plan
        return (estimate.speed_mps > 5.5 and plan is not None and not node.vehicle.upload_pending
                and not estimate.differs_from(plan.request.scenario, PREFLIGHT_RESOLUTION_MPS))
    recorder = f.fly(during, ready=planned_for_the_wind)
    progress = f.node.progress
    planned_wind = progress.segments[0].result.scenario
    print(f'planned for a wind of {planned_wind.wind_speed_mps:.2f} m/s from '
          f'{planned_wind.wind_from_deg:.0f} deg (SIM_WIND 6 m/s from 90, turbulence 2)')
    print(f'link cut at {cut["at"]:.1f} s for {cut["restored"] - cut["at"]:.1f} s, up again '
          f'at {cut["up_at"]:.1f} s (autopilot time); {len(progress.segments)} plans flown')
    print('stream events:', f.node.vehicle.stream_events)
    mission = progress.mission          # as long as the mission flown (a replan may lengthen it)
    schedule, kept = progress.schedule()
    times = np.concatenate([segment.slot_times_s(count) for segment, count in kept])
    flown = mission_rates_flown(mission, schedule, recorder.at(times)[:, 1:3])
    first = float(np.min(progress.segments[0].result.rates))
    outcome = f.node.current_plan
    stated = (outcome.receding.mission_rates if outcome.receding is not None
              else np.asarray(outcome.result.rates))
    closest, when = closest_in_slot(progress, recorder, SLOT_S)
    print(f'flown min throughput {flown.min():.6g} bit/s: {100 * flown.min() / first:.2f} % '
          f'of the first promise {first:.6g}; the promise in force {stated.min():.6g} '
          f'({100 * flown.min() / stated.min():.2f} % of it delivered)')
    print(f'points in force: {np.sum(closest > ON_TIME_RADIUS_M)} of {len(closest)} not '
          f'passed within {ON_TIME_RADIUS_M:g} m within a slot of their time; the closest '
          f'{np.median(closest):.2f} m (median), {closest.max():.2f} m at most')
    missed = np.flatnonzero(closest > ON_TIME_RADIUS_M)
    print('missed points in force (mission slot, metres):',
          [(int(k) + 1, round(float(closest[k]), 2)) for k in missed])
    # The points of the plan in force at the cut, from the cut on: every one flown, late until
    # the time is made up.
    cut_plan = [segment for segment in progress.segments
                if segment.start_s is not None and segment.start_s <= cut['at']][-1]
    planned_times = cut_plan.start_s + SLOT_S * np.arange(
        1, cut_plan.result.scenario.num_slots + 1)
    after_cut = planned_times > cut['at']
    late = lateness_after(np.asarray(cut_plan.result.trajectory)[after_cut],
                          planned_times[after_cut], recorder, ON_TIME_RADIUS_M)
    behind = np.flatnonzero(late > SLOT_S)
    made_up = cut['at'] if len(behind) == 0 else (
        planned_times[after_cut][behind[-1] + 1] if behind[-1] + 1 < len(late) else np.inf)
    print(f'the plan at the cut: its {len(late)} points after the cut: every one passed within '
          f'{ON_TIME_RADIUS_M:g} m: {bool(np.all(np.isfinite(late)))}; at most '
          f'{late.max() / SLOT_S:.2f} slots late; each within a slot of its time from '
          f'{made_up - cut["at"]:.1f} s after the cut on; lateness (slots)',
          np.round(late / SLOT_S, 2))
    caught = [line for line in f.node.vehicle.stream_events if 'caught up' in line]
    assert len(caught) == 1, 'the stream did not catch the plan up'
    assert f.node.stats.requests_made == cut['requests'] + 1, 'the outage made the node replan'
    assert progress.segments[-1].start_s > cut['at'] and progress.segments[-2] is cut_plan
    assert np.all(np.isfinite(late)), 'a point of the plan in force was skipped'
    assert math.isfinite(made_up), 'the time lost was not made up'
    assert np.all(closest <= ON_TIME_RADIUS_M)
    assert flown.min() >= 0.99 * first
    # The promise in force is the flight's: the outage slots where the vehicle was.
    assert abs(flown.min() / stated.min() - 1.0) <= 1e-3


def set_glitch(link, north_m: float) -> None:
    """SIM_GPS1_GLTCH_X, without waiting for its echo (the recorder reads on)."""
    link.mav.param_set_send(link.target_system, link.target_component, b'SIM_GPS1_GLTCH_X',
                            north_m / METRES_PER_DEGREE, MAV.MAV_PARAM_TYPE_REAL32)


def test_a_33_m_gps_glitch_for_0_2_s_replans_nothing(flight):
    f = flight()
    glitch: dict[str, float] = {}

    def during(mission_s: float, recorder: Telemetry) -> None:
        now = recorder.rows[-1][0]
        link = f.link
        if 'at' not in glitch and mission_s >= GLITCH_AT_S:
            glitch.update(at=now, requests=f.node.stats.requests_made,
                          refused=f.node.flight.positions_refused)
            set_glitch(link, GLITCH_M)
        elif 'at' in glitch and 'off' not in glitch and recorder.raw \
                and recorder.raw[-1][1] - recorder.rows[-1][2] > GLITCH_M / 2:
            # Cleared at the first glitched fix seen: one fix of the 5 Hz GPS off (0.2 s), or
            # two when the test's telemetry lags the autopilot on a loaded machine.
            glitch['off'] = now
            set_glitch(link, 0.0)
    recorder = f.fly(during)
    # The glitch as the GPS reported it: its fixes north of the estimate by about 33 m.
    raw = np.array(recorder.raw)
    rows = np.array(recorder.rows)
    estimate = np.interp(raw[:, 0], rows[:, 0], rows[:, 2])
    offset = raw[:, 1] - estimate
    glitched = raw[np.abs(offset) > GLITCH_M / 2, 0]
    print(f'GPS fixes {GLITCH_M:g} m off: {len(glitched)}, from {glitched.min():.2f} to '
          f'{glitched.max():.2f} s (set at {glitch["at"]:.2f} s, cleared at '
          f'{glitch["off"]:.2f} s); largest offset {np.abs(offset).max():.1f} m')
    fixes = np.unique(glitched)
    print(f'distinct glitched fixes: {fixes}')
    assert 1 <= len(fixes) <= 2 and fixes.max() - fixes.min() <= GLITCH_S + 1e-6
    assert np.abs(offset).max() >= GLITCH_M - 3.0
    # The estimate the node reads, around the glitch: how far it moved.
    near = (rows[:, 0] > glitch['at'] - 1.0) & (rows[:, 0] < glitch['off'] + 2.0)
    steps = np.hypot(np.diff(rows[near, 1]), np.diff(rows[near, 2]))
    print(f'largest step of the estimate around the glitch: {steps.max():.2f} m per sample; '
          f'node refused {f.node.flight.positions_refused - glitch["refused"]} samples')
    assert f.node.stats.requests_made == glitch['requests'], 'the glitch made the node replan'
    assert len(f.node.progress.segments) == 1
    f.check_flight(recorder)


def test_a_mission_for_another_home_is_refused_before_upload(ros_context, tmp_path):
    sitl = start_sitl(tmp_path, HOME, instances=INSTANCES)
    node = executor = None
    try:
        link = open_link(sitl)
        url = f'tcp:127.0.0.1:{5762 + 10 * sitl.instance}'
        scenario = paper_scenario('I', max_speed_mps=SPEED_MPS, horizon_s=HORIZON_S,
                                  num_slots=SLOTS)
        zurich = default_home('px4')      # PX4 SITL's home, not ArduCopter SITL's
        mission = export_mission(plan(scenario, SolverSettings(compute_baselines=False)),
                                 tmp_path / 'zurich.waypoints', zurich)
        done = subprocess.run(CLI + ['upload', str(mission), '--connect', url],
                              capture_output=True, text=True, timeout=120)
        print(done.stderr)
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 2 and len(lines) == 1, done.stderr
        for place in (zurich, HOME):
            assert f'{place.latitude_deg:.7f}, {place.longitude_deg:.7f}' in lines[0]
        assert 'farther than 1000 m' in lines[0]
        assert len(download_mission(link)) <= 1, 'the CLI uploaded the mission'

        def run_node(*parameters: Parameter) -> PlannerNode:
            made = PlannerNode(context=ros_context, parameter_overrides=[
                Parameter('max_speed_mps', value=SPEED_MPS),
                Parameter('horizon_s', value=HORIZON_S), Parameter('num_slots', value=SLOTS),
                Parameter('compute_baselines', value=False),
                Parameter('mavlink_url', value=url), *parameters])
            executor.add_node(made)
            return made

        def spin_until(condition, what: str) -> None:
            deadline = time.monotonic() + 60.0
            while not condition():
                assert time.monotonic() < deadline, f'no {what}'
                executor.spin_once(timeout_sec=0.05)

        executor = SingleThreadedExecutor(context=ros_context)
        # Home parameters set to another place: the node refuses to upload, with both places.
        paris = Home(48.8566, 2.3522, 35.0)
        node = run_node(Parameter('home_latitude_deg', value=paris.latitude_deg),
                        Parameter('home_longitude_deg', value=paris.longitude_deg),
                        Parameter('home_altitude_m', value=paris.altitude_m))
        spin_until(lambda: 'refused' in node.vehicle.last_error, 'refusal of the upload')
        print(node.vehicle.last_error)
        assert 'mission upload refused' in node.vehicle.last_error
        for place in (paris, HOME):
            assert (f'{place.latitude_deg:.7f}, {place.longitude_deg:.7f}'
                    in node.vehicle.last_error)
        assert node.vehicle.uploads_verified == 0 and not node.vehicle.upload_pending
        assert node.diagnostics is not None and node.stats.error_count >= 1
        assert len(download_mission(link)) <= 1, 'the node uploaded the mission'
        executor.remove_node(node)
        node.destroy_node()
        # No home parameter: the vehicle's home is the frame's origin, the mission goes up.
        node = run_node()
        spin_until(lambda: node.vehicle.uploads_verified >= 1, 'upload at the vehicle home')
        assert node.vehicle.home is not None
        assert abs(node.vehicle.home.latitude_deg - HOME.latitude_deg) < 1e-6
        items = download_mission(link)
        q0 = items[2]
        print(f'uploaded at the vehicle home: q0 at ({q0.x:.7f}, {q0.y:.7f})')
        assert abs(q0.x - HOME.latitude_deg) < 1e-4 and abs(q0.y - HOME.longitude_deg) < 1e-4
    finally:
        if executor is not None:
            executor.shutdown()
        if node is not None:
            node.destroy_node()
        sitl.stop()
