"""Flights for the benchmark: vehicle-aware plans flown on ArduCopter SITL, stated vs flown.

Each case is planned for the vehicle's limits, uploaded to a fresh ArduCopter SITL whose
parameters match those limits, flown in AUTO and held against its plan
(:func:`uav_comm_planner.vehicle.evaluation.evaluate_flight`): how late the planned points
were reached, how far the track strayed from the planned line, and the throughput the plan's
power gives at the positions flown against the throughput the plan states.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
import tempfile

import numpy as np

from devtools.sitl import fly_plan, SitlFlight
from uav_comm_planner.core.scenario import paper_scenario, Scenario
from uav_comm_planner.mission.policy import plan_for_vehicle
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.limits import VehicleLimits

#: ArduPilot's SITL home (Canberra model airfield).
SITL_HOME = Home(-35.363262, 149.165237, 584.0)


@dataclass(frozen=True)
class FlightCase:
    """A scenario, the vehicle's limits, and the autopilot parameters that give them."""

    name: str
    scenario: Scenario
    limits: VehicleLimits
    parameters: dict[str, float]


def random_six_nodes(seed: int = 1) -> Scenario:
    """Six nodes uniform in a 1500 m x 800 m field, flown from (0, 0) to (1500, 0) at 10 m/s."""
    rng = np.random.default_rng(seed)
    nodes = np.column_stack([rng.uniform(0, 1500, 6), rng.uniform(-400, 400, 6)])
    return Scenario(ground_nodes_m=tuple(map(tuple, nodes)), start_m=(0.0, 0.0),
                    goal_m=(1500.0, 0.0), max_speed_mps=10.0, horizon_s=400.0, num_slots=100)


#: Wind flights: ArduCopter SITL's SIM_WIND_* and the same wind told to the planner, for the
#: letter's case I at 10 m/s over 800 s (a 6 m/s headwind leaves 3 m/s over the ground).
WIND_HORIZON_S, WIND_SLOTS = 800.0, 200
WIND_TURBULENCE_MPS = 2.0


def wind_case(speed_mps: float, from_deg: float, *, told: bool = True) -> FlightCase:
    """Case I in a wind of ``speed_mps`` from ``from_deg`` (SIM_WIND_SPD, SIM_WIND_DIR,
    SIM_WIND_TURB 2 m/s), planned for it (``told``) or for still air."""
    scenario = paper_scenario('I', max_speed_mps=10.0, horizon_s=WIND_HORIZON_S,
                              num_slots=WIND_SLOTS)
    if told:
        scenario = scenario.replace(
            wind_speed_mps=speed_mps, wind_from_deg=from_deg,
            max_airspeed_mps=VehicleLimits().airspeed_for_wind_mps(speed_mps))
    name = f'case I, wind {speed_mps:g} from {from_deg:g}' + ('' if told else ', not told')
    return FlightCase(name, scenario, VehicleLimits(),
                      {'SIM_WIND_SPD': speed_mps, 'SIM_WIND_DIR': from_deg,
                       'SIM_WIND_TURB': WIND_TURBULENCE_MPS if speed_mps else 0.0})


def flight_cases(quick: bool = False) -> list[FlightCase]:
    case_one = paper_scenario('I', max_speed_mps=10.0, horizon_s=400.0, num_slots=100)
    cases = [FlightCase('case I, 10 m/s, defaults', case_one, VehicleLimits(), {})]
    if quick:
        return cases
    tuned = VehicleLimits(max_speed_mps=12.0, max_accel_mpss=5.0, max_jerk_mpsss=5.0)
    return cases + [
        FlightCase('six random nodes, defaults', random_six_nodes(), VehicleLimits(), {}),
        FlightCase('case I, 12 m/s, tuned', case_one.replace(max_speed_mps=12.0), tuned,
                   {'WPNAV_SPEED': 1200, 'WPNAV_ACCEL': 500, 'WPNAV_JERK': 5,
                    'ANGLE_MAX': 4500}),
        wind_case(6.0, 90.0),
        wind_case(6.0, 0.0),
    ]


def fly_case(case: FlightCase, binary=None) -> tuple[float, SitlFlight]:
    """Plan ``case`` for its vehicle and fly it; returns (ideal plan's value, the flight)."""
    vehicle_plan = plan_for_vehicle(case.scenario, case.limits)
    with tempfile.TemporaryDirectory(prefix='uav_comm_planner_sitl_') as folder:
        flight = fly_plan(vehicle_plan, Path(folder),
                          home=SITL_HOME, parameters=case.parameters, binary=binary)
    return vehicle_plan.ideal.min_throughput, flight


def format_flights(rows: list[tuple[FlightCase, float, SitlFlight]]) -> str:
    lines = [f'{"case":<34}{"ideal":>10}{"stated":>10}{"flown":>10}{"flown/stated":>14}'
             f'{"worst":>8}{"median":>8}{"track_m":>9}{"qF_late_s":>11}']
    for case, ideal, flight in rows:
        report, scenario = flight.report, case.scenario
        late = flight.arrival_s - scenario.slot_s * (scenario.num_slots + 1)
        lines.append(f'{case.name:<34}{ideal:>10.4f}{report.stated:>10.4f}{report.flown:>10.4f}'
                     f'{report.flown_to_stated:>14.4%}{report.worst_reach_slots:>8.2f}'
                     f'{report.median_reach_slots:>8.2f}{report.cross_track_m:>9.2f}'
                     f'{late:>11.1f}')
    lines.append('worst, median: how late or early the planned points were reached, in slots; '
                 'track_m: largest distance from the planned line; qF_late_s: arrival at the '
                 'goal after the planned time (negative: early)')
    return '\n'.join(lines)
