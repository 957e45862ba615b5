"""A plan around a no-fly zone flown by ArduCopter SITL with its fence on.

The letter's case I at 10 m/s with an operating area around the field and a keep-out wall
across its straight line (and across the leg from node 1 to node 2 the unfenced plan flies):
the plan goes round the wall's corner; the zones are uploaded as the vehicle's fence (an
inclusion polygon and an exclusion polygon, MAV_MISSION_TYPE_FENCE), read back identical,
and enforced (FENCE_ENABLE 1, FENCE_TYPE 4: breaching would switch the vehicle to RTL or
LAND). What must hold:

- the fence accepted and read back identical;
- no breach: FENCE_STATUS reports none, the heartbeat's mode stays AUTO, and every position
  flown keeps out of the wall and inside the area;
- on time as the flights without zones (``test_sitl_flight.py``): every planned point within
  one slot of its planned time, the median within a quarter of a slot, and the nodes getting
  at least 99 % of what the plan states, more than both baselines.

The figures are printed for the record (``pytest -s``).
"""

from __future__ import annotations

import pytest

from devtools.sitl import fly_plan, why_not_runnable
from uav_comm_planner import paper_scenario
from uav_comm_planner.core.zones import KeepOutPolygon, OperatingArea, Zones
from uav_comm_planner.vehicle.fence import fence_from_zones
from uav_comm_planner.mission.policy import plan_for_vehicle
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.mavlink.fence import fence_items
from uav_comm_planner.vehicle.mavlink.guided import COPTER_MODES
from uav_comm_planner.vehicle.mavlink.items import mismatches

pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(bool(why_not_runnable()), reason=why_not_runnable())]

HOME = Home(-35.363262, 149.165237, 584.0)
AREA = OperatingArea([(-100.0, -100.0), (2100.0, -100.0), (2100.0, 600.0), (-100.0, 600.0)])
#: From below the straight line q0 -> qF up across the leg node 1 -> node 2.
WALL = KeepOutPolygon([(560.0, -150.0), (640.0, -150.0), (640.0, 330.0), (560.0, 330.0)])
ZONES = Zones(AREA, (WALL,), margin_m=10.0)
SCENARIO = paper_scenario('I', max_speed_mps=10.0, horizon_s=400.0, num_slots=100,
                          zones=ZONES)


@pytest.fixture(scope='module')
def flight(tmp_path_factory):
    vehicle_plan = plan_for_vehicle(SCENARIO)
    flown = fly_plan(vehicle_plan, tmp_path_factory.mktemp('sitl'), home=HOME,
                     instances=(20, 29))
    record = flown.record
    flown_clearance = ZONES.clearance(record.positions_m).min()
    planned_clearance = ZONES.path_clearance(vehicle_plan.flown.trajectory)
    print(f'\nfenced case I: {flown.report.summary()}; qF reached at {flown.arrival_s:.1f} s, '
          f'planned {SCENARIO.slot_s * (SCENARIO.num_slots + 1):g} s; least clearance flown '
          f'{flown_clearance:.2f} m (planned {planned_clearance:.4f} m, margin '
          f'{ZONES.margin_m:g} m); fence breaches {record.fence_breaches}; modes '
          f'{sorted(record.modes)}; baselines '
          + ', '.join(f'{key} {value:.6g}' for key, value in vehicle_plan.ideal.baselines.items()))
    return vehicle_plan, flown


def test_the_plan_goes_round_the_wall(flight):
    vehicle_plan, _ = flight
    assert ZONES.path_clearance(vehicle_plan.ideal.trajectory) >= ZONES.margin_m - 1e-6
    # As the vehicle flies it (S-curve legs between the mission's waypoints): within a
    # centimetre of the margin.
    assert ZONES.path_clearance(vehicle_plan.flown.trajectory) >= ZONES.margin_m - 0.01
    # The wall is in the way: the plan without it crosses it.
    unfenced = plan_for_vehicle(SCENARIO.replace(zones=None))
    assert Zones(keep_out=(WALL,)).path_clearance(unfenced.flown.trajectory) < 0


def test_the_fence_is_held_as_uploaded(flight):
    _, flown = flight
    sent = fence_items(fence_from_zones(ZONES, HOME))
    assert len(flown.fence) == len(sent) == 8
    assert mismatches(sent, list(flown.fence), home_row=False) == []


def test_the_flight_never_breaches_the_fence(flight):
    _, flown = flight
    record = flown.record
    assert record.fence_breaches == 0
    assert record.modes == {COPTER_MODES['AUTO']}
    assert ZONES.clearance(record.positions_m).min() > 0


def test_the_fenced_flight_is_on_time(flight):
    vehicle_plan, flown = flight
    report = flown.report
    assert report.worst_reach_slots <= 1.0
    assert report.median_reach_slots <= 0.25
    assert report.flown_to_stated >= 0.99
    assert report.flown > max(vehicle_plan.ideal.baselines.values())
