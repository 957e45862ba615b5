"""The streamed mode on PX4 SITL (v1.16, its SIH quadrotor): the node, linked on PX4's onboard
port, flies its plan as OFFBOARD targets, and the same plan is then flown as a PX4 mission on
a fresh PX4, side by side in the figures.

The node uploads the plan, the test arms PX4 in AUTO.MISSION on its own ground-station link;
PX4 takes off and holds q0, where the mission clock starts: the node streams targets (q0
first), switches PX4 to OFFBOARD and, once the plan has reached qF, puts it back in
AUTO.MISSION at the qF item (its landing follows). Measured in autopilot time
(``time_boot_ms``) on the test's own link with the package's ``evaluate_flight``: when each
planned point was reached against its time, and what the plan's power schedule delivers at
the positions flown at the slot times against what the plan stated. The figures are printed
(``pytest -s``). A second flight stops the node in the middle of the stream with
``stream_fallback`` hold: PX4 is held in AUTO.LOITER where it was, and the node says so.
"""

from __future__ import annotations

from pathlib import Path

from helpers import LinkRecord, SpunNode
import numpy as np
import pytest

from devtools.px4_sitl import (FLIGHT_ATTEMPTS, fly_px4_mission, PX4_HOME, quiet_streams,
                               start_mission, start_px4, TAKEOFF_HEIGHT_M, TakeoffError,
                               why_px4_not_runnable)
from uav_comm_planner.vehicle.evaluation import evaluate_flight
from uav_comm_planner.vehicle.mavlink.guided import PX4_MODES
from uav_comm_planner.vehicle.mavlink.link import connect
from uav_comm_planner.vehicle.mavlink.telemetry import global_position_enu

RUN_PX4 = Path(__file__).resolve().parents[2] / 'shared' / 'sitl' / 'px4' / 'run_px4.sh'
#: This module's PX4 SITL instance (onboard port 14540 + 9, ground station 18570 + 9).
INSTANCE = 9
SPEEDUP = 5
#: Two nodes either side of a 400 m line: 30 slots of 4 s at PX4's 5 m/s cruise.
PLAN = {'ground_nodes': [-150.0, 150.0, 150.0, 350.0], 'start_m': [0.0, 10.0],
        'goal_m': [0.0, 400.0], 'max_speed_mps': 5.0, 'horizon_s': 120.0, 'num_slots': 30,
        'altitude_m': 30.0}
#: Wall-clock limit of the streamed flight, generous (about 40 s at the speed-up).
WALL_LIMIT_S = 300.0

pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(bool(why_px4_not_runnable(RUN_PX4)),
                                 reason=why_px4_not_runnable(RUN_PX4))]


class StreamedFlight(LinkRecord):
    """PX4 SITL, the node linked to its onboard port in stream mode on one executor thread,
    and the test's ground-station link recording GLOBAL_POSITION_INT and the flight mode."""

    def __init__(self, ros_context, folder: Path, **parameters) -> None:
        self.vehicle = start_px4(folder, INSTANCE, script=RUN_PX4, speedup=SPEEDUP)
        self.spun = self.link = None
        # The onboard port streams much at its rates in simulated time: only what the node
        # asks for is kept.
        onboard = connect(self.vehicle.onboard_url, timeout_s=60.0)
        quiet_streams(onboard)
        onboard.close()
        self.link = connect(self.vehicle.ground_station_url, timeout_s=60.0)
        quiet_streams(self.link)
        self.spun = SpunNode(ros_context, {
            **PLAN, 'compute_baselines': False, 'flight_mode': 'stream',
            'mission_firmware': 'px4', 'home_latitude_deg': PX4_HOME.latitude_deg,
            'home_longitude_deg': PX4_HOME.longitude_deg, 'home_altitude_m': PX4_HOME.altitude_m,
            'mavlink_url': self.vehicle.onboard_url, **parameters})
        self.node = self.spun.node
        super().__init__(self.link, WALL_LIMIT_S)

    def start(self) -> None:
        """Arm in AUTO.MISSION once the node's mission is on PX4; record from then on."""
        self.wait(lambda: self.node.vehicle.uploads_verified >= 1, 'mission on the vehicle')
        start_mission(self.link)
        # start_mission returns once PX4 has taken off, not on the arming's ack alone; it has
        # asked for GLOBAL_POSITION_INT at POSITION_RATE_HZ on this link, which records it.
        before = len(self.positions)
        self.wait(lambda: len(self.positions) > before, 'position after the takeoff')
        # start_mission measured the climb from the lowest altitude it saw; relative_alt is
        # above home, which PX4 sets within a decimetre or two of that ground (0.895 m seen).
        assert self.positions[before][2] >= 0.5 * TAKEOFF_HEIGHT_M * 1000.0, \
            self.positions[before]
        self.wait(lambda: self.node.progress.started, 'mission clock')

    def describe(self) -> str:
        vehicle = self.node.vehicle
        said = [line.strip() for line in (self.vehicle.folder / 'px4.log').read_text(
            errors='replace').splitlines() if line.startswith(('WARN', 'ERROR'))]
        return (f'{super().describe()}; the node: mode {vehicle.mode}, speed '
                f'{vehicle.speed_mps:.2f} m/s, last pose {self.node.flight.track.latest}; '
                f'PX4 warned: {said[-5:]}')

    def track(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        latitude, longitude, altitude = np.array(self.positions).T
        east, north, up = global_position_enu(latitude, longitude, altitude, PX4_HOME)
        return np.array(self.times), np.column_stack([east, north]), up

    def close(self) -> None:
        if self.spun is not None:
            self.spun.stop()
        if self.link is not None:
            self.link.close()
        self.vehicle.stop()


def started_flight(ros_context, folder: Path, **parameters) -> StreamedFlight:
    """A :class:`StreamedFlight` started, on a fresh PX4 again when PX4 does not take off (a
    :class:`TakeoffError`, at most FLIGHT_ATTEMPTS PX4s in all, each in a folder ``attemptK``),
    as :func:`fly_px4_mission` does."""
    attempt = 1
    while True:
        flight = StreamedFlight(ros_context, folder / f'attempt{attempt}', **parameters)
        try:
            flight.start()
            return flight
        except TakeoffError as exc:
            flight.close()
            if attempt == FLIGHT_ATTEMPTS:
                raise
            print(f'\n{exc}; flying again on a fresh PX4')
        except BaseException:
            flight.close()
            raise
        attempt += 1


def test_px4_flies_the_streamed_plan_in_offboard_on_time_and_its_mission_after(
        ros_context, tmp_path):
    flight = started_flight(ros_context, tmp_path / 'stream')
    try:
        node = flight.node
        segment = node.progress.segments[0]
        result = segment.result
        scenario = result.scenario
        end_s = segment.start_s + (scenario.num_slots + 1) * scenario.slot_s
        flight.wait(lambda: any('stopped' in line for line in node.vehicle.stream_events),
                    'end of the stream')
        flight.wait(lambda: flight.now_s > end_s + 5.0
                    and flight.mode == PX4_MODES['AUTO.MISSION'], 'AUTO.MISSION after it')
        events = list(node.vehicle.stream_events)
        outcome = node.current_plan
        reference = node.vehicle.stream_reference
        targets = node.vehicle.stream.targets_sent
    finally:
        flight.close()
    print('\nstream events:', events)
    started = [line for line in events if line.startswith('streaming')]
    stopped = [line for line in events if 'stopped' in line]
    assert len(started) == 1 and 'OFFBOARD' in started[0]
    assert len(stopped) == 1 and 'reached qF' in stopped[0]
    assert 'back in AUTO.MISSION from mission item' in stopped[0]
    assert len(node.progress.segments) == 1, 'the stream was replanned in flight'
    # OFFBOARD from the clock's start (after the first targets) to qF, then AUTO.MISSION.
    # After the plan's end a process starved of the CPU for over COM_OF_LOSS_T (a telemetry
    # gap of 2.6 s was seen on a loaded machine) lets PX4's offboard-loss failsafe flap the
    # mode (POSCTL, OFFBOARD again on the last targets) before the AUTO.MISSION asked for.
    timed = [(when, mode) for when, mode in flight.modes if when is not None]
    offboard = [when for when, mode in timed if mode == PX4_MODES['OFFBOARD'] and when <= end_s]
    assert len(offboard) == 1 and 0.0 <= offboard[0] - segment.start_s <= 2.5
    assert not [mode for when, mode in timed if offboard[0] < when <= end_s], flight.modes
    assert timed[-1][1] == PX4_MODES['AUTO.MISSION'], flight.modes

    times, positions, up = flight.track()
    report = evaluate_flight(result, reference.track(), times, positions, segment.start_s)
    flying = (times >= segment.start_s) & (times <= end_s)
    height_error = float(np.abs(up[flying] - scenario.altitude_m).max())
    print(f'stream on PX4: {report.summary()}; {targets} targets sent; height held within '
          f'{height_error:.2f} m of {scenario.altitude_m:g} m')
    print('reach errors (slots):', np.round(report.reach_errors_s / scenario.slot_s, 2))

    # The same plan as a PX4 mission, on a fresh PX4.
    mission = outcome.plan.write(tmp_path / 'mission.plan')
    flown = fly_px4_mission(outcome.vehicle_plan, mission, tmp_path / 'mission', instance=INSTANCE,
                            speedup=SPEEDUP, script=RUN_PX4)
    print(f'mission on PX4: {flown.report.summary()}')
    print('reach errors (slots):', np.round(flown.report.reach_errors_s / scenario.slot_s, 2))

    assert report.worst_reach_slots <= 0.5
    assert report.median_reach_slots <= 0.15
    assert report.flown_to_stated >= 0.99
    assert height_error <= 2.0
    # The stream keeps the plan's time at its worst point better than the mission does.
    assert report.worst_reach_slots < flown.report.worst_reach_slots


def test_a_node_stopped_mid_stream_leaves_px4_held_in_loiter_and_says_so(ros_context,
                                                                         tmp_path):
    flight = started_flight(ros_context, tmp_path, stream_fallback='hold')
    try:
        node = flight.node
        began = node.progress.segments[0].start_s
        flight.wait(lambda: flight.now_s > began + 20.0
                    and flight.mode == PX4_MODES['OFFBOARD'], 'stream in OFFBOARD')
        flight.spun.stop_spinning()
        events = node.vehicle.stream.events
        reference = node.vehicle.stream_reference
        flight.spun.stop()              # the link closes: the stream falls back
        stopped_s = flight.now_s
        flight.wait(lambda: flight.mode == PX4_MODES['AUTO.LOITER'], 'AUTO.LOITER after it')
        flight.wait(lambda: flight.now_s > stopped_s + 15.0, 'fifteen seconds held')
    finally:
        flight.close()
    print('\nstream events:', [event.message for event in events])
    stopped = [event.message for event in events if event.kind == 'stopped']
    assert len(stopped) == 1 and 'closing' in stopped[0] and 'AUTO.LOITER' in stopped[0]
    times, positions, _ = flight.track()
    # PX4 brakes from the stream's speed to its hold point, then holds it.
    at_stop = positions[np.searchsorted(times, stopped_s)]
    for since_s in (3, 6, 9, 12, 15):
        where = positions[np.searchsorted(times, stopped_s + since_s)]
        print(f'{since_s} s after: {np.linalg.norm(where - at_stop):.2f} m from the stop')
    after = positions[times >= stopped_s]
    farthest = float(np.linalg.norm(after - at_stop, axis=1).max())
    held = positions[times >= stopped_s + 10.0]
    spread = float(np.linalg.norm(held - held.mean(axis=0), axis=1).max())
    # Where the plan would have taken it meanwhile.
    elapsed = stopped_s - began
    ahead = reference.state(np.array([elapsed, elapsed + 15.0]))[0]
    planned = float(np.linalg.norm(ahead[1] - ahead[0]))
    print(f'at most {farthest:.2f} m from where it was when the node stopped (the plan: '
          f'{planned:.1f} m on in 15 s); held within {spread:.2f} m from 10 s to 15 s after')
    assert planned >= 20.0 and farthest <= 8.0 and spread <= 1.0


def test_a_px4_plan_at_10_mps_streams_with_the_acceleration_it_needs(ros_context, tmp_path):
    # At 10 m/s the plan's points need about 3.5 m/s/s, more than MPC_ACC_HOR's 3: streamed
    # with it (OFFBOARD follows it), not refused and flown as a mission.
    flight = started_flight(ros_context, tmp_path, max_speed_mps=10.0,
                            vehicle_max_speed_mps=10.0)
    try:
        node = flight.node
        segment = node.progress.segments[0]
        result = segment.result
        scenario = result.scenario
        end_s = segment.start_s + (scenario.num_slots + 1) * scenario.slot_s
        flight.wait(lambda: any('stopped' in line for line in node.vehicle.stream_events),
                    'end of the stream')
        flight.wait(lambda: flight.now_s > end_s + 2.0, 'the end of the plan')
        events = list(node.vehicle.stream_events)
        reference = node.vehicle.stream_reference
        errors = node.stats.last_error
    finally:
        flight.close()
    print('\nstream events:', events)
    assert reference is not None and reference.accel_raised, errors
    assert 3.0 < reference.bounds.accel_mpss <= 6.0
    started = [line for line in events if line.startswith('streaming')]
    stopped = [line for line in events if 'stopped' in line]
    assert len(started) == 1 and 'OFFBOARD' in started[0]
    assert len(stopped) == 1 and 'reached qF' in stopped[0]
    times, positions, _ = flight.track()
    report = evaluate_flight(result, reference.track(), times, positions, segment.start_s)
    print(f'stream on PX4 at 10 m/s, targets up to {reference.bounds.accel_mpss:.2f} m/s/s: '
          f'{report.summary()}')
    print('reach errors (slots):', np.round(report.reach_errors_s / scenario.slot_s, 2))
    assert report.flown_to_stated >= 0.99
    assert report.worst_reach_slots <= 1.0
