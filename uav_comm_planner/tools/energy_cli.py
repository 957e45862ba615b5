"""The command line's energy options: the airframe, an energy budget, the battery, and the
least-energy plan for a throughput target (``uav-comm-planner plan --airframe ...``)."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
import functools

from uav_comm_planner.core.energy import Battery, DEFAULT_RESERVE
from uav_comm_planner.core.least_energy import least_energy_plan
from uav_comm_planner.core.optimizer import plan, PlanResult
from uav_comm_planner.core.propulsion import Airframe
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.mission.energy import energy_lines, mission_airframe, with_energy
from uav_comm_planner.mission.energy import energy_record as mission_energy_record
from uav_comm_planner.vehicle.airframe import airframe_named, airframe_names


def add_airframe_argument(parser) -> None:
    """``--airframe NAME|FILE.yaml`` on ``parser`` (or an argument group)."""
    parser.add_argument('--airframe', metavar='NAME|FILE.yaml',
                        help=f'propulsion model: one of {", ".join(airframe_names())}, or a '
                             'YAML file (its top airspeed also bounds the airspeed)')


def add_energy_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group(
        'energy', "the vehicle's propulsion energy (Zeng 2019's rotary-wing model, "
        'docs/energy.md): stated with --airframe, kept within a budget or a battery')
    add_airframe_argument(group)
    group.add_argument('--energy-budget-wh', type=float, metavar='WH',
                       help="cap on the horizon's propulsion energy q0 -> qF, Wh")
    group.add_argument('--battery-wh', type=float, metavar='WH',
                       help='usable battery energy, Wh: the horizon gets what remains after '
                            'the reserve, takeoff and landing')
    group.add_argument('--battery-reserve', type=float, default=DEFAULT_RESERVE, metavar='SHARE',
                       help=f'share of the battery kept at landing (default {DEFAULT_RESERVE:g})')
    group.add_argument('--min-throughput', type=float, metavar='BPS',
                       help='plan the least propulsion energy such that every node gets at '
                            'least BPS bit/s (instead of the most throughput)')


@dataclass(frozen=True)
class EnergyRequest:
    """What the energy options ask: the airframe, the battery (None: not given), the cap on
    the horizon's energy (None: none) and the throughput target (None: max-min)."""

    airframe: Airframe
    battery: Battery | None
    budget_wh: float | None
    target_bps: float | None


def energy_request(args: argparse.Namespace, scenario: Scenario, *, firmware: str | None = None
                   ) -> tuple[Scenario, EnergyRequest | None]:
    """The scenario with the airframe and the energy cap the options ask for, and the request;
    refuses (typed error, before any planning) a battery that cannot fly the horizon. Without
    ``--airframe``, a mission for ``firmware`` (None: not a mission) is planned with that
    firmware's default airframe, if it has one."""
    asked = [flag for flag, value in (('--energy-budget-wh', args.energy_budget_wh),
                                      ('--battery-wh', args.battery_wh),
                                      ('--min-throughput', args.min_throughput))
             if value is not None]
    if args.airframe is not None:
        airframe = airframe_named(args.airframe)
    elif asked:
        raise InvalidScenarioError(f'{asked[0]} needs --airframe (the propulsion model): '
                                   f'one of {", ".join(airframe_names())} or a YAML file')
    else:
        airframe = mission_airframe(scenario, firmware)
        if airframe is None:
            return scenario, None
    battery = None if args.battery_wh is None else Battery(args.battery_wh,
                                                           args.battery_reserve)
    scenario = with_energy(scenario, airframe, budget_wh=args.energy_budget_wh,
                           battery=battery)
    return scenario, EnergyRequest(airframe, battery, scenario.energy_budget_wh,
                                   args.min_throughput)


def planner_for(request: EnergyRequest | None):
    """The planner the request asks for: the least-energy plan for a throughput target, else
    the core's max-min plan."""
    if request is None or request.target_bps is None:
        return plan
    return functools.partial(least_energy_plan, target_bps=request.target_bps)


def format_energy(result: PlanResult, request: EnergyRequest) -> str:
    """The energy lines under the plan's table (:func:`~uav_comm_planner.mission.energy.
    energy_lines`)."""
    return '\n'.join(energy_lines(result, request.battery))


def energy_record(result: PlanResult, request: EnergyRequest | None) -> dict:
    """The JSON result's energy keys (none without an airframe), with the target if any."""
    if request is None:
        return {}
    record = mission_energy_record(result, request.battery)
    if request.target_bps is not None:
        record['min_throughput_target'] = request.target_bps
    return record


__all__ = ['add_airframe_argument', 'add_energy_arguments', 'energy_record', 'energy_request',
           'EnergyRequest', 'format_energy', 'planner_for']
