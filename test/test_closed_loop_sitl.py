"""The closed loop on ArduCopter SITL: the node plans, uploads, the vehicle flies, the node
replans in flight for a new ground-node set and the vehicle goes on with the new mission.

Measured in autopilot time on the test's own MAVLink link (independent of the node's): the
energy of the power the node scheduled over the whole flight, and each node's whole-mission
throughput with that power at the positions the vehicle occupied at the slot times.
"""

from __future__ import annotations

import threading
import time

from geometry_msgs.msg import PoseStamped
import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter

from devtools.sitl import (open_link, set_mode, set_parameter, start_sitl, take_off,
                           why_not_runnable)
from uav_comm_planner import paper_scenario
from uav_comm_planner.core.receding import mission_rates_flown
from uav_comm_planner.ros.messages import pose_array
from uav_comm_planner.ros.node import GROUND_NODES_QOS, PlannerNode, TOPIC_GROUND_NODES
from uav_comm_planner.ros.vehicle import TOPIC_VEHICLE_POSE
from uav_comm_planner.vehicle.geodesy import geodetic_to_enu, Home
from uav_comm_planner.vehicle.mavlink.items import Q0_SEQ
from uav_comm_planner.vehicle.mavlink.telemetry import request_telemetry

HOME = Home(-35.363262, 149.165237, 584.0)
SPEED_MPS = 10.0
HORIZON_S = 400.0
SLOTS = 100
#: Mission time (autopilot seconds after the clock starts) at which the new node set comes.
CHANGE_AT_S = 120.0
NEW_NODES = [(200.0, 400.0), (1000.0, -150.0), (1700.0, 300.0)]
#: Wall-clock limits, generous: the flight itself is about 25 s at the SITL's speedup.
WALL_LIMIT_S = 240.0

pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(bool(why_not_runnable()), reason=why_not_runnable())]


class Recorder:
    """GLOBAL_POSITION_INT on the test's link: times (autopilot s) and east, north metres."""

    def __init__(self, link) -> None:
        self.link = link
        self.times: list[float] = []
        self.lat: list[float] = []
        self.lon: list[float] = []

    def poll(self) -> float | None:
        message = self.link.recv_match(type='GLOBAL_POSITION_INT', blocking=True, timeout=1.0)
        if message is None:
            return None
        self.times.append(message.time_boot_ms / 1000.0)
        self.lat.append(message.lat / 1e7)
        self.lon.append(message.lon / 1e7)
        return self.times[-1]

    def positions_at(self, times_s: np.ndarray) -> np.ndarray:
        east, north, _ = geodetic_to_enu(np.array(self.lat), np.array(self.lon),
                                         np.full(len(self.lat), HOME.altitude_m), HOME)
        t = np.array(self.times)
        assert t[0] <= times_s.min() and times_s.max() <= t[-1] + 0.5
        return np.column_stack([np.interp(times_s, t, east), np.interp(times_s, t, north)])


def test_the_node_flies_a_changing_mission_within_budget(ros_context, tmp_path):
    sitl = start_sitl(tmp_path, HOME)
    node = probe = executor = spinner = None
    try:
        link = open_link(sitl)
        set_parameter(link, 'FENCE_ENABLE', 0)
        url = f'tcp:127.0.0.1:{5762 + 10 * sitl.instance}'
        node = PlannerNode(context=ros_context, parameter_overrides=[
            Parameter('max_speed_mps', value=SPEED_MPS),
            Parameter('horizon_s', value=HORIZON_S), Parameter('num_slots', value=SLOTS),
            Parameter('compute_baselines', value=False),
            Parameter('home_latitude_deg', value=HOME.latitude_deg),
            Parameter('home_longitude_deg', value=HOME.longitude_deg),
            Parameter('home_altitude_m', value=HOME.altitude_m),
            Parameter('mavlink_url', value=url)])
        probe = Node('closed_loop_probe', context=ros_context)
        nodes_pub = probe.create_publisher(type(pose_array([], 'map')), TOPIC_GROUND_NODES,
                                           GROUND_NODES_QOS)
        vehicle_poses: list[PoseStamped] = []
        probe.create_subscription(PoseStamped, TOPIC_VEHICLE_POSE, vehicle_poses.append, 10)
        executor = SingleThreadedExecutor(context=ros_context)
        executor.add_node(node)
        executor.add_node(probe)
        spinner = threading.Thread(target=executor.spin, daemon=True)
        spinner.start()

        deadline = time.monotonic() + WALL_LIMIT_S

        def wait(condition, what: str) -> None:
            while not condition():
                assert time.monotonic() < deadline, f'no {what} within {WALL_LIMIT_S} s'
                time.sleep(0.05)

        wait(lambda: node.vehicle.uploads_verified >= 1, 'first mission on the vehicle')
        take_off(link, 100.0)
        set_mode(link, 'AUTO')
        request_telemetry(link, 10.0)
        recorder = Recorder(link)
        changed = False
        while True:
            assert time.monotonic() < deadline, 'the mission did not end in time'
            now = recorder.poll()
            if now is None or not node.progress.started:
                continue
            first_start = node.progress.segments[0].start_s
            if not changed and now - first_start >= CHANGE_AT_S:
                nodes_pub.publish(pose_array(NEW_NODES, 'map'))
                changed = True
            segment = node.progress.current
            if (changed and len(node.progress.segments) >= 2 and segment.start_s is not None
                    and segment.first_slot + segment.num_slots == SLOTS
                    and now >= segment.slot_times_s(segment.num_slots)[-1] + 0.5):
                break
        assert node.vehicle.uploads_verified >= 2
        assert node.stats.error_count == 0, node.stats.last_error
        # The replan was flown from its q0 item on: the vehicle never went back to the takeoff.
        assert node.vehicle.mission_item is not None and node.vehicle.mission_item > Q0_SEQ
        assert vehicle_poses, 'no vehicle_pose published'
        last = vehicle_poses[-1].pose.position
        assert abs(last.z - 100.0) < 5.0

        outcome = node.current_plan
        assert outcome.receding is not None
        assert outcome.result.scenario.ground_nodes_m == tuple(NEW_NODES)
        mission = paper_scenario('I', ground_nodes_m=NEW_NODES, max_speed_mps=SPEED_MPS,
                                 horizon_s=HORIZON_S, num_slots=SLOTS)
        schedule, kept = node.progress.schedule()
        assert schedule.shape == (3, SLOTS)
        # The vehicle kept to its plans: the node set was the one reason to replan.
        assert len(kept) == 2
        energy = schedule.sum()
        print(f'energy scheduled over the flight: {energy:.12g} W (P_T {mission.power_budget_w} W)'
              f' in {len(kept)} plans of {[count for _, count in kept]} slots')
        assert energy <= mission.power_budget_w * (1 + 1e-9)

        for segment, count in kept:
            print(f'plan from slot {segment.first_slot + 1}: {count} slots from '
                  f'{segment.start_s:.1f} s, q0 {segment.result.scenario.start_m}')
        slot_times = np.concatenate([segment.slot_times_s(count) for segment, count in kept])
        flown = mission_rates_flown(mission, schedule, recorder.positions_at(slot_times))
        stated = outcome.receding.mission_rates
        ratio = flown / stated
        print('whole-mission throughput at the flown positions, bit/s:', flown)
        print('stated by the last plan, bit/s:                         ', stated)
        print('flown / stated:', ratio)
        assert np.all(ratio >= 0.99), ratio
    finally:
        if executor is not None:
            executor.shutdown()
        if spinner is not None:
            spinner.join(10)
        if node is not None:
            node.destroy_node()
        if probe is not None:
            probe.destroy_node()
        sitl.stop()
