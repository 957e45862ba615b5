"""The command line's altitude options: ``plan --altitude-range MIN,MAX [--climb-rate MPS]``
plans the altitude of every slot with the trajectory and the power
(:mod:`uav_comm_planner.core.altitude`), prints the plan against the best fixed altitude and
writes ``altitudes_m`` in the JSON result. With ``--mission`` (or any vehicle option) it is planned
for ArduCopter with its climbs (:mod:`uav_comm_planner.mission.altitude`) and the mission's
waypoints carry their altitudes. Fences, figures, airframes and energy budgets keep one
altitude: asked together with a range, they are refused before planning."""

from __future__ import annotations

import argparse
from typing import Any

from uav_comm_planner.core.altitude import AltitudeLimits, AltitudePlan, plan_with_altitude
from uav_comm_planner.core.altitude_limits import DEFAULT_CLIMB_MPS, limits_of
from uav_comm_planner.core.fading import Fading
from uav_comm_planner.core.numbers import counted
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.mission.altitude import AltitudeVehiclePlan, plan_altitude_for_vehicle
from uav_comm_planner.tools import fading_cli
from uav_comm_planner.tools.serialize import run_record, scenario_to_dict
from uav_comm_planner.vehicle.climbs import ClimbLimits
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink.files import write_mission_file
from uav_comm_planner.vehicle.mavlink.items import build_mission_items

#: Options a plan with altitudes does not combine with (flag, the attribute it sets).
NOT_WITH_ALTITUDE = (('--fence', 'fence'), ('--figure', 'figure'),
                     ('--airframe', 'airframe'), ('--energy-budget-wh', 'energy_budget_wh'),
                     ('--battery-wh', 'battery_wh'), ('--min-throughput', 'min_throughput'))


def _range(text: str) -> tuple[float, float]:
    parts = text.split(',')
    try:
        low, high = (float(part) for part in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f'expected MIN,MAX (metres), got {text!r}') from None
    return low, high


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """--altitude-range and --climb-rate on the plan command."""
    group = parser.add_argument_group(
        'altitude as a variable (docs/channel.md): every slot its own altitude')
    group.add_argument('--altitude-range', type=_range, metavar='MIN,MAX',
                       help='plan each slot\'s altitude within MIN..MAX metres above the nodes '
                            '(q0\'s and qF\'s altitudes free within it); with --channel '
                            'los:* altitude is a trade-off, with free space the lowest wins')
    group.add_argument('--climb-rate', type=float, metavar='MPS',
                       help='fastest climb or descent between slots, m/s (default '
                            f'{DEFAULT_CLIMB_MPS:g}); needs --altitude-range')


def scenario_changes(args: argparse.Namespace, base: Scenario) -> dict[str, Any]:
    """The Scenario fields the altitude flags set over ``base`` (the case, or the scenario
    file): each flag given wins over the file's field, as every scenario flag does. Refuses
    --climb-rate with no range from either (typed error)."""
    changes: dict[str, Any] = {}
    if getattr(args, 'altitude_range', None) is not None:
        changes['altitude_range_m'] = args.altitude_range
    if getattr(args, 'climb_rate', None) is not None:
        if 'altitude_range_m' not in changes and base.altitude_range_m is None:
            raise InvalidScenarioError('--climb-rate needs --altitude-range MIN,MAX (or the '
                                       'scenario field altitude_range_m)')
        changes['max_climb_mps'] = args.climb_rate
    return changes


def refuse_altitudes(scenario: Scenario) -> None:
    """Refuse (typed error) a scenario with altitudes where they are not planned: the
    budget sweeps and the fleet keep one altitude."""
    if scenario.altitude_range_m is not None:
        raise InvalidScenarioError('altitude_range_m is planned by the plan command for one UAV '
                                   'only: remove it (or --altitude-range) here')


def altitude_limits(args: argparse.Namespace, vehicle_aware: bool,
                    scenario: Scenario) -> AltitudeLimits | None:
    """The limits ``scenario`` asks for (None without ``altitude_range_m``, from the scenario
    file or --altitude-range); refuses (typed error) the options a plan with altitudes does
    not take. The climb rate is, unless given (``max_climb_mps``, --climb-rate),
    :data:`DEFAULT_CLIMB_MPS`, or for a ``vehicle_aware`` plan the vehicle's slower vertical
    speed."""
    if scenario.altitude_range_m is None:
        return None
    given = [flag for flag, name in NOT_WITH_ALTITUDE if getattr(args, name, None) is not None]
    if given:
        raise InvalidScenarioError(f'a plan with altitudes (--altitude-range, altitude_range_m) '
                                   f'does not combine with {given[0]}: it keeps the speed '
                                   'limits only')
    return limits_of(scenario, ClimbLimits().slowest_mps if vehicle_aware else DEFAULT_CLIMB_MPS)


def format_altitude_plan(result: AltitudePlan) -> str:
    """The plan against the best fixed altitude, and its altitudes."""
    scenario, heights = result.scenario, result.altitudes
    low, high = result.limits.range_m
    return '\n'.join([
        f'N = {scenario.num_nodes} nodes, M = {scenario.num_slots} slots of '
        f'{scenario.slot_s:g} s, P_T = {scenario.power_budget_w:g} W, altitude {low:g} to '
        f'{high:g} m (climb {result.limits.max_climb_mps:g} m/s), V = '
        f'{scenario.max_speed_mps:g} m/s, channel {scenario.channel}',
        f'{"method":<42}{"min avg throughput (bit/s)":>28}',
        f'{"proposed (altitude planned)":<42}{result.min_throughput:>28.4f}',
        f'{f"best fixed altitude, {result.fixed_altitude_m:.1f} m":<42}'
        f'{result.fixed.min_throughput:>28.4f}',
        f'altitudes {heights.min():.1f} to {heights.max():.1f} m (mean {heights.mean():.1f} m); '
        f'{len(result.history) - 1} steps, '
        f'{"converged" if result.converged else "iteration limit"}, plan time '
        f'{result.solve_time_s:.2f} s'])


def altitude_record(result: AltitudePlan, settings: SolverSettings) -> dict[str, Any]:
    """The JSON result: trajectory, altitudes_m, times, power, rates, min_throughput, history,
    the best fixed altitude and its throughput, the range, the scenario and the settings."""
    return {
        'trajectory': result.trajectory.tolist(),
        'altitudes_m': result.altitudes.tolist(),
        'times': result.times.tolist(),
        'power': result.power.tolist(),
        'rates': result.rates.tolist(),
        'min_throughput': result.min_throughput,
        'history': list(result.history),
        'fixed_altitude_m': result.fixed_altitude_m,
        'fixed_altitude_throughput': result.fixed.min_throughput,
        'altitude_range_m': list(result.limits.range_m),
        'max_climb_mps': result.limits.max_climb_mps,
        'scenario': scenario_to_dict(result.scenario),
        'solve_time_s': result.solve_time_s,
        'status': 'converged' if result.converged else 'iteration limit',
        **run_record(settings),
    }


def run(args: argparse.Namespace, scenario: Scenario, limits: AltitudeLimits,
        settings: SolverSettings, write_json, fading: Fading | None = None, *,
        vehicle: VehicleLimits | None = None, home: Home | None = None) -> int:
    """Plan with altitudes, print it (and its evaluation under ``fading``, if any), and write
    the JSON result with ``write_json(record)`` if --json asks for it. For a ``vehicle``
    (VehicleLimits), plan for it and state the plan as it flies it; with --mission, write
    the mission (its waypoints at their altitudes, for ``home``)."""
    if vehicle is None:
        result = plan_with_altitude(scenario, limits, settings)
        print(format_altitude_plan(result))
        record, flown = altitude_record(result, settings), result
    else:
        flown = plan_altitude_for_vehicle(scenario, limits, vehicle, settings=settings,
                                          firmware=args.firmware)
        result = flown.ideal
        print(format_altitude_plan(result))
        print(format_flown_altitudes(flown))
        record = {**altitude_record(result, settings), **flown_record(flown)}
    evaluation = fading_cli.evaluate(fading, flown.trajectory, flown.power, scenario,
                                     flown.altitudes)
    items = None
    if vehicle is not None and args.mission is not None:
        items = build_mission_items(flown.mission, home, end=args.mission_end,
                                    firmware=args.firmware)
    if args.json is not None:
        write_json({**record, **fading_cli.fading_record(evaluation)})
    if items is not None:
        print(f'wrote {write_mission_file(items, args.mission, home, firmware=args.firmware)}')
    return 0


def format_flown_altitudes(flown: AltitudeVehiclePlan) -> str:
    """The plan as the vehicle flies it, and its mission's timing."""
    schedule = flown.mission.schedule
    scenario = flown.scenario
    kept = (f'the level plan at {flown.altitudes[0]:.1f} m flies better than the plan with '
            f'altitudes ({flown.alternative_throughput:.4f}) and is kept' if flown.level else
            f'the level plan at the best fixed altitude flies {flown.alternative_throughput:.4f}')
    return '\n'.join([
        f'{"as the vehicle flies it (the plan to state)":<42}{flown.min_throughput:>28.4f}',
        kept,
        f'vehicle: climb {flown.climb.up_mps:g} m/s, descent {flown.climb.down_mps:g} m/s; '
        f'{counted(len(schedule.legs), "leg")}, {counted(len(schedule.stops) - 2, "stop")}, '
        f'take-off to {flown.planned_points()[1][0]:.1f} m, qF reached at '
        f'{schedule.arrival_s:.1f} s of {scenario.slot_s * (scenario.num_slots + 1):g}'])


def flown_record(flown: AltitudeVehiclePlan) -> dict[str, Any]:
    """The JSON result's part for the plan as flown: ``flown`` with its trajectory,
    altitudes, power, rates and min throughput, whether the level plan at the best fixed
    altitude was kept, and what the other of the two flies."""
    return {'flown': {'trajectory': flown.trajectory.tolist(),
                      'altitudes_m': flown.altitudes.tolist(), 'power': flown.power.tolist(),
                      'rates': flown.rates.tolist(), 'min_throughput': flown.min_throughput,
                      'arrival_s': flown.mission.schedule.arrival_s, 'level': flown.level,
                      'alternative_throughput': flown.alternative_throughput}}


__all__ = ['add_arguments', 'altitude_limits', 'altitude_record', 'DEFAULT_CLIMB_MPS',
           'format_altitude_plan', 'refuse_altitudes', 'run', 'scenario_changes']
