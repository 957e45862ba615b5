"""The command line's energy options: the airframe, an energy budget, the battery, and the
least-energy plan for a throughput target (``uav-comm-planner plan --airframe ...``)."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
import functools

from uav_comm_planner.core.energy import (Battery, DEFAULT_RESERVE, horizon_allowance_wh,
                                          JOULES_PER_WH, leg_powers, least_horizon_energy_j,
                                          takeoff_landing_j)
from uav_comm_planner.core.least_energy import least_energy_plan
from uav_comm_planner.core.optimizer import plan, PlanResult
from uav_comm_planner.core.propulsion import Airframe
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.errors import InfeasibleHorizonError, InvalidScenarioError
from uav_comm_planner.vehicle.airframe import airframe_named, airframe_names

#: ArduCopter's default battery: BATT_CAPACITY 3300 mAh at SITL's 12.6 V.
DEFAULT_BATTERY_WH = 3.3 * 12.6


def add_energy_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group(
        'energy', "the vehicle's propulsion energy (Zeng 2019's rotary-wing model, "
        'docs/energy.md): stated with --airframe, kept within a budget or a battery')
    group.add_argument('--airframe', metavar='NAME|FILE.yaml',
                       help=f'propulsion model: one of {", ".join(airframe_names())}, or a '
                            'YAML file (its top airspeed also bounds the airspeed)')
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


def energy_request(args: argparse.Namespace, scenario: Scenario
                   ) -> tuple[Scenario, EnergyRequest | None]:
    """The scenario with the airframe and the energy cap the options ask for, and the request;
    refuses (typed error, before any planning) a battery that cannot fly the horizon."""
    asked = [flag for flag, value in (('--energy-budget-wh', args.energy_budget_wh),
                                      ('--battery-wh', args.battery_wh),
                                      ('--min-throughput', args.min_throughput))
             if value is not None]
    if args.airframe is None:
        if asked:
            raise InvalidScenarioError(f'{asked[0]} needs --airframe (the propulsion model): '
                                       f'one of {", ".join(airframe_names())} or a YAML file')
        return scenario, None
    airframe = airframe_named(args.airframe)
    battery = None if args.battery_wh is None else Battery(args.battery_wh,
                                                           args.battery_reserve)
    scenario = scenario.replace(airframe=airframe)
    caps = [value for value in (args.energy_budget_wh,) if value is not None]
    if battery is not None:
        allowance = horizon_allowance_wh(battery, airframe, scenario.altitude_m)
        least = least_horizon_energy_j(scenario, airframe) / JOULES_PER_WH
        if allowance <= least:
            up, down = takeoff_landing_j(airframe, scenario.altitude_m)
            raise InfeasibleHorizonError(
                f'the battery cannot fly this mission: it needs at least '
                f'{least + (up + down) / JOULES_PER_WH:.4g} Wh (takeoff {up / JOULES_PER_WH:.3g}, '
                f'the horizon at least {least:.4g}, landing {down / JOULES_PER_WH:.3g}) and '
                f'{battery.available_wh:.4g} Wh are available ({battery.usable_wh:g} Wh less '
                f'the {battery.reserve:.0%} reserve); give a larger --battery-wh, a shorter '
                f'--horizon or a lower --altitude')
        caps.append(allowance)
    budget = min(caps) if caps else None
    if budget is not None:
        scenario = scenario.replace(energy_budget_wh=budget)
    return scenario, EnergyRequest(airframe, battery, budget, args.min_throughput)


def planner_for(request: EnergyRequest | None):
    """The planner the request asks for: the least-energy plan for a throughput target, else
    the core's max-min plan."""
    if request is None or request.target_bps is None:
        return plan
    return functools.partial(least_energy_plan, target_bps=request.target_bps)


@dataclass(frozen=True)
class EnergyFigures:
    """A plan's propulsion energy: per leg (W), the horizon's, takeoff and landing (J)."""

    leg_powers_w: list[float]
    horizon_j: float
    takeoff_j: float
    landing_j: float

    @property
    def mission_j(self) -> float:
        return self.takeoff_j + self.horizon_j + self.landing_j


def energy_figures(result: PlanResult, airframe: Airframe) -> EnergyFigures:
    scenario = result.scenario
    powers = leg_powers(result.trajectory, scenario, airframe)
    up, down = takeoff_landing_j(airframe, scenario.altitude_m)
    return EnergyFigures(powers.tolist(), float(powers.sum() * scenario.slot_s), up, down)


def format_energy(result: PlanResult, request: EnergyRequest) -> str:
    """The energy lines under the plan's table: the plan's energy, and whether the battery
    (the one given, else ArduCopter's default) flies it."""
    figures = energy_figures(result, request.airframe)
    scenario = result.scenario
    duration = (scenario.num_slots + 1) * scenario.slot_s
    lines = [f'propulsion ({request.airframe.name}): horizon {figures.horizon_j / 3600:.2f} Wh, '
             f'mean {figures.horizon_j / duration:.1f} W over {duration:g} s; takeoff '
             f'{figures.takeoff_j / 3600:.2f} Wh, landing {figures.landing_j / 3600:.2f} Wh; '
             f'mission {figures.mission_j / 3600:.2f} Wh'
             + (f' (horizon budget {request.budget_wh:.2f} Wh)'
                if request.budget_wh is not None else '')]
    battery = request.battery or Battery(DEFAULT_BATTERY_WH)
    name = ('battery' if request.battery is not None
            else "ArduCopter's default battery (3300 mAh at 12.6 V)")
    spare = battery.available_wh - figures.mission_j / 3600
    verdict = (f'flies it with {spare:.2f} Wh to spare' if spare >= 0
               else f'does not fly it: {-spare:.2f} Wh short')
    lines.append(f'{name}: {battery.usable_wh:.2f} Wh, {battery.available_wh:.2f} Wh available '
                 f'with the {battery.reserve:.0%} reserve: {verdict}')
    return '\n'.join(lines)


def energy_record(result: PlanResult, request: EnergyRequest | None) -> dict:
    """The JSON result's energy keys (none without an airframe)."""
    if request is None:
        return {}
    figures = energy_figures(result, request.airframe)
    record = {'propulsion_energy_j': figures.horizon_j,
              'propulsion_power_w': figures.leg_powers_w,
              'takeoff_energy_j': figures.takeoff_j, 'landing_energy_j': figures.landing_j,
              'mission_energy_j': figures.mission_j}
    if request.battery is not None:
        record['battery'] = {'usable_wh': request.battery.usable_wh,
                             'reserve': request.battery.reserve,
                             'available_wh': request.battery.available_wh}
    if request.target_bps is not None:
        record['min_throughput_target'] = request.target_bps
    return record


__all__ = ['add_energy_arguments', 'DEFAULT_BATTERY_WH', 'energy_figures', 'energy_record',
           'energy_request', 'EnergyRequest', 'format_energy', 'planner_for']
