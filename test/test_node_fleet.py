"""The planner node planning a fleet (``uavs`` >= 2) on real rclpy, in this process: each
vehicle's plan on its own namespaced topics equal to the core's fleet plan for the same input,
the parameters that disagree refused with their reason while the last good plan stays, and one
mission file per vehicle."""

from __future__ import annotations

import math
from pathlib import Path as FilePath
import re
import socket

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from fake_vehicle import FakeVehicle
from helpers import (node_from_arguments, NODES_A, NODES_B, ros_arguments, SLOW_FLEET,
                     slow_fleet, SLOW_FLEET_STARTS, small_scenario)
from nav_msgs.msg import Path
import numpy as np
import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import Trigger

from uav_comm_planner import PlannerError, SolverSettings
from uav_comm_planner.core.fleet import FleetScenario, FleetSettings, plan_fleet
from uav_comm_planner.core.model import average_rates
from uav_comm_planner.mission.fleet import plan_for_missions, uav_result
from uav_comm_planner.ros.diagnostics import DIAGNOSTICS_QOS, TOPIC_DIAGNOSTICS
from uav_comm_planner.ros.messages import nanoseconds_of
from uav_comm_planner.ros.node import PlannerNode
from uav_comm_planner.ros.params import flat_pairs
from uav_comm_planner.ros.publishing import (OUTPUT_QOS, STATUS_QOS, TOPIC_MIN_THROUGHPUT,
                                             TOPIC_PATH, TOPIC_POWER, TOPIC_STATUS)
from uav_comm_planner.vehicle.geodesy import default_home, geodetic_to_enu
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink.files import read_waypoints, write_mission_file
from uav_comm_planner.vehicle.mavlink.items import (build_mission_items, from_message,
                                                    mismatches, Q0_SEQ)

STARTS = ((0.0, 0.0), (0.0, 250.0))
GOALS = ((1500.0, 0.0), (1500.0, 250.0))
SEPARATION_M = 120.0
FLEET = {'ground_nodes': flat_pairs(NODES_A), 'uavs': 2, 'uav_starts_m': flat_pairs(STARTS),
         'uav_goals_m': flat_pairs(GOALS), 'min_separation_m': SEPARATION_M}


def core_fleet(nodes=NODES_A, separation_m: float = SEPARATION_M) -> FleetScenario:
    """The fleet the node's parameters describe, as the core sees it."""
    return FleetScenario(small_scenario(nodes), STARTS, GOALS, separation_m)


class FleetProbe:
    """Subscribes the probe of ``harness`` to each vehicle's path, power schedule and min
    throughput (``uav1/...``, ``uav2/...``) and to the node's own min throughput and status."""

    def __init__(self, h, count: int = 2) -> None:
        self.h = h
        self.received: dict[str, list] = {}
        topics = [(Float64, TOPIC_MIN_THROUGHPUT, OUTPUT_QOS),
                  (DiagnosticArray, TOPIC_STATUS, STATUS_QOS),
                  (DiagnosticArray, TOPIC_DIAGNOSTICS, DIAGNOSTICS_QOS)]
        for k in range(1, count + 1):
            topics += [(Path, f'uav{k}/{TOPIC_PATH}', OUTPUT_QOS),
                       (Float64MultiArray, f'uav{k}/{TOPIC_POWER}', OUTPUT_QOS),
                       (Float64, f'uav{k}/{TOPIC_MIN_THROUGHPUT}', OUTPUT_QOS)]
        for kind, topic, qos in topics:
            self.received[topic] = []
            h.probe.create_subscription(kind, topic, self.received[topic].append, qos)

    def latest(self, topic: str):
        return self.received[topic][-1] if self.received[topic] else None

    def planner_diagnostics(self, level: int, message: str):
        """Spin until ``/diagnostics`` says the planner is at ``level`` with a message starting
        with ``message``; that status."""
        def found():
            return next((s for m in reversed(self.received[TOPIC_DIAGNOSTICS]) for s in m.status
                         if s.name.endswith(': planner') and s.level == level
                         and s.message.startswith(message)), None)
        self.h.spin_until(lambda: found() is not None, f'planner diagnostics {message!r}')
        return found()

    def plan(self, plans: int):
        """Spin until the node has published ``plans`` fleet plans and every topic has had
        one message per plan (the paths with the stamp of the last); the fleet outcome."""
        node = self.h.node
        self.h.spin_until(lambda: node.stats.plans_published >= plans, f'fleet plan {plans}')
        stamp = node.fleet.current.request.start_ns

        def arrived() -> bool:
            paths = [self.latest(f'uav{k}/{TOPIC_PATH}') for k in (1, 2)]
            return (all(len(messages) >= plans for topic, messages in self.received.items()
                        if topic not in (TOPIC_STATUS, TOPIC_DIAGNOSTICS))
                    and all(nanoseconds_of(p.header.stamp) == stamp for p in paths))
        self.h.spin_until(arrived, 'every vehicle\'s plan')
        return node.fleet.current


def points_of(path: Path) -> np.ndarray:
    return np.array([[p.pose.position.x, p.pose.position.y] for p in path.poses])


def check_published(probe: FleetProbe, core) -> None:
    """Every vehicle's topics hold its part of the core's fleet plan ``core``."""
    fleet = core.fleet
    for k in range(2):
        name = f'uav{k + 1}'
        path = points_of(probe.latest(f'{name}/{TOPIC_PATH}'))
        # q0, the M slot points, qF.
        np.testing.assert_allclose(
            path, np.vstack([fleet.starts_m[k], core.trajectories[k], fleet.goals_m[k]]),
            atol=1e-9)
        power = probe.latest(f'{name}/{TOPIC_POWER}')
        schedule = np.array(power.data).reshape(fleet.scenario.num_slots, -1).T
        np.testing.assert_allclose(schedule, core.power[k], rtol=1e-9, atol=1e-12)
        # UAV k's own throughput, recomputed from the letter's rate formula here.
        alone = average_rates(core.trajectories[k], core.power[k], core.fleet.vehicle(k))
        assert probe.latest(f'{name}/{TOPIC_MIN_THROUGHPUT}').data == pytest.approx(
            alone.min(), rel=1e-9)
    assert probe.latest(TOPIC_MIN_THROUGHPUT).data == pytest.approx(core.min_throughput,
                                                                    rel=1e-9)


def test_two_uavs_publish_their_own_plans_equal_to_the_core_fleet_plan(harness):
    h = harness(**FLEET)
    probe = FleetProbe(h)
    outcome = probe.plan(1)
    core = plan_fleet(core_fleet(), FleetSettings(single=SolverSettings()))
    check_published(probe, core)
    # The two vehicles' plans differ (each flies its own ends) and keep d_min at every slot.
    paths = [points_of(probe.latest(f'uav{k}/{TOPIC_PATH}')) for k in (1, 2)]
    assert np.linalg.norm(paths[0] - paths[1], axis=1).min() >= SEPARATION_M * (1 - 1e-6)
    assert outcome.plan.min_throughput > max(core.single_throughputs.values()) * (1 - 1e-9)
    h.spin_until(lambda: probe.received[TOPIC_STATUS], 'the fleet plan\'s status')
    status = probe.latest(TOPIC_STATUS).status[0]
    assert status.message.startswith('planned: fleet plan: min throughput'), status.message
    values = {v.key: v.value for v in status.values}
    assert float(values['min_throughput_bps']) == pytest.approx(core.min_throughput, rel=1e-9)
    assert values['uavs'] == '2'
    planner = probe.planner_diagnostics(DiagnosticStatus.OK, 'fleet plan: min throughput')
    assert {v.key: v.value for v in planner.values}['uavs'] == '2'

    # A new node set replans the fleet jointly, on the same topics.
    h.send_nodes(NODES_B)
    probe.plan(2)
    check_published(probe, plan_fleet(core_fleet(NODES_B), FleetSettings(single=SolverSettings())))
    # One UAV's topics are not the node's: its own planned_path carries no fleet plan.
    assert h.latest(TOPIC_PATH) is None


def set_parameter(h, name: str, value):
    request = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
    return h.call('set_parameters', request).results[0]


@pytest.mark.parametrize('name, value, reason', [
    ('uav_starts_m', [0.0, 0.0, 0.0, 250.0, 0.0, 500.0], 'uav_starts_m must hold one point per '
                                                         'UAV, x1, y1, x2, y2, ...: uavs is 2, '
                                                         'got 3 points'),
    ('uav_goals_m', [1500.0, 0.0, 1500.0], 'uav_goals_m must be a flat list x1, y1, x2, y2, '
                                           '... with an even number of values, got 3'),
    ('mavlink_urls', ['tcp:127.0.0.1:5762'], 'mavlink_urls must hold one link per UAV (or '
                                             'none): uavs is 2, got 1'),
    ('min_separation_m', 300.0, 'starts of UAV 1 and UAV 2 are 250.0 m apart, less than the '
                                'separation 300 m'),
    ('mavlink_url', 'tcp:127.0.0.1:5762', 'mavlink_url is for one UAV'),
    ('uavs', 3, 'read-only'),
])
def test_parameters_that_disagree_are_refused_and_the_last_good_plan_stays(harness, name,
                                                                           value, reason):
    h = harness(**FLEET)
    probe = FleetProbe(h)
    before = probe.plan(1)
    config, requests, errors = h.node.config, h.node.stats.requests_made, h.node.stats.error_count
    answer = set_parameter(h, name, value)
    assert not answer.successful
    assert reason in answer.reason
    if name != 'uavs':      # read-only: refused by rclpy before the node's check
        assert reason in h.node.stats.last_error
        assert h.node.stats.error_count == errors + 1
    for _ in range(20):
        h.executor.spin_once(timeout_sec=0.01)
    assert h.node.stats.requests_made == requests
    assert h.node.fleet.current is before and h.node.config is config


@pytest.mark.parametrize('values, reason', [
    ({'uavs': 0}, 'uavs must be a whole number of UAVs from 1 to 8, got 0'),
    ({'uavs': 2, 'uav_starts_m': flat_pairs(STARTS)},
     'uav_goals_m must hold one point per UAV, x1, y1, x2, y2, ...: uavs is 2, got 0 points'),
    ({'uav_starts_m': flat_pairs(STARTS[:1])},
     'uav_starts_m set but uavs is 1: one UAV flies from start_m to goal_m'),
    ({**FLEET, 'flight_mode': 'stream'}, "flight_mode 'stream' is for one UAV"),
    ({**FLEET, 'num_slots': 20, 'horizon_s': 40.0, 'max_speed_mps': 100.0,
      'vehicle_aware': False, 'max_node_slots': 100},
     'problem too large: K x N x M = 2 UAVs x 3 nodes x 20 slots = 120 exceeds the compute '
     'budget max_node_slots = 100'),
])
def test_a_node_started_with_parameters_that_disagree_says_why(ros_context, values, reason):
    with pytest.raises(PlannerError, match=re.escape(reason)):
        PlannerNode(context=ros_context, parameter_overrides=[
            Parameter(name, value=value) for name, value in values.items()])


def test_one_uav_keeps_the_single_vehicle_topics_only(harness):
    h = harness()
    h.published(1)
    assert h.node.fleet.active is False and h.node.fleet.current is None
    topics = {name for name, _ in h.node.get_topic_names_and_types()}
    assert not [t for t in topics if re.match(r'/uav\d+/', t)], topics


def test_each_vehicle_gets_its_own_mission_file(harness, tmp_path: FilePath):
    h = harness(**SLOW_FLEET, mission_dir=str(tmp_path), mission_file='fleet.waypoints')
    probe = FleetProbe(h)
    outcome = probe.plan(1)
    # Planned as the command line plans missions: they keep d_min as ArduCopter times them.
    (tmp_path / 'expected').mkdir()
    core, _ = plan_for_missions(slow_fleet(), FleetSettings(single=SolverSettings()),
                                VehicleLimits(), 'ardupilot')
    check_published(probe, core)
    home = default_home('ardupilot')
    for k in range(2):
        path = tmp_path / f'fleet_uav{k + 1}.waypoints'
        assert outcome.vehicles[k].mission_path == path
        expected = build_mission_items(uav_result(core, k), home, end='land',
                                       firmware='ardupilot', limits=VehicleLimits())
        assert mismatches(expected, outcome.vehicles[k].plan.items) == []
        # The file as the mission export writes these items (.waypoints keeps 6 decimals).
        written = write_mission_file(expected, tmp_path / 'expected' / path.name, home)
        assert path.read_text() == written.read_text()
        # Each vehicle's mission starts at its own q0 (to the file's 1e-6 degree).
        q0 = read_waypoints(path)[Q0_SEQ]
        east, north, _ = geodetic_to_enu(np.array([q0.x]), np.array([q0.y]), home.altitude_m,
                                         home)
        assert math.dist((east[0], north[0]), SLOW_FLEET_STARTS[k]) < 0.2
    assert not (tmp_path / 'fleet.waypoints').exists()


def held(vehicle: FakeVehicle) -> list:
    """The mission ``vehicle`` stores, as mission items."""
    return [from_message(message) for message in vehicle.stored]


def test_each_link_gets_its_own_vehicle_s_mission_and_the_links_follow_mavlink_urls(harness):
    cmac = default_home('ardupilot')
    home = (cmac.latitude_deg, cmac.longitude_deg, cmac.altitude_m)
    with FakeVehicle('good', home=home) as first, FakeVehicle('good', home=home) as second:
        h = harness(**SLOW_FLEET, mavlink_urls=[first.url, second.url])
        probe = FleetProbe(h)
        links = h.node.fleet.links

        def uploaded(outcome) -> bool:
            return links.verified_tag == [outcome.request.start_ns] * 2
        outcome = probe.plan(1)
        h.spin_until(lambda: uploaded(outcome), 'both missions uploaded')
        assert mismatches(outcome.vehicles[0].plan.items, held(first)) == []
        assert mismatches(outcome.vehicles[1].plan.items, held(second)) == []
        assert mismatches(held(first), held(second)) != []       # each its own

        # The links given in the other order: the links are made again and the fleet planned
        # again; each vehicle is given the mission of the UAV its link now stands for.
        assert set_parameter(h, 'mavlink_urls', [second.url, first.url]).successful
        again = probe.plan(2)
        h.spin_until(lambda: uploaded(again), 'both missions uploaded again')
        assert mismatches(again.vehicles[0].plan.items, held(second)) == []
        assert mismatches(again.vehicles[1].plan.items, held(first)) == []
        assert h.node.stats.error_count == 0, h.node.stats.last_error


@pytest.mark.parametrize('source', ['command line', 'parameters file'])
def test_a_fleet_from_ros_arguments_takes_whole_numbers_and_empty_lists(tmp_path, source):
    """``uav_starts_m:=[0, 0, 0, 250]`` (integers) and ``mavlink_urls:=[]`` (no value to rcl)
    are taken as the declared double and string arrays, on the command line and in a
    parameters file."""
    given = {'uavs': '2', 'uav_starts_m': '[0, 0, 0, 250]', 'uav_goals_m': '[1500, 0, 1500, 250]',
             'min_separation_m': '120', 'mavlink_urls': '[]',
             'ground_nodes': '[300, 200, 900, -150, 1500, 250]'}
    context, node = node_from_arguments(ros_arguments(given, source, tmp_path))
    try:
        fleet = node.config.fleet
        assert fleet.starts_m == STARTS and fleet.goals_m == GOALS
        assert fleet.min_separation_m == SEPARATION_M and node.config.fleet_urls == ()
        assert node.get_parameter('mavlink_urls').type_ == Parameter.Type.STRING_ARRAY
        assert node.get_parameter('uav_starts_m').type_ == Parameter.Type.DOUBLE_ARRAY
    finally:
        node.destroy_node()
        context.try_shutdown()


def test_a_fleet_plan_that_fails_is_refused_and_the_last_good_plan_stays(harness, tmp_path):
    """Goals swapped, the two paths cross: the missions, as ArduCopter times them, bring the
    vehicles closer than d_min however the plan's slots are kept apart, so the plan is refused
    on planner_status, with the reason, and the plan in force and its mission files stay."""
    h = harness(**SLOW_FLEET, mission_dir=str(tmp_path), mission_file='fleet.waypoints')
    probe = FleetProbe(h)
    before = probe.plan(1)
    files = {path.name: path.read_text() for path in tmp_path.iterdir()}
    assert set(files) == {'fleet_uav1.waypoints', 'fleet_uav2.waypoints'}
    errors = h.node.stats.error_count
    assert set_parameter(h, 'uav_goals_m', [25.0, 500.0, -25.0, 500.0]).successful
    h.errors_after(errors)
    assert h.node.stats.last_error.startswith(
        'fleet planning failed (parameters uav_goals_m); the last good plan stays '
        'published: the missions, flown as ardupilot times them'), h.node.stats.last_error
    h.spin_until(lambda: any(s.message.startswith('refused: fleet planning failed')
                             for m in probe.received[TOPIC_STATUS] for s in m.status),
                 'the refusal on planner_status')
    assert h.node.fleet.current is before and h.node.stats.plans_published == 1
    # A plan stays in force: the planner's diagnostics warn, they do not say there is none.
    probe.planner_diagnostics(DiagnosticStatus.WARN, 'fleet planning failed')
    assert {path.name: path.read_text() for path in tmp_path.iterdir()} == files


def test_start_and_export_mission_say_what_a_fleet_does_instead(harness, tmp_path):
    h = harness(**SLOW_FLEET, mission_dir=str(tmp_path), mission_file='fleet.waypoints')
    FleetProbe(h).plan(1)
    for service in ('start', 'export_mission'):
        answer = h.call(service, Trigger.Request())
        assert not answer.success
        assert answer.message.startswith('a fleet (uavs >= 2) has no mission clock yet'), \
            answer.message


def test_a_vehicle_whose_link_is_down_does_not_keep_the_other_from_its_mission(harness):
    cmac = default_home('ardupilot')
    with socket.socket() as probe_socket:       # a port nothing listens on
        probe_socket.bind(('127.0.0.1', 0))
        dead = f'tcp:127.0.0.1:{probe_socket.getsockname()[1]}'
    with FakeVehicle('good', home=(cmac.latitude_deg, cmac.longitude_deg,
                                   cmac.altitude_m)) as vehicle:
        h = harness(**SLOW_FLEET, mavlink_urls=[dead, vehicle.url])
        probe = FleetProbe(h)
        statuses: list = []
        h.probe.create_subscription(DiagnosticArray, f'uav1/{TOPIC_STATUS}', statuses.append,
                                    STATUS_QOS)
        links = h.node.fleet.links
        outcome = probe.plan(1)
        h.spin_until(lambda: links.verified_tag[1] == outcome.request.start_ns,
                     'UAV 2\'s mission uploaded')
        assert mismatches(outcome.vehicles[1].plan.items, held(vehicle)) == []
        h.spin_until(lambda: links.last_error[0] != '', 'UAV 1\'s link error')
        assert links.verified_tag[0] is None and not links.link_up[0] and links.link_up[1]
        assert links.last_error[1] == ''
        h.spin_until(lambda: any(s.message.startswith('refused: ') and dead in s.message
                                 for m in statuses for s in m.status),
                     'UAV 1\'s link error on uav1/planner_status')
        assert h.node.stats.last_error.startswith('uav1: '), h.node.stats.last_error
