"""Two ArduCopter SITL vehicles fly a two-UAV plan at once, each streamed on its own clock
(:mod:`devtools.fleet_flight`), judged together on plan time: each on time at every slot, the
plan's power at the positions flown delivering what the plan states, never closer than d_min.
Then the link to one of them is cut for 20 s of its autopilot time mid-flight: the other flies
on, on time, delivering its own share of every node's throughput as its plan states, while the
cut one holds, is heard again and catches its plan up as a single streamed vehicle does.

Held-out plans: two nodes the planner has not seen elsewhere, the UAVs' ends 50 m apart and
d_min = 40 m, slow enough (5 m/s, 5 s slots) for ArduCopter's default acceleration and jerk to
follow the smooth reference through every plan point, and for the cut vehicle (cruise 10 m/s)
to make the lost time up well before qF. Every time is autopilot time (``time_boot_ms``).
"""

from __future__ import annotations

import numpy as np
import pytest

from devtools.fleet_flight import fly_fleet, LinkCut
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
#: The cut test's instances (two shares of five).
CUT_INSTANCES = (65, 74)
#: UAV 1's stream link cut 60 s into its plan (slot 12 of 40) for 20 s of its autopilot time.
CUT = LinkCut(uav=0, at_s=60.0, for_s=20.0)


def held_out_fleet(nodes: tuple[tuple[float, float], ...]) -> FleetScenario:
    """Two UAVs 50 m apart from y = 0 to y = 500 over ``nodes`` at 5 m/s, 40 slots of 5 s."""
    base = paper_scenario('I', ground_nodes_m=nodes, start_m=(-25.0, 0.0),
                          goal_m=(-25.0, 500.0), max_speed_mps=5.0, horizon_s=200.0,
                          num_slots=40, altitude_m=30.0)
    return FleetScenario(base, ((-25.0, 0.0), (25.0, 0.0)), ((-25.0, 500.0), (25.0, 500.0)),
                         SEPARATION_M)


def test_two_vehicles_fly_the_fleet_plan_on_time_and_apart(tmp_path):
    fleet = held_out_fleet(((-150.0, 150.0), (150.0, 350.0)))
    base = fleet.scenario
    plan = plan_fleet(fleet)
    flight = fly_fleet(plan, tmp_path, home=HOME, instances=INSTANCES)
    print(f'off the plan at the slots: {flight.slot_errors_m.max(axis=1)} m at most; flown / '
          f'stated min throughput {flight.flown_min_throughput / plan.min_throughput:.7f} '
          f'({plan.min_throughput:.6g} bit/s); apart {flight.closest_at_slots_m:.1f} m at the '
          f'slots, {flight.closest_m:.1f} m over the flight')
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


def test_a_link_cut_on_one_vehicle_does_not_stop_the_other(tmp_path):
    fleet = held_out_fleet(((-140.0, 380.0), (170.0, 120.0)))
    base, plan = fleet.scenario, plan_fleet(fleet)
    flight = fly_fleet(plan, tmp_path, home=HOME, instances=CUT_INSTANCES, cut=CUT)
    cut, other = flight.tracks
    tolerance = 0.1 * base.max_step_m
    errors = flight.slot_errors_m
    print(f'UAV 1 cut from {cut.outage_s[0]:.1f} to {cut.outage_s[1]:.1f} s of its plan; UAV 2 '
          f'was then at {other.outage_s[0]:.1f} to {other.outage_s[1]:.1f} s of its own')
    print('UAV 1 said:', [event.message for event in cut.events])
    print('UAV 2 said:', [event.message for event in other.events])
    assert CUT.at_s <= cut.outage_s[0] <= CUT.at_s + 0.5
    assert cut.outage_s[1] - cut.outage_s[0] >= CUT.for_s
    # UAV 2 during the outage, on its own clock: heard throughout, on time at every slot.
    start, end = other.outage_s
    near = other.times_s[(other.times_s >= start - 1.0) & (other.times_s <= end + 1.0)]
    during = (plan.times >= start) & (plan.times <= end)
    print(f'UAV 2: {len(near)} positions around the outage, largest gap '
          f'{np.diff(near).max():.2f} s; {during.sum()} slots within it, off its plan by '
          f'{errors[1, during].max():.2f} m at most ({errors[1].max():.2f} m over the flight)')
    assert near[0] <= start and near[-1] >= end and np.diff(near).max() <= 0.5
    assert during.sum() >= 3 and errors[1].max() <= tolerance
    # Its own share of every node's throughput, at the positions it flew, as its plan states.
    flown, stated = flight.own_rates(1)
    print('UAV 2 flown / stated per node:', flown / stated)
    assert np.all(flown >= 0.99 * stated)
    assert other.said('lost') == [] and other.catch_up is None
    assert len(other.said('stopped')) == 1 and 'reached qF' in other.said('stopped')[0]
    # UAV 1: the loss said once, the link up again, its plan caught up once, on time after.
    catch = cut.catch_up
    print(f'UAV 1 resumed {catch.lag_s:.1f} s behind at {catch.clock_s[0]:.1f} s, on time '
          f'again at {catch.caught_s:.1f} s of its plan')
    assert len(cut.said('lost')) == 1 and len(cut.said('connected')) == 2
    assert len(cut.said('caught up')) == 1 and catch.clock_s[0] >= cut.outage_s[1]
    assert catch.caught_s < plan.times[-1]
    after = plan.times >= catch.caught_s + base.slot_s
    print(f'UAV 1 off its plan by {errors[0, after].max():.2f} m at most at the '
          f'{after.sum()} slots after the catch-up')
    assert after.sum() >= 3 and errors[0, after].max() <= tolerance
    # Every point of its plan from the cut on flown (late until the time was made up).
    late = plan.times > cut.outage_s[0]
    passed = [np.linalg.norm(cut.positions_m[cut.times_s >= when - base.slot_s] - point,
                             axis=1).min()
              for point, when in zip(plan.trajectories[0][late], plan.times[late])]
    print(f'UAV 1 passed each of its {late.sum()} points after the cut within '
          f'{max(passed):.2f} m')
    assert max(passed) <= tolerance
    print(f'closest approach {flight.closest_m:.1f} m (d_min {SEPARATION_M:g}); the two '
          f'together delivered {flight.flown_min_throughput:.6g} bit/s of the '
          f'{plan.min_throughput:.6g} stated')
    assert flight.closest_m >= SEPARATION_M
