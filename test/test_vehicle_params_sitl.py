"""The vehicle's own limits read from a real ArduCopter SITL over the node's link.

WPNAV_SPEED is set on the SITL to 750 cm/s (ArduCopter's default is 1000) with PARAM_SET
before the node connects: the node reads it (PARAM_REQUEST_READ), says so once, shows it on
``/diagnostics`` and plans for 7.5 m/s; WPNAV_SPEED set again while the node is linked
(ArduCopter tells every link with PARAM_VALUE) replans for the new speed; and a node started
with ``vehicle_max_speed_mps`` set explicitly plans for that speed whatever the vehicle says.

A last test flies what it is for: on a vehicle slower to start and stop than ArduCopter's
defaults (WPNAV_ACCEL 100 cm/s/s, WPNAV_SPEED 750 cm/s), the plan the node made with the
values it read is flown with every planned point within a slot of its time (autopilot time);
the same mission planned with the defaults, flown on the same vehicle, is printed beside it.
SITL instances 100-104 (MAVLink TCP 5760 + 10 I).
"""

from __future__ import annotations

import time

from helpers import SpunNode
import pytest

from devtools.sitl import fly_plan, open_link, set_parameter, start_sitl, why_not_runnable
from uav_comm_planner.mission.policy import plan_for_vehicle
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.mavlink.items import DO_CHANGE_SPEED

HOME = Home(-35.363262, 149.165237, 584.0)
#: This module's SITL instances (MAVLink TCP 5760 + 10 I).
INSTANCES = (100, 104)
#: A mission slower than every speed the vehicle is given here.
PLAN = {'ground_nodes': [0.0, 400.0, 500.0, 400.0], 'start_m': [0.0, 0.0],
        'goal_m': [600.0, 0.0], 'max_speed_mps': 7.0, 'horizon_s': 200.0, 'num_slots': 50,
        'altitude_m': 50.0, 'vehicle_aware': True, 'compute_baselines': False,
        'home_latitude_deg': HOME.latitude_deg, 'home_longitude_deg': HOME.longitude_deg,
        'home_altitude_m': HOME.altitude_m}
#: Wall-clock limit of each wait.
WAIT_S = 120.0

pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(bool(why_not_runnable()), reason=why_not_runnable())]


@pytest.fixture
def sitl(tmp_path):
    vehicle = start_sitl(tmp_path, HOME, instances=INSTANCES)
    link = open_link(vehicle)
    try:
        yield vehicle, link
    finally:
        link.close()
        vehicle.stop()


def wait(condition, what: str) -> None:
    deadline = time.monotonic() + WAIT_S
    while not condition():
        assert time.monotonic() < deadline, f'no {what} within {WAIT_S} s'
        time.sleep(0.1)


def planned_for(node, speed_mps: float) -> bool:
    """Whether the plan in force is made, and its mission built, for ``speed_mps``."""
    outcome = node.current_plan
    return (outcome is not None and outcome.plan.vehicle_plan.limits.max_speed_mps == speed_mps
            and outcome.plan.items is not None)


def describe_plan(node) -> str:
    plan = node.current_plan.plan
    legs = [round(float(leg.speed_mps), 2) for leg in plan.vehicle_plan.schedule.legs]
    commanded = sorted({float(item.params[1]) for item in plan.items
                        if item.command == DO_CHANGE_SPEED})
    return (f'limits {plan.vehicle_plan.limits.max_speed_mps:g} m/s; leg speeds {legs}; '
            f'DO_CHANGE_SPEED {commanded}; min throughput {plan.min_throughput:.6g} bit/s')


def test_the_node_plans_with_the_speed_set_on_the_vehicle(ros_context, sitl):
    vehicle, link = sitl
    set_parameter(link, 'WPNAV_SPEED', 750.0)
    url = f'tcp:127.0.0.1:{5762 + 10 * vehicle.instance}'
    spun = SpunNode(ros_context, {**PLAN, 'mavlink_url': url})
    try:
        node = spun.node
        watch = node.vehicle.parameters
        wait(lambda: watch.read is not None and planned_for(node, 7.5), 'plan for 7.5 m/s')
        print(f'\n{watch.describe()}\nplan: {describe_plan(node)}')
        assert watch.read.values['WPNAV_SPEED'] == 750.0 and watch.read.missing == ()
        assert watch.sources()['max_speed_mps'] == 'vehicle' and watch.used
        legs = node.current_plan.plan.vehicle_plan.schedule.legs
        assert max(leg.speed_mps for leg in legs) <= 7.5
        # The defaults of the rest, as ArduCopter ships them (copter.parm leaves them).
        limits = node.config.vehicle
        assert (limits.max_accel_mpss, limits.max_jerk_mpsss) == (2.5, 1.0)
        # A set while the node is linked: ArduCopter tells every link, the node replans.
        reads = watch.reads
        set_parameter(link, 'WPNAV_SPEED', 800.0)
        wait(lambda: planned_for(node, 8.0), 'plan for 8 m/s after a PARAM_SET')
        assert watch.reads == reads + 1 and watch.read.values['WPNAV_SPEED'] == 800.0
        print(f'after WPNAV_SPEED 800: {describe_plan(node)}')
    finally:
        spun.stop()


def test_an_explicit_speed_wins_over_the_vehicles(ros_context, sitl):
    vehicle, link = sitl
    set_parameter(link, 'WPNAV_SPEED', 750.0)
    url = f'tcp:127.0.0.1:{5762 + 10 * vehicle.instance}'
    spun = SpunNode(ros_context, {**PLAN, 'mavlink_url': url, 'vehicle_max_speed_mps': 9.0})
    try:
        node = spun.node
        watch = node.vehicle.parameters
        wait(lambda: watch.read is not None and planned_for(node, 9.0), 'the read and a plan')
        print(f'\n{watch.describe()}\nplan: {describe_plan(node)}')
        assert watch.read.values['WPNAV_SPEED'] == 750.0
        assert watch.sources()['max_speed_mps'] == 'explicit'
        assert node.config.vehicle.max_speed_mps == 9.0
        assert 'WPNAV_SPEED 750 (vehicle_max_speed_mps set explicitly wins)' in watch.describe()
    finally:
        spun.stop()


#: A vehicle slower to start and stop than ArduCopter's defaults (2.5 m/s/s, 10 m/s).
SLOW_STARTS = {'WPNAV_ACCEL': 100.0, 'WPNAV_SPEED': 750.0}


def test_the_plan_made_with_the_vehicles_values_is_flown_on_time(ros_context, sitl, tmp_path):
    vehicle, link = sitl
    for name, value in SLOW_STARTS.items():
        set_parameter(link, name, value)
    url = f'tcp:127.0.0.1:{5762 + 10 * vehicle.instance}'
    spun = SpunNode(ros_context, {**PLAN, 'mavlink_url': url})
    try:
        node = spun.node
        wait(lambda: planned_for(node, 7.5), 'plan for the vehicle read')
        read_plan = node.current_plan.plan.vehicle_plan
    finally:
        spun.stop()
    link.close()
    vehicle.stop()
    assert (read_plan.limits.max_accel_mpss, read_plan.limits.max_speed_mps) == (1.0, 7.5)
    default_plan = plan_for_vehicle(read_plan.ideal.scenario)
    reports = {}
    for name, vehicle_plan in (('read from the vehicle', read_plan),
                               ('firmware defaults', default_plan)):
        folder = tmp_path / name.replace(' ', '_')
        folder.mkdir()
        flown = fly_plan(vehicle_plan, folder, home=HOME, parameters=SLOW_STARTS,
                         instances=INSTANCES)
        reports[name] = flown.report
        scenario = vehicle_plan.ideal.scenario
        print(f'\nplanned with the {name} ({vehicle_plan.limits.max_accel_mpss:g} m/s/s, '
              f'{vehicle_plan.limits.max_speed_mps:g} m/s), flown on WPNAV_ACCEL 100, '
              f'WPNAV_SPEED 750: {flown.report.summary()}; qF at {flown.arrival_s:.1f} s of '
              f'{scenario.slot_s * (scenario.num_slots + 1):g}')
    report = reports['read from the vehicle']
    assert report.worst_reach_slots <= 1.0
    assert report.flown_to_stated >= 0.99
