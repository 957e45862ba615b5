"""The streamed mode on ArduCopter SITL: the node, linked, flies its plan as GUIDED targets in a
6 m/s wind from the east with 2 m/s turbulence that nobody tells the planner (the autopilot
estimates it; the node plans for its estimate), and keeps the plan's time.

Measured in autopilot time on the test's own MAVLink link: when each planned point was reached
against its time, and what the plan's power schedule delivers at the positions flown at the
slot times against what the plan in force at q0 stated. A second flight stops the node in the
middle of the stream: the vehicle is held (BRAKE) and the node says so.
"""

from __future__ import annotations

from geometry_msgs.msg import Vector3Stamped
from helpers import LinkRecord, SpunNode
import numpy as np
import pytest

from devtools.sitl import (open_link, set_mode, set_parameter, start_sitl, take_off,
                           why_not_runnable)
from uav_comm_planner.ros.wind import PREFLIGHT_RESOLUTION_MPS, TOPIC_WIND, WIND_QOS
from uav_comm_planner.vehicle.evaluation import evaluate_flight
from uav_comm_planner.vehicle.geodesy import geodetic_to_enu, Home
from uav_comm_planner.vehicle.mavlink.guided import COPTER_MODES
from uav_comm_planner.vehicle.mavlink.telemetry import request_telemetry

HOME = Home(-35.363262, 149.165237, 584.0)
#: Instances of this module's vehicles (MAVLink TCP 5760 + 10 I).
INSTANCES = (30, 39)
SPEEDUP = 5
#: West of the line, downwind: the plan has hovers to stop at.
NODES = [(-200.0, 100.0), (-150.0, 500.0)]
PLAN = {'ground_nodes': [x for node in NODES for x in node], 'start_m': [0.0, -100.0],
        'goal_m': [0.0, 700.0], 'max_speed_mps': 8.0, 'horizon_s': 240.0, 'num_slots': 60,
        'altitude_m': 100.0}
WIND = {'SIM_WIND_SPD': 6.0, 'SIM_WIND_DIR': 90.0, 'SIM_WIND_TURB': 2.0}
#: The autopilot estimates the wind only with its drag model on: the simulated quad's values.
DRAG = {'EK3_DRAG_BCOEF_X': 17.209, 'EK3_DRAG_BCOEF_Y': 17.209, 'EK3_DRAG_MCOEF': 0.209}
#: Wall-clock limit of one flight, generous (the flight is about a minute at the speed-up).
WALL_LIMIT_S = 400.0

pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(bool(why_not_runnable()), reason=why_not_runnable())]


class Flight(LinkRecord):
    """The SITL vehicle, the node linked to it on its second port, one executor thread, and
    the test's own link recording GLOBAL_POSITION_INT and the flight mode."""

    def __init__(self, ros_context, folder, **parameters) -> None:
        self.sitl = start_sitl(folder, HOME, speedup=SPEEDUP, instances=INSTANCES)
        self.spun = None
        self.link = open_link(self.sitl)
        for name, value in {'FENCE_ENABLE': 0, **WIND, **DRAG}.items():
            set_parameter(self.link, name, value)
        url = f'tcp:127.0.0.1:{5762 + 10 * self.sitl.instance}'
        self.spun = SpunNode(ros_context, {
            **PLAN, 'compute_baselines': False, 'flight_mode': 'stream',
            'home_latitude_deg': HOME.latitude_deg, 'home_longitude_deg': HOME.longitude_deg,
            'home_altitude_m': HOME.altitude_m, 'mavlink_url': url, **parameters})
        self.node = self.spun.node
        self.winds: list[Vector3Stamped] = []
        self.node.create_subscription(Vector3Stamped, TOPIC_WIND, self.winds.append, WIND_QOS)
        super().__init__(self.link, WALL_LIMIT_S)

    def start(self) -> None:
        """Take off, wait for the autopilot's wind estimate to settle (it rises over the first
        half minute of flight) and for a plan made for it, then fly it in AUTO to q0; the node
        streams it from there."""
        node = self.node
        self.wait(lambda: node.vehicle.uploads_verified >= 1, 'first mission on the vehicle')
        take_off(self.link, PLAN['altitude_m'])
        request_telemetry(self.link, 10.0)

        def planned_for_the_wind() -> bool:
            estimate = node.vehicle.wind.estimate
            plan = node.current_plan
            return (estimate.speed_mps > 5.5 and plan is not None
                    and not node.vehicle.upload_pending
                    and not estimate.differs_from(plan.request.scenario,
                                                  PREFLIGHT_RESOLUTION_MPS))
        self.wait(planned_for_the_wind, 'plan for the measured wind')
        set_mode(self.link, 'AUTO')
        self.wait(lambda: node.progress.started, 'mission clock')

    def track(self) -> tuple[np.ndarray, np.ndarray]:
        latitude, longitude, _ = np.array(self.positions).T
        east, north, _ = geodetic_to_enu(latitude / 1e7, longitude / 1e7,
                                         np.full(len(latitude), HOME.altitude_m), HOME)
        return np.array(self.times), np.column_stack([east, north])

    def close(self) -> None:
        if self.spun is not None:
            self.spun.stop()
        self.link.close()
        self.sitl.stop()


def test_the_streamed_plan_keeps_its_time_in_a_wind_the_planner_was_not_told(
        ros_context, tmp_path):
    flight = Flight(ros_context, tmp_path)
    try:
        node = flight.node
        flight.start()
        segment = node.progress.segments[0]
        end_s = segment.start_s + (segment.result.scenario.num_slots + 1) \
            * segment.result.scenario.slot_s
        flight.wait(lambda: flight.now_s is not None and flight.now_s > end_s + 5.0
                    and any('stopped' in line for line in node.vehicle.stream_events),
                    'end of the stream')
        flight.wait(lambda: flight.mode == COPTER_MODES['AUTO'], 'AUTO after the stream')
        started = [line for line in node.vehicle.stream_events if 'streaming' in line]
        stopped = [line for line in node.vehicle.stream_events if 'stopped' in line]
        print('stream events:', node.vehicle.stream_events)
        assert len(started) == 1 and len(stopped) == 1
        assert 'reached qF' in stopped[0] and 'back in AUTO' in stopped[0]
        assert len(node.progress.segments) == 1, 'the stream was replanned in flight'

        result = segment.result
        scenario = result.scenario
        estimate = node.vehicle.wind.estimate
        print(f'wind estimated {estimate.speed_mps:.2f} m/s from {estimate.from_deg:.0f} deg; '
              f'planned for {scenario.wind_speed_mps:g} m/s from {scenario.wind_from_deg:g} '
              f'(SIM_WIND 6 m/s from 90, turbulence 2)')
        assert scenario.wind_speed_mps > 4.0
        # Published as the air's velocity: a wind from the east moves the air west (x < 0).
        last = flight.winds[-1].vector
        print(f'wind_estimate: x {last.x:.2f}, y {last.y:.2f} m/s ({len(flight.winds)} messages)')
        assert last.x < -4.0 and abs(last.y) < 1.5 and last.z == 0.0
        reference = node.vehicle.stream_reference
        times, positions = flight.track()
        report = evaluate_flight(result, reference.track(), times, positions, segment.start_s)
        energy = float(np.asarray(result.power).sum())
        print(f'stream: {report.summary()}; energy {energy:.12g} W of P_T '
              f'{scenario.power_budget_w:g} W; {node.vehicle.stream.targets_sent} targets sent')
        print('reach errors (slots):', np.round(report.reach_errors_s / scenario.slot_s, 2))
        assert report.worst_reach_slots <= 1.0
        assert report.median_reach_slots <= 0.25
        assert report.flown_to_stated >= 0.99
        assert energy <= scenario.power_budget_w * (1 + 1e-9)
    finally:
        flight.close()


def test_a_node_stopped_mid_stream_leaves_the_vehicle_held_and_says_so(ros_context, tmp_path):
    flight = Flight(ros_context, tmp_path, stream_fallback='hold')
    try:
        node = flight.node
        flight.start()
        began = node.progress.segments[0].start_s
        flight.wait(lambda: flight.now_s is not None and flight.now_s > began + 30.0
                    and flight.mode == COPTER_MODES['GUIDED'], 'stream in GUIDED')
        flight.spun.stop_spinning()
        events = node.vehicle.stream.events
        flight.spun.stop()
        stopped = [event.message for event in events if event.kind == 'stopped']
        print('stream events:', [event.message for event in events])
        assert len(stopped) == 1 and 'closing' in stopped[0] and 'BRAKE' in stopped[0]
        flight.wait(lambda: flight.mode == COPTER_MODES['BRAKE'], 'BRAKE after the node stopped')
    finally:
        flight.close()
