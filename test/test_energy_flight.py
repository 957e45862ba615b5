"""The propulsion energy a plan states against the energy ArduCopter SITL's battery reports.

Held-out missions (not the legs the airframe was fitted on: see
uav_comm_planner/vehicle/airframes/arducopter_sitl_quad.yaml's source) planned with the default
ArduPilot airframe are flown on ArduCopter SITL (BATT_MONITOR 4, copter.parm's, reads the
simulated battery); between the plan's clock start at q0 and reaching qF the battery's
energy_consumed must be within 5 % of the plan's ``propulsion_energy_j`` (the flown plan's
legs, each at constant velocity over its slot, at its airspeed), and the mean power, energy
over duration flown and planned, within 2 %; in still air, and in a wind the plan is told.
The figures are printed for the record (``pytest -s``).
"""

from __future__ import annotations

from helpers import random_six_nodes
import pytest

from devtools.sitl import fly_plan, why_not_runnable
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.mission.energy import energy_figures
from uav_comm_planner.vehicle.airframe import default_airframe
from uav_comm_planner.mission.policy import plan_for_vehicle
from uav_comm_planner.vehicle.geodesy import Home

pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(bool(why_not_runnable()), reason=why_not_runnable())]

HOME = Home(-35.363262, 149.165237, 584.0)
#: ArduCopter SITL's wind for the windy case: 5 m/s from the north-east, no turbulence (the
#: energy is compared, not the tracking), told to the planner.
WIND = {'SIM_WIND_SPD': 5.0, 'SIM_WIND_DIR': 45.0, 'SIM_WIND_TURB': 0.0}


def held_out(seed: int, horizon_s: float = 300.0) -> Scenario:
    """Six nodes of a seed the airframe never saw, in slots of 4 s."""
    return random_six_nodes(seed).replace(horizon_s=horizon_s, num_slots=int(horizon_s / 4))


CASES = {
    'still air, six nodes (seed 7)': (held_out(7), {}),
    'told a 5 m/s wind, six nodes (seed 8)': (
        held_out(8, 400.0).replace(wind_speed_mps=WIND['SIM_WIND_SPD'],
                                   wind_from_deg=WIND['SIM_WIND_DIR']), WIND),
}


@pytest.fixture(scope='module', params=list(CASES))
def flight(request, tmp_path_factory):
    scenario, parameters = CASES[request.param]
    airframe = default_airframe('ardupilot')
    assert airframe is not None, 'the ArduCopter SITL quad ships with the package'
    vehicle_plan = plan_for_vehicle(scenario.replace(airframe=airframe))
    flown = fly_plan(vehicle_plan, tmp_path_factory.mktemp('sitl'), home=HOME,
                     parameters=parameters)
    planned = vehicle_plan.flown
    figures = energy_figures(planned)
    duration_s = planned.scenario.slot_s * (planned.scenario.num_slots + 1)
    # The plan's clock started arrival_s before qF was reached.
    end_s = max(flown.record.reached.values())
    used_j = flown.record.energy_between_j(end_s - flown.arrival_s, end_s)
    print(f'\n{request.param}: battery {used_j / 3600:.3f} Wh over {flown.arrival_s:.1f} s '
          f'({used_j / flown.arrival_s:.1f} W); planned {figures.horizon_j / 3600:.3f} Wh over '
          f'{duration_s:g} s ({figures.horizon_j / duration_s:.1f} W); '
          f'{flown.report.summary()}')
    return figures, duration_s, used_j, flown.arrival_s


def test_the_battery_uses_what_the_plan_states(flight):
    figures, _, used_j, _ = flight
    assert abs(used_j - figures.horizon_j) <= 0.05 * figures.horizon_j


def test_the_mean_power_flown_is_the_planned_mean_power(flight):
    figures, duration_s, used_j, arrival_s = flight
    planned_w, flown_w = figures.horizon_j / duration_s, used_j / arrival_s
    assert abs(flown_w - planned_w) <= 0.02 * planned_w
