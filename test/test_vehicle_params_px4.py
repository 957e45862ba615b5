"""PX4's own limits read from a real PX4 SITL (v1.16, its SIH quadrotor) over the node's link.

PX4 boots with NAV_ACC_RAD 6 m (its default is 2 m) and MPC_ACC_HOR 2.5 m/s/s (default 3):
the node, linked on PX4's onboard port, reads MPC_XY_CRUISE, MPC_ACC_HOR, MPC_JERK_AUTO and
NAV_ACC_RAD (PARAM_REQUEST_READ), and its plan for PX4 is timed with them: each leg's hold
starts counting on entering the 6 m radius (``vehicle/px4_timing.py``), which the figures
printed compare with PX4's default radius. A second test flies that plan on a PX4 with the
same parameters, every planned point within a slot of its time (autopilot time), and the same
mission planned with PX4's defaults beside it (printed). PX4 instance 3, one at a time.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
import time

from helpers import SpunNode
import pytest

from devtools.px4_sitl import (fly_px4_mission, PX4_HOME, quiet_streams, start_px4,
                               why_px4_not_runnable)
from uav_comm_planner.mission.pipeline import plan_mission
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink.link import connect
from uav_comm_planner.vehicle.px4_timing import px4_profile, px4_reach_time

RUN_PX4 = Path(__file__).resolve().parents[2] / 'shared' / 'sitl' / 'px4' / 'run_px4.sh'
#: This module's PX4 SITL instance (onboard port 14540 + 3).
INSTANCE = 3
SPEEDUP = 4
BOOT = {'NAV_ACC_RAD': 6.0, 'MPC_ACC_HOR': 2.5}
#: Two nodes either side of a 400 m line: 30 slots of 4 s at PX4's 5 m/s cruise.
PLAN = {'ground_nodes': [-150.0, 150.0, 150.0, 350.0], 'start_m': [0.0, 10.0],
        'goal_m': [0.0, 400.0], 'max_speed_mps': 5.0, 'horizon_s': 120.0, 'num_slots': 30,
        'altitude_m': 30.0, 'compute_baselines': False, 'mission_firmware': 'px4',
        'home_latitude_deg': PX4_HOME.latitude_deg,
        'home_longitude_deg': PX4_HOME.longitude_deg, 'home_altitude_m': PX4_HOME.altitude_m}
WAIT_S = 180.0

pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(bool(why_px4_not_runnable(RUN_PX4)),
                                 reason=why_px4_not_runnable(RUN_PX4))]


def read_and_plan(ros_context, folder: Path):
    """The node linked to a PX4 booted with :data:`BOOT`, once it plans with what it read:
    (its parameter watch, the plan in force); PX4 and the node are stopped."""
    vehicle = start_px4(folder, INSTANCE, script=RUN_PX4, speedup=SPEEDUP, parameters=BOOT)
    spun = None
    try:
        # The onboard port streams much at its rates in simulated time: only what the node
        # asks for is kept.
        onboard = connect(vehicle.onboard_url, timeout_s=60.0)
        quiet_streams(onboard)
        onboard.close()
        spun = SpunNode(ros_context, {**PLAN, 'mavlink_url': vehicle.onboard_url})
        node = spun.node
        watch = node.vehicle.parameters

        def planned() -> bool:
            outcome = node.current_plan
            return (watch.used and outcome is not None and outcome.plan.items is not None
                    and outcome.plan.vehicle_plan.limits.acceptance_radius_m == 6.0)
        deadline = time.monotonic() + WAIT_S
        while not planned():
            assert time.monotonic() < deadline, f'no plan with the read; {watch.read}'
            time.sleep(0.2)
        return watch, node.current_plan
    finally:
        if spun is not None:
            spun.stop()
        vehicle.stop()


def test_nav_acc_rad_set_on_px4_times_the_plans_legs(ros_context, tmp_path):
    watch, outcome = read_and_plan(ros_context, tmp_path)
    print(f'\n{watch.describe()}')
    read = watch.read
    assert read.firmware == 'px4' and read.missing == ()
    assert (read.values['NAV_ACC_RAD'], read.values['MPC_ACC_HOR']) == (6.0, 2.5)
    # PX4 v1.16's defaults of the two not set at boot.
    assert (read.values['MPC_XY_CRUISE'], read.values['MPC_JERK_AUTO']) == (5.0, 4.0)
    assert set(watch.sources().values()) == {'vehicle'}
    plan = outcome.plan.vehicle_plan
    assert (plan.limits.max_accel_mpss, plan.limits.acceptance_radius_m) == (2.5, 6.0)
    default_radius = replace(plan.limits, acceptance_radius_m=None)     # PX4's 2 m
    for index, leg in enumerate(plan.schedule.legs):
        wide = px4_reach_time(leg.vertices, leg.speed_mps, plan.limits)
        narrow = px4_reach_time(leg.vertices, leg.speed_mps, default_radius)
        profile = px4_profile(leg.vertices, leg.speed_mps, plan.limits)
        print(f'leg {index}: {len(leg.vertices)} vertices at {leg.speed_mps:.2f} m/s; hold '
              f'counts from {wide:.2f} s (NAV_ACC_RAD 6 m), {narrow:.2f} s at 2 m; at rest '
              f'{profile.duration_s:.2f} s')
        assert wide < narrow
        # The plan's leg is timed with the radius read, not PX4's default.
        assert leg.profile.hold_start_s == pytest.approx(wide, abs=1e-9)
        assert leg.profile.duration_s == pytest.approx(profile.duration_s, abs=1e-9)


def test_the_plan_timed_with_px4s_own_values_is_flown_on_time(ros_context, tmp_path):
    (tmp_path / 'read').mkdir()
    _, outcome = read_and_plan(ros_context, tmp_path / 'read')
    request = outcome.plan.request
    plans = {'read from the vehicle': outcome.plan,
             "PX4's defaults": plan_mission(replace(
                 request, vehicle=VehicleLimits.for_firmware('px4')))}
    reports = {}
    for name, planned in plans.items():
        folder = tmp_path / name.replace(' ', '_').replace("'", '')
        folder.mkdir()
        mission = planned.write(folder / 'mission.plan')
        flown = fly_px4_mission(planned.vehicle_plan, mission, folder, instance=INSTANCE,
                                parameters=BOOT, speedup=SPEEDUP, script=RUN_PX4)
        reports[name] = flown.report
        limits = planned.vehicle_plan.limits
        scenario = request.scenario
        print(f'\nplanned with the {name} (NAV_ACC_RAD {limits.acceptance_radius_m or 2.0:g} m, '
              f'MPC_ACC_HOR {limits.max_accel_mpss:g}), flown on NAV_ACC_RAD 6, MPC_ACC_HOR '
              f'2.5: {flown.report.summary()}; qF at {flown.arrival_s:.1f} s of '
              f'{scenario.slot_s * (scenario.num_slots + 1):g}')
    report = reports['read from the vehicle']
    assert report.worst_reach_slots <= 1.0
    assert report.flown_to_stated >= 0.99
