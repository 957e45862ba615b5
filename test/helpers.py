"""What several test modules share: seeded random scenarios, the six-node field, the node
harness (the planner node, a probe node and one executor, on real rclpy), the record a
SITL test's own MAVLink link keeps of the vehicle, and the fuzz targets run in process."""

from __future__ import annotations

import threading
import time
from typing import Callable

from geometry_msgs.msg import PoseArray, PoseStamped
from nav_msgs.msg import Path
import numpy as np
import pytest
from rcl_interfaces.msg import Log
from rcl_interfaces.srv import SetParameters, SetParametersAtomically
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

#: Six nodes uniform in a 1500 m x 800 m field, flown from (0, 0) to (1500, 0) at 10 m/s: the
#: field the flights and the vehicle-aware tests use (the benchmark's own).
from devtools.flights import random_six_nodes  # noqa: F401
from uav_comm_planner import paper_scenario, plan, Scenario
from uav_comm_planner.core import drops
from uav_comm_planner.ros.messages import nanoseconds_of, pose_array
from uav_comm_planner.ros.node import (GROUND_NODES_QOS, NODE_NAME, PlannerNode,
                                       TOPIC_GROUND_NODES, TOPIC_UAV_POSE)
from uav_comm_planner.ros.publishing import (OUTPUT_QOS, TOPIC_MARKERS, TOPIC_MIN_THROUGHPUT,
                                             TOPIC_PATH, TOPIC_POWER)


def random_scenario(seed: int, nodes: int = 6, slots: int = 60, *, side_m: float = 2000.0,
                    **changes) -> Scenario:
    """``nodes`` nodes uniform in a side x side square, flown from (0, 0) to (side, side) in
    ``slots`` slots of 1 s at 100 m/s, the letter's radio; ``changes`` override any setting.
    ``seed`` is an integer or a generator to draw from.
    The core's generator (:func:`uav_comm_planner.core.drops.random_scenario`)."""
    return drops.random_scenario(nodes, slots, seed, side_m=side_m, **changes)


def two_node_stream_reference():
    """The stream reference of a short vehicle plan (two nodes, 700 m, 30 slots of 4 s at
    10 m/s, ArduCopter's limits): what the stream tests send targets from."""
    from uav_comm_planner.mission.policy import plan_for_vehicle
    from uav_comm_planner.vehicle.limits import VehicleLimits
    from uav_comm_planner.vehicle.stream import stream_reference

    scenario = paper_scenario('I', ground_nodes_m=((200.0, 150.0), (500.0, -100.0)),
                              goal_m=(700.0, 0.0), max_speed_mps=10.0, horizon_s=120.0,
                              num_slots=30)
    vehicle = plan_for_vehicle(scenario, VehicleLimits())
    return stream_reference(vehicle.flown, vehicle.limits)


def waterfilling_multipliers(allocation, a: np.ndarray) -> tuple[np.ndarray, float]:
    """The Lagrange multipliers of a water-filling answer for SNR per watt ``a`` (N, M):
    p = (mu_n - 1/a)^+ is the inner maximiser of the dual at lambda_n = M ln2 nu mu_n, so
    lambda is mu over the served nodes (read from their active slots), normalised, and
    nu = 1 / (M ln 2 sum mu)."""
    served = allocation.p.sum(axis=1) > 0
    mu = np.where(served, np.where(allocation.p > 0, allocation.p + 1.0 / a, 0.0).max(axis=1),
                  0.0)
    return mu / mu.sum(), 1.0 / (a.shape[1] * np.log(2.0) * mu.sum())


DEADLINE_S = 30.0
PROCESS_DEADLINE_S = 90.0
SLOTS = 20
HORIZON_S = 40.0
SLOT_S = HORIZON_S / SLOTS
MAX_STEP_M = 100.0 * SLOT_S
NODES_A = [(300.0, 200.0), (900.0, -150.0), (1500.0, 250.0)]
NODES_B = [(400.0, -200.0), (1100.0, 300.0)]
#: How close the flight must pass over each node (the optimum hovers within about 20 m).
NEAR_M = 50.0


def small_scenario(nodes=NODES_A, **changes):
    """The scenario the harness's node plans for ``nodes``, as the core sees it."""
    return paper_scenario('I', ground_nodes_m=nodes, num_slots=SLOTS, horizon_s=HORIZON_S,
                          **changes)


class SpunNode:
    """A :class:`PlannerNode` with the parameters ``values``, spun on one executor thread of
    its own (as a SITL test runs the node beside its vehicle); :meth:`stop` ends both."""

    def __init__(self, ros_context, values: dict) -> None:
        self.node: PlannerNode | None = PlannerNode(context=ros_context, parameter_overrides=[
            Parameter(name, value=value) for name, value in values.items()])
        self.executor: SingleThreadedExecutor | None = SingleThreadedExecutor(
            context=ros_context)
        self.executor.add_node(self.node)
        self.spinner: threading.Thread | None = threading.Thread(target=self.executor.spin,
                                                                 daemon=True)
        self.spinner.start()

    def stop_spinning(self) -> None:
        """The executor stopped (the node not yet destroyed)."""
        if self.executor is not None:
            self.executor.shutdown()
        if self.spinner is not None:
            self.spinner.join(10)
        self.executor = self.spinner = None

    def stop(self) -> None:
        self.stop_spinning()
        if self.node is not None:
            self.node.destroy_node()
        self.node = None


class LinkRecord:
    """What a test's own MAVLink link ``link`` hears of its vehicle: every GLOBAL_POSITION_INT
    (``times`` in autopilot seconds, ``positions`` as latitude and longitude x 1e7 and the
    height above home in mm) and every change of flight mode (``modes``: autopilot time of the
    latest position, custom_mode). :meth:`wait` reads it until a condition holds, at most
    ``limit_s`` of wall clock from now."""

    def __init__(self, link, limit_s: float) -> None:
        self.link = link
        self.limit_s = limit_s
        self.deadline = time.monotonic() + limit_s
        self.times: list[float] = []
        self.positions: list[tuple[int, int, int]] = []
        self.modes: list[tuple[float | None, int]] = []
        self.now_s: float | None = None

    @property
    def mode(self) -> int | None:
        """The vehicle's latest flight mode (None before its heartbeat)."""
        return self.modes[-1][1] if self.modes else None

    def wait(self, condition: Callable[[], bool], what: str) -> None:
        while not condition():
            assert time.monotonic() < self.deadline, \
                f'no {what} within {self.limit_s} s; {self.describe()}'
            self.poll()

    def describe(self) -> str:
        """What the link last heard, for a failure's message."""
        if not self.positions:
            return f'no position heard; modes {self.modes[-3:]}'
        return (f'last heard at {self.now_s:.1f} s (autopilot time), '
                f'{self.positions[-1][2] / 1000.0:.1f} m above home; modes {self.modes[-3:]}')

    def poll(self) -> None:
        message = self.link.recv_match(type=['GLOBAL_POSITION_INT', 'HEARTBEAT'],
                                       blocking=True, timeout=0.2)
        if message is None or message.get_srcSystem() != self.link.target_system:
            return
        if message.get_type() == 'HEARTBEAT':
            # Type 6 is a ground station's heartbeat relayed.
            if message.type != 6 and message.custom_mode != self.mode:
                self.modes.append((self.now_s, int(message.custom_mode)))
            return
        self.now_s = message.time_boot_ms / 1000.0
        self.times.append(self.now_s)
        self.positions.append((message.lat, message.lon, message.relative_alt))


class Harness:
    """The node under test, a probe node that talks to it, and one executor for both."""

    def __init__(self, context, *, planner=plan, **parameters) -> None:
        # The letter's own speed, planned as the optimiser plans it: these tests are about the
        # node's mechanics; the vehicle-aware plan has tests of its own below.
        values = {'num_slots': SLOTS, 'horizon_s': HORIZON_S, 'max_speed_mps': 100.0,
                  'vehicle_aware': False, **parameters}
        self.node = PlannerNode(context=context, planner=planner, parameter_overrides=[
            Parameter(name, value=value) for name, value in values.items()])
        self.probe = Node('planner_test_probe', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.probe)
        self.received: dict[str, list] = {topic: [] for topic in (
            TOPIC_PATH, TOPIC_POWER, TOPIC_MIN_THROUGHPUT, TOPIC_MARKERS)}
        for message_type, topic in ((Path, TOPIC_PATH), (Float64MultiArray, TOPIC_POWER),
                                    (Float64, TOPIC_MIN_THROUGHPUT),
                                    (MarkerArray, TOPIC_MARKERS)):
            self.probe.create_subscription(message_type, topic, self.received[topic].append,
                                           OUTPUT_QOS)
        self.error_logs: list[str] = []
        self.info_logs: list[str] = []
        self.probe.create_subscription(Log, '/rosout', self._on_log, QoSProfile(
            depth=100, reliability=ReliabilityPolicy.RELIABLE))
        self.nodes_pub = self.probe.create_publisher(PoseArray, TOPIC_GROUND_NODES,
                                                     GROUND_NODES_QOS)
        self.pose_pub = self.probe.create_publisher(PoseStamped, TOPIC_UAV_POSE, 10)

    def _on_log(self, message: Log) -> None:
        if message.name == NODE_NAME and message.level == Log.ERROR:
            self.error_logs.append(message.msg)
        elif message.name == NODE_NAME and message.level == Log.INFO:
            self.info_logs.append(message.msg)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.probe.destroy_node()

    def spin_until(self, condition: Callable[[], bool], what: str) -> None:
        deadline = time.monotonic() + DEADLINE_S
        while not condition():
            if time.monotonic() > deadline:
                pytest.fail(f'no {what} within {DEADLINE_S} s')
            self.executor.spin_once(timeout_sec=0.05)

    def latest(self, topic: str):
        messages = self.received[topic]
        return messages[-1] if messages else None

    def published(self, plans: int) -> None:
        """Spin until the node has published ``plans`` plans and the probe holds the last."""
        self.spin_until(lambda: self.node.stats.plans_published >= plans, f'plan number {plans}')
        outcome = self.node.current_plan
        expected_power = outcome.result.power.T.ravel().tolist()
        start_ns = outcome.request.start_ns

        def arrived() -> bool:
            path, power, rate, markers = (self.latest(t) for t in self.received)
            return (path is not None and nanoseconds_of(path.header.stamp) == start_ns
                    and markers is not None
                    and nanoseconds_of(markers.markers[0].header.stamp) == start_ns
                    and power is not None and list(power.data) == expected_power
                    and rate is not None and rate.data == outcome.min_throughput)
        self.spin_until(arrived, 'plan on every output topic')

    def send_nodes(self, points, frame_id: str = 'map') -> None:
        self.spin_until(lambda: self.nodes_pub.get_subscription_count() > 0,
                        'subscriber of ground_nodes')
        self.nodes_pub.publish(pose_array(points, frame_id))

    def send_pose(self, x: float, y: float) -> None:
        self.spin_until(lambda: self.pose_pub.get_subscription_count() > 0,
                        'subscriber of uav_pose')
        message = PoseStamped()
        message.header.frame_id = 'map'
        message.pose.position.x, message.pose.position.y = x, y
        self.pose_pub.publish(message)

    def call(self, service: str, request):
        kind = next(service for service in (Trigger, SetParameters, SetParametersAtomically)
                    if isinstance(request, service.Request))
        client = self.probe.create_client(kind, f'/{NODE_NAME}/{service}')
        self.spin_until(client.service_is_ready, f'service {service}')
        future = client.call_async(request)
        self.spin_until(future.done, f'answer of {service}')
        self.probe.destroy_client(client)
        return future.result()

    def errors_after(self, count: int) -> None:
        self.spin_until(lambda: self.node.stats.error_count > count, 'error')


#: A two-UAV fleet slow enough for ArduCopter's default waypoint limits (5 m/s, 5 s slots):
#: two nodes, the UAVs' ends 50 m apart, d_min 40 m; as the node's parameters and as the core's
#: fleet (:func:`slow_fleet`).
SLOW_FLEET_NODES = ((-150.0, 150.0), (150.0, 350.0))
SLOW_FLEET_STARTS = ((-25.0, 0.0), (25.0, 0.0))
SLOW_FLEET_GOALS = ((-25.0, 500.0), (25.0, 500.0))
SLOW_FLEET = {'ground_nodes': [v for p in SLOW_FLEET_NODES for v in p], 'max_speed_mps': 5.0,
              'horizon_s': 200.0, 'num_slots': 40, 'altitude_m': 30.0, 'uavs': 2,
              'uav_starts_m': [v for p in SLOW_FLEET_STARTS for v in p],
              'uav_goals_m': [v for p in SLOW_FLEET_GOALS for v in p], 'min_separation_m': 40.0}


def slow_fleet():
    """:data:`SLOW_FLEET` as the core's :class:`~uav_comm_planner.core.fleet.FleetScenario`."""
    from uav_comm_planner.core.fleet import FleetScenario

    base = paper_scenario('I', ground_nodes_m=SLOW_FLEET_NODES, start_m=SLOW_FLEET_STARTS[0],
                          goal_m=SLOW_FLEET_GOALS[0], max_speed_mps=5.0, horizon_s=200.0,
                          num_slots=40, altitude_m=30.0)
    return FleetScenario(base, SLOW_FLEET_STARTS, SLOW_FLEET_GOALS, 40.0)


def run_fuzz_target(module: str, argv: list[str]) -> int:
    """Run the fuzz target ``module`` of test/fuzz (``make fuzz``'s) in process with ``argv``:
    its exit status, its report printed."""
    import importlib.util
    import pathlib
    import sys

    folder = pathlib.Path(__file__).resolve().parent / 'fuzz'
    sys.path.insert(0, str(folder))
    try:
        spec = importlib.util.spec_from_file_location(module, folder / f'{module}.py')
        target = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(target)
        return target.main(argv)
    finally:
        sys.path.remove(str(folder))


def ros_arguments(given: dict[str, str], source: str, folder) -> list[str]:
    """The node's ROS arguments for parameter texts ``given`` by name: ``-p name:=text`` when
    ``source`` is 'command line', else a parameters file written in ``folder``."""
    if source == 'command line':
        return [part for name, text in given.items() for part in ('-p', f'{name}:={text}')]
    params = folder / 'parameters.yaml'
    params.write_text('uav_comm_planner:\n  ros__parameters:\n' + ''.join(
        f'    {name}: {text}\n' for name, text in given.items()))
    return ['--params-file', str(params)]


def node_from_arguments(arguments: list[str]):
    """A planner node made with ``arguments`` as its command line's ROS arguments (how the
    executable gets -p and --params-file), in a context of its own: (context, node)."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from uav_comm_planner.ros.node import PlannerNode

    context = rclpy.Context()
    rclpy.init(args=['planner', '--ros-args', *arguments], context=context,
               signal_handler_options=SignalHandlerOptions.NO)
    try:
        return context, PlannerNode(context=context)
    except BaseException:
        context.try_shutdown()
        raise


def keep_out_plan_file(path, polygons: list[list[list[float]]]):
    """A QGroundControl ``.plan`` at ``path`` whose geofence keeps out of each polygon
    ([[lat, lon], ...]); ``path``."""
    import json

    path.write_text(json.dumps({'fileType': 'Plan', 'version': 1, 'geoFence': {
        'version': 2, 'circles': [], 'polygons': [
            {'inclusion': False, 'version': 1, 'polygon': polygon} for polygon in polygons]}}))
    return path


def build_no_polygon(monkeypatch) -> None:
    """Make building a keep-out polygon fail the test: a bound must refuse the file first."""
    from uav_comm_planner.core.zones import KeepOutPolygon

    def never(*args, **kwargs):
        raise AssertionError('a polygon was built before the vertices were counted')
    monkeypatch.setattr(KeepOutPolygon, '__post_init__', never)
