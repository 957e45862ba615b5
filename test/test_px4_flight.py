"""The package's PX4 missions flown by PX4 itself: PX4 v1.16 SITL, its SIH quadrotor.

Each case is planned for PX4 with the package's own pipeline (``plan_mission``, firmware
``px4``: PX4's leg timing, :mod:`uav_comm_planner.vehicle.px4_timing`), written as a
QGroundControl ``.plan``, uploaded and read back with the package's ``upload``
(:func:`~uav_comm_planner.vehicle.mavlink.upload.upload_file`), and flown in AUTO.MISSION on a
fresh PX4 SITL (``../shared/sitl/px4``) with PX4's default parameters but MPC_XY_CRUISE. The
flights run one after the other (instances 4 to 8) at a speed-up of 5. The plan's
clock starts when PX4 starts counting the hold at q0; every time is autopilot time. What must hold,
for the letter's case I at 5 and at 10 m/s and for a random scenario of six nodes:

- every planned point reached within one slot of its planned time, the median within
  MEDIAN_SLOTS; qF reported reached within one slot of the end of the horizon;
- the plan's power schedule, at the positions flown at the planned slot times, gives at least
  99 % of the min throughput the plan states.

A mission PX4 refuses is reported by ``uav-comm-planner upload`` as one error line naming the
item (instance 7). The held-out five-node case (instance 8) was drawn for this test and never
used to fit PX4's leg timing: its median within a quarter of a slot. The figures are printed
for the record (``pytest -s``).
"""

from __future__ import annotations

from pathlib import Path
import subprocess
import sys

from helpers import random_scenario, random_six_nodes
import pytest

from devtools.px4_sitl import fly_px4_mission, PX4_HOME, start_px4, why_px4_not_runnable
from uav_comm_planner import paper_scenario
from uav_comm_planner.mission.pipeline import plan_mission
from uav_comm_planner.mission.request import MissionRequest
from uav_comm_planner.vehicle.limits import VehicleLimits

RUN_PX4 = Path(__file__).resolve().parents[2] / 'shared' / 'sitl' / 'px4' / 'run_px4.sh'
CLI = [sys.executable, '-m', 'uav_comm_planner.tools.cli']
#: Three PX4s at 10x on a loaded 2-core machine once flew a point 4.2 s late (its flight
#: controller's threads starved); at 5x they keep up.
SPEEDUP = 5
#: The median point's lateness, slots. The same missions fly differently from run to run
#: (then three PX4s side by side on two cores): over ten runs the case I 10 m/s median was 0.01 to
#: 0.28 slot, the legs flown up to about 0.4 s per stop later than PX4's leg timing says, and
#: one case I 5 m/s run at a speed-up of 3 gave 0.38. A quarter of a slot held in eight of
#: the ten. With the braking lead refitted to those legs, three runs gave 0.07-0.08 at 10 m/s
#: and 0.00-0.15 for the other two (docs/flying.md, "Measured on PX4").
MEDIAN_SLOTS = 0.4

pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(bool(why_px4_not_runnable(RUN_PX4)),
                                 reason=why_px4_not_runnable(RUN_PX4))]


def px4_limits(cruise_mps: float) -> VehicleLimits:
    """PX4's MPC_ACC_HOR (3 m/s/s) and MPC_JERK_AUTO (4 m/s/s/s) defaults at a cruise."""
    return VehicleLimits(max_speed_mps=cruise_mps, max_accel_mpss=3.0, max_jerk_mpsss=4.0)


#: name: (scenario, cruise m/s, PX4 SITL instance). 4 s slots.
CASES = {
    'case I at 5 m/s': (paper_scenario('I', max_speed_mps=5.0, horizon_s=600.0,
                                       num_slots=150), 5.0, 4),
    'case I at 10 m/s': (paper_scenario('I', max_speed_mps=10.0, horizon_s=400.0,
                                        num_slots=100), 10.0, 5),
    'random, six nodes, 5 m/s': (random_six_nodes().replace(max_speed_mps=5.0, horizon_s=600.0,
                                                            num_slots=150), 5.0, 6),
    # Held out: drawn for this test only, never used to fit PX4's leg timing.
    'held out, five nodes, 5 m/s': (random_scenario(
        21, nodes=5, slots=200, side_m=1000.0, max_speed_mps=5.0, horizon_s=800.0), 5.0, 8),
}
#: The held-out case's median lateness, slots: a quarter of a slot.
HELD_OUT_MEDIAN_SLOTS = 0.25


def fly_case(name: str, folder: Path):
    scenario, cruise, instance = CASES[name]
    request = MissionRequest(scenario=scenario, vehicle=px4_limits(cruise), firmware='px4',
                             home=PX4_HOME)
    planned = plan_mission(request)
    mission = planned.write(folder / 'mission.plan')
    flown = fly_px4_mission(planned.vehicle_plan, mission, folder, instance=instance,
                            parameters={'MPC_XY_CRUISE': cruise}, speedup=SPEEDUP,
                            script=RUN_PX4)
    return planned.vehicle_plan, flown


@pytest.fixture(scope='module')
def flights(tmp_path_factory):
    # One flight at a time. PX4 SITL's lockstep clock waits for its work queues (the
    # controllers) but not for its tasks (navigator, commander): a machine that does not run
    # the navigator in time holds the mission while the clock goes on. Three PX4s side by side
    # (about 40 % of two cores at 5x) on a CI machine slower than this one flew a point of the
    # six-node case 1.02 slots late; on a quiet machine the same flight's worst is 0.17-0.25.
    results = {name: fly_case(name, tmp_path_factory.mktemp('px4')) for name in CASES}
    for name, (vehicle_plan, flown) in results.items():
        scenario = vehicle_plan.ideal.scenario
        end_s = scenario.slot_s * (scenario.num_slots + 1)
        within = int((flown.report.reach_errors_s <= scenario.slot_s).sum())
        print(f'\n{name}: {flown.report.summary()}; {within} of '
              f'{len(flown.report.reach_errors_s)} points within a slot; qF reached at '
              f'{flown.arrival_s:.1f} s, planned {end_s:g} s')
    return results


@pytest.mark.parametrize('name', list(CASES))
def test_px4_reaches_every_planned_point_on_time(flights, name):
    vehicle_plan, flown = flights[name]
    scenario = vehicle_plan.ideal.scenario
    assert flown.report.worst_reach_slots <= 1.0
    assert flown.report.median_reach_slots <= (HELD_OUT_MEDIAN_SLOTS if name.startswith('held')
                                               else MEDIAN_SLOTS)
    assert abs(flown.arrival_s - scenario.slot_s * (scenario.num_slots + 1)) <= scenario.slot_s


@pytest.mark.parametrize('name', list(CASES))
def test_the_nodes_get_what_the_px4_plan_states(flights, name):
    _, flown = flights[name]
    assert flown.report.flown_to_stated >= 0.99


#: A QGC WPL 110 mission whose row 3 holds a command PX4 does not know (31999).
REFUSED = '''QGC WPL 110
0\t1\t0\t16\t0\t0\t0\t0\t47.397742\t8.545594\t489\t1
1\t0\t3\t22\t0\t0\t0\t0\t47.397742\t8.545594\t20\t1
2\t0\t3\t16\t0\t0\t0\t0\t47.3978\t8.5456\t20\t1
3\t0\t3\t31999\t0\t0\t0\t0\t47.3979\t8.5457\t20\t1
4\t0\t3\t21\t0\t0\t0\t0\t47.3979\t8.5457\t0\t1
'''


def test_upload_reports_the_item_px4_refuses(tmp_path):
    mission = tmp_path / 'refused.waypoints'
    mission.write_text(REFUSED)
    vehicle = start_px4(tmp_path, 7, script=RUN_PX4, speedup=SPEEDUP)
    try:
        uploaded = subprocess.run(CLI + ['upload', str(mission), '--connect',
                                         vehicle.onboard_url, '--connect-timeout', '60'],
                                  capture_output=True, text=True, timeout=180)
    finally:
        vehicle.stop()
    assert uploaded.returncode == 2
    lines = uploaded.stderr.strip().splitlines()
    assert len(lines) == 1
    # PX4 numbers its items from the take-off: the file's row 3 is its item 2.
    assert 'refused the mission at item 2' in lines[0], lines[0]
