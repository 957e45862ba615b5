"""Two ArduCopter SITL vehicles fly a two-UAV plan at once, each streamed on its own clock
(:mod:`devtools.fleet_flight`), judged together on plan time: each on time at every slot, the
plan's power at the positions flown delivering what the plan states, never closer than d_min.

A held-out plan: two nodes the planner has not seen elsewhere, the UAVs' ends 50 m apart and
d_min = 40 m, slow enough (5 m/s, 5 s slots) for ArduCopter's default acceleration and jerk to
follow the smooth reference through every plan point.
"""

from __future__ import annotations

import numpy as np
import pytest

from devtools.fleet_flight import fly_fleet
from devtools.sitl import why_not_runnable
from uav_comm_planner.core.fleet import FleetScenario, plan_fleet
from uav_comm_planner.core.scenario import paper_scenario
from uav_comm_planner.vehicle.geodesy import Home

pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(bool(why_not_runnable()), reason=why_not_runnable())]

HOME = Home(-35.363262, 149.165237, 584.0)
#: This module's vehicles' instances (MAVLink TCP 5760 + 10 I), one half each.
INSTANCES = (20, 29)
SEPARATION_M = 40.0


def test_two_vehicles_fly_the_fleet_plan_on_time_and_apart(tmp_path):
    base = paper_scenario('I', ground_nodes_m=((-150.0, 150.0), (150.0, 350.0)),
                          start_m=(-25.0, 0.0), goal_m=(-25.0, 500.0), max_speed_mps=5.0,
                          horizon_s=200.0, num_slots=40, altitude_m=30.0)
    fleet = FleetScenario(base, ((-25.0, 0.0), (25.0, 0.0)), ((-25.0, 500.0), (25.0, 500.0)),
                          SEPARATION_M)
    plan = plan_fleet(fleet)
    flight = fly_fleet(plan, tmp_path, home=HOME, instances=INSTANCES)
    # On time: at every slot time each vehicle is within a tenth of a slot's travel
    # (V delta = 25 m) of its planned point.
    assert flight.slot_errors_m.max() <= 0.1 * base.max_step_m, flight.slot_errors_m.max(axis=1)
    # Judged on both flights together: the plan's power at the positions flown.
    assert flight.flown_min_throughput >= 0.99 * plan.min_throughput, (
        flight.flown_min_throughput, plan.min_throughput)
    # Apart at every slot and over the whole flight, telemetry sample by sample.
    assert flight.closest_at_slots_m >= SEPARATION_M, flight.closest_at_slots_m
    assert flight.closest_m >= SEPARATION_M, flight.closest_m
    for track in flight.tracks:
        assert track.times_s[0] <= 0.5 and track.times_s[-1] >= plan.times[-1], (
            track.times_s[0], track.times_s[-1])
        assert np.all(np.diff(track.times_s) > 0)
