"""A plan around a no-fly zone flown by PX4 SITL with its geofence on.

Two nodes either side of a 400 m line at PX4's 5 m/s cruise, an operating area around the
field and a keep-out wall across the straight line: the plan (the package's pipeline for
``px4``) goes round the wall; the mission and the zones as PX4's geofence (an inclusion and an
exclusion polygon, MAV_MISSION_TYPE_FENCE, from the same .plan file) are uploaded and read back
(:func:`~uav_comm_planner.vehicle.mavlink.upload.upload_files`), and PX4 enforces the fence
(GF_ACTION 2: a breach puts it in AUTO.LOITER). What must hold:

- no breach: PX4's heartbeat shows AUTO.MISSION only, and every position flown keeps out of
  the wall and inside the area;
- on time as PX4's flights without zones (``test_px4_flight.py``): every planned point within
  one slot of its planned time, and the nodes getting at least 99 % of what the plan states;
- the fence is PX4's own: the plan made without the zones (across the wall), uploaded under the
  same fence on a fresh PX4, is refused by PX4's mission check ("Geofence violation for
  waypoint N").

PX4 SITL instance 5 at a speed-up of 5. The figures are printed (``pytest -s``).
"""

from __future__ import annotations

from pathlib import Path
import time

import pytest

from devtools.px4_sitl import (fly_px4_mission, PX4_HOME, quiet_streams, start_px4,
                               upload_with_retries, why_px4_not_runnable)
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.core.zones import KeepOutPolygon, OperatingArea, Zones
from uav_comm_planner.mission.pipeline import plan_mission
from uav_comm_planner.mission.request import MissionRequest
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink.guided import PX4_MODES
from uav_comm_planner.vehicle.mavlink.link import connect

RUN_PX4 = Path(__file__).resolve().parents[2] / 'shared' / 'sitl' / 'px4' / 'run_px4.sh'
INSTANCE = 5
SPEEDUP = 5
AREA = OperatingArea([(-300.0, -60.0), (300.0, -60.0), (300.0, 460.0), (-300.0, 460.0)])
#: Across the straight line q0 -> qF.
WALL = KeepOutPolygon([(-60.0, 180.0), (60.0, 180.0), (60.0, 220.0), (-60.0, 220.0)])
ZONES = Zones(AREA, (WALL,), margin_m=10.0)
SCENARIO = Scenario(ground_nodes_m=((-150.0, 150.0), (150.0, 350.0)), start_m=(0.0, 10.0),
                    goal_m=(0.0, 400.0), max_speed_mps=5.0, horizon_s=140.0, num_slots=35,
                    altitude_m=30.0, zones=ZONES)
#: PX4's MPC_ACC_HOR (3 m/s/s) and MPC_JERK_AUTO (4 m/s/s/s) defaults at its 5 m/s cruise.
LIMITS = VehicleLimits(max_speed_mps=5.0, max_accel_mpss=3.0, max_jerk_mpsss=4.0)

pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(bool(why_px4_not_runnable(RUN_PX4)),
                                 reason=why_px4_not_runnable(RUN_PX4))]


@pytest.fixture(scope='module')
def flight(tmp_path_factory):
    folder = tmp_path_factory.mktemp('px4_fence')
    planned = plan_mission(MissionRequest(scenario=SCENARIO, vehicle=LIMITS, firmware='px4',
                                          home=PX4_HOME))
    mission = planned.write(folder / 'mission.plan')        # its geoFence: the zones
    flown = fly_px4_mission(planned.vehicle_plan, mission, folder, instance=INSTANCE,
                            parameters={'MPC_XY_CRUISE': 5.0, 'GF_ACTION': 2},
                            speedup=SPEEDUP, script=RUN_PX4, fence=mission)
    record = flown.record
    print(f'\nfenced flight on PX4: {flown.report.summary()}; least clearance flown '
          f'{ZONES.clearance(record.positions_m).min():.2f} m (planned '
          f'{ZONES.path_clearance(planned.vehicle_plan.flown.trajectory):.3f} m, margin '
          f'{ZONES.margin_m:g} m); modes {sorted(record.modes)}')
    return planned, flown


def test_the_plan_goes_round_the_wall(flight):
    planned, _ = flight
    assert ZONES.path_clearance(planned.vehicle_plan.ideal.trajectory) >= ZONES.margin_m - 1e-6
    # As PX4 flies it (its leg timing's points between the waypoints): within 0.25 m of the
    # margin (0.095 m inside it measured).
    assert ZONES.path_clearance(planned.vehicle_plan.flown.trajectory) >= ZONES.margin_m - 0.25
    unfenced = plan_mission(MissionRequest(scenario=SCENARIO.replace(zones=None),
                                           vehicle=LIMITS, firmware='px4', home=PX4_HOME))
    assert Zones(keep_out=(WALL,)).path_clearance(unfenced.vehicle_plan.flown.trajectory) < 0


def test_px4_flies_it_inside_its_fence_in_auto_mission_only(flight):
    _, flown = flight
    record = flown.record
    assert record.modes == {PX4_MODES['AUTO.MISSION']}
    assert ZONES.clearance(record.positions_m).min() > 0


def test_the_fenced_flight_is_on_time(flight):
    _, flown = flight
    assert flown.report.worst_reach_slots <= 1.0
    assert flown.report.flown_to_stated >= 0.99


#: How long PX4 has to say that a mission breaks its fence (wall clock).
REFUSAL_WAIT_S = 60.0


def test_px4_refuses_the_plan_across_the_wall_under_the_same_fence(tmp_path):
    fenced = plan_mission(MissionRequest(scenario=SCENARIO, vehicle=LIMITS, firmware='px4',
                                         home=PX4_HOME))
    fence = fenced.write(tmp_path / 'fence.plan')
    unfenced = plan_mission(MissionRequest(scenario=SCENARIO.replace(zones=None),
                                           vehicle=LIMITS, firmware='px4', home=PX4_HOME))
    mission = unfenced.write(tmp_path / 'mission.plan')
    vehicle = start_px4(tmp_path, INSTANCE, script=RUN_PX4, speedup=SPEEDUP,
                        parameters={'GF_ACTION': 2})
    listen = None
    try:
        onboard = connect(vehicle.onboard_url, timeout_s=60.0)
        quiet_streams(onboard)
        onboard.close()
        listen = connect(vehicle.ground_station_url, timeout_s=60.0)
        upload_with_retries(mission, vehicle.onboard_url, fence)
        said: list[str] = []
        deadline = time.monotonic() + REFUSAL_WAIT_S
        while time.monotonic() < deadline and not any('Geofence' in text for text in said):
            message = listen.recv_match(type='STATUSTEXT', blocking=True, timeout=1.0)
            if message is not None:
                said.append(message.text)
        print('PX4 said:', said)
        assert any('Geofence violation for waypoint' in text for text in said)
    finally:
        if listen is not None:
            listen.close()
        vehicle.stop()
