"""A plan with altitudes flown by a real autopilot: ArduCopter in software-in-the-loop.

The letter's case I under `los:urban`, at a radio where altitude matters, planned with the
altitude free in 30..120 m, climbing at up to 0.5 m/s (a third of WPNAV_SPEED_DN), timed for
ArduCopter with its climbs, uploaded (read back and compared, altitudes included), taken off to
q0's altitude and flown in AUTO. From the telemetry (GLOBAL_POSITION_INT's time_boot_ms,
position and relative_alt):

- every planned point (q0, the slots' points, qF) reached within one slot of its planned time,
  within 2 m horizontally and 1 m of its altitude, the median within a quarter of a slot;
- the vehicle at the planned altitude at the slot times (within 2 m);
- the plan's power, at the positions and altitudes flown at the slot times, gives at least 99 %
  of the min throughput the plan states.

The figures are printed for the record (``pytest -s``).
"""

from __future__ import annotations

import numpy as np
import pytest

from devtools.sitl import fly_plan, why_not_runnable
from uav_comm_planner import paper_scenario
from uav_comm_planner.core.altitude import AltitudeLimits, rates_3d
from uav_comm_planner.mission.altitude import plan_altitude_for_vehicle
from uav_comm_planner.vehicle.evaluation import positions_at, reach_errors_3d
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.mavlink.items import Q0_SEQ

pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(bool(why_not_runnable()), reason=why_not_runnable())]

HOME = Home(-35.363262, 149.165237, 584.0)
#: Where altitude matters (docs/channel.md): B = 1 MHz, -145 dBm/Hz, P_T = 0.1 W.
SCENARIO = paper_scenario('I', max_speed_mps=10.0, horizon_s=400.0, num_slots=50,
                          channel='los:urban', bandwidth_hz=1e6, noise_psd_dbm_per_hz=-145.0,
                          power_budget_w=0.1)
LIMITS = AltitudeLimits((30.0, 120.0), 0.5)
#: The SITL instances this test may use.
INSTANCES = (75, 84)


@pytest.fixture(scope='module')
def flight(tmp_path_factory):
    planned = plan_altitude_for_vehicle(SCENARIO, LIMITS)
    flown = fly_plan(planned.mission, tmp_path_factory.mktemp('sitl'), home=HOME,
                     instances=INSTANCES)
    record = flown.record
    start_s = flown.record.reached[Q0_SEQ] - planned.mission.schedule.stops[0].hold_s
    points, heights, times = planned.planned_points()
    errors = reach_errors_3d(points, heights, times, record.times_s, record.positions_m,
                             record.altitudes_m, start_s)
    at = SCENARIO.times_s + start_s
    xy = positions_at(at, record.times_s, record.positions_m)
    up = np.interp(at, record.times_s, record.altitudes_m)
    rates = rates_3d(xy, up, planned.power, SCENARIO)
    altitude_errors = np.abs(up - planned.altitudes)
    print(f'\naltitudes planned {planned.ideal.altitudes.min():.1f} to '
          f'{planned.ideal.altitudes.max():.1f} m, take-off to {heights[0]:.1f} m; reached '
          f'within {errors.max() / SCENARIO.slot_s:.2f} slot (median '
          f'{np.median(errors) / SCENARIO.slot_s:.2f}); altitude at the slot times within '
          f'{altitude_errors.max():.2f} m (median {np.median(altitude_errors):.2f}); flown '
          f'{rates.min():.6g} bit/s = {100 * rates.min() / planned.min_throughput:.2f} % of the '
          f'stated {planned.min_throughput:.6g} (ideal {planned.ideal.min_throughput:.6g}, best '
          f'fixed altitude {planned.ideal.fixed.min_throughput:.6g}, flown level '
          f'{planned.alternative_throughput:.6g}); qF reached at '
          f'{flown.arrival_s:.1f} s, planned {SCENARIO.slot_s * (SCENARIO.num_slots + 1):g} s')
    return planned, errors, altitude_errors, rates


def test_the_plan_climbs_and_descends_and_flies_better_than_the_level_one(flight):
    planned, *_ = flight
    assert np.ptp(planned.ideal.altitudes) > 10.0
    assert not planned.level and planned.min_throughput > planned.alternative_throughput


def test_every_planned_point_is_reached_on_time_at_its_altitude(flight):
    _, errors, _, _ = flight
    assert errors.max() <= SCENARIO.slot_s
    assert np.median(errors) <= 0.25 * SCENARIO.slot_s


def test_the_vehicle_is_at_the_planned_altitude_at_the_slot_times(flight):
    _, _, altitude_errors, _ = flight
    assert altitude_errors.max() <= 2.0


def test_the_nodes_get_what_the_plan_states(flight):
    planned, _, _, rates = flight
    assert rates.min() >= 0.99 * planned.min_throughput
