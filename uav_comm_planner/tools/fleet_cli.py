"""``uav-comm-planner plan --uavs K``: a fleet's plan on the command line.

``--start "X,Y;X,Y" --goal "X,Y;X,Y"`` give each UAV's ends, ``--min-separation M`` d_min
(default :data:`~uav_comm_planner.core.fleet.scenario.DEFAULT_SEPARATION_M`, 100 m); the
other scenario flags (nodes, speed, horizon, budget...) are every UAV's. The JSON result holds
``trajectories`` (K x M x 2, metres) and ``power`` (K x N x M, watts) beside ``min_throughput``
and ``rates``; ``--mission m.waypoints`` writes one mission per vehicle, ``m_uav1.waypoints``,
``m_uav2.waypoints``, ...; ``--figure`` draws every UAV. ``--fence`` and the energy options
(``--airframe``, ``--energy-budget-wh``, ``--battery-wh``) are every UAV's: each keeps out of
the zones and within its own budget. Every check (the flags, the fleet, the
output paths, every vehicle's mission rows, the JSON text) passes before the first file is
written.
"""

from __future__ import annotations

import argparse
from typing import Callable

from uav_comm_planner.core.energy import horizon_energy_j, JOULES_PER_WH
from uav_comm_planner.core.fleet import FleetScenario, FleetSettings, plan_fleet
from uav_comm_planner.core.fleet.model import closest_approach_m
from uav_comm_planner.core.fleet.planner import FleetPlan
from uav_comm_planner.core.fleet.scenario import (DEFAULT_SEPARATION_M, ends_too_close,
                                                  MAX_UAVS)
from uav_comm_planner.core.fleet.shared_band import (check_shared_band, plan_shared_band,
                                                     SharedBandPlan)
from uav_comm_planner.core.model import flown_path
from uav_comm_planner.core.numbers import counted
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.errors import InvalidScenarioError, PlannerError
from uav_comm_planner.files import write_text_atomic
from uav_comm_planner.mission.fleet import fleet_mission_paths, plan_for_missions, uav_result
from uav_comm_planner.tools.energy_cli import energy_request
from uav_comm_planner.tools.serialize import run_record, scenario_to_dict
from uav_comm_planner.vehicle.fence import read_zones
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.limits import VehicleLimits

#: Flags of the single-UAV plan that a fleet's plan does not take, by their dest.
SINGLE_ONLY = {'vehicle': '--vehicle', 'min_throughput': '--min-throughput',
               'letter': '--letter'}


def _uav_count(text: str) -> int:
    try:
        count = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a whole number of UAVs, got {text!r}')
    if not 1 <= count <= MAX_UAVS:
        raise argparse.ArgumentTypeError(f'expected 1 to {MAX_UAVS} UAVs, got {count}')
    return count


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--uavs`` and ``--min-separation`` on the plan command's parser."""
    group = parser.add_argument_group(
        'fleet', 'several UAVs planned together on orthogonal channels (docs/fleet.md): each '
        "its own band B and budget P_T, a node's throughput the sum over the UAVs")
    group.add_argument('--uavs', type=_uav_count, metavar='K',
                       help='plan K UAVs jointly; --start and --goal then give K points '
                            '"X,Y;X,Y;..."')
    group.add_argument('--min-separation', type=float, metavar='M',
                       help='least distance between any two UAVs in every slot, metres '
                            f'(with --uavs; default {DEFAULT_SEPARATION_M:g}, Wu 2018\'s d_min; '
                            '0 lets them meet)')
    group.add_argument('--shared-band', action='store_true',
                       help="Wu 2018's model instead: one band B for all UAVs, each serving one "
                            'node per slot, the others interfering (with --uavs; --json and '
                            '--figure)')
    group.add_argument('--no-power-control', action='store_true',
                       help='with --shared-band: every UAV sends P_T / M in every slot')


def fleet_request(args: argparse.Namespace, base: Scenario, home: Home) -> FleetScenario:
    """The fleet the flags describe, over ``base`` (the other flags' scenario) with the
    fence's zones (anchored at ``home``) and the energy options, every UAV's; refuses
    (PlannerError) a count of ends other than K and the flags a fleet does not take."""
    given = [flag for dest, flag in SINGLE_ONLY.items() if getattr(args, dest, None)]
    if given:
        raise PlannerError(f'{given[0]} is for one UAV; --uavs plans a fleet on the '
                           f"letter's model per UAV (docs/fleet.md)")
    count = args.uavs
    for name in ('start', 'goal'):
        ends = getattr(args, name)
        if ends is None or len(ends) != count:
            got = 'none' if ends is None else len(ends)
            raise PlannerError(f'--uavs {count} needs {count} points in --{name} "X,Y;X,Y;...", '
                               f'got {got}')
    if getattr(args, 'fence', None) is not None:
        base = base.replace(zones=read_zones(args.fence, home, margin_m=args.fence_margin))
    base, _ = energy_request(args, base)
    if args.min_separation is None:
        close = ends_too_close(args.start, args.goal, DEFAULT_SEPARATION_M)
        if close:
            raise PlannerError(f'{close} (the default d_min): move them apart or give a '
                               f'smaller --min-separation')
        return FleetScenario(base, tuple(args.start), tuple(args.goal))
    return FleetScenario(base, tuple(args.start), tuple(args.goal), args.min_separation)


def vehicle_figures(result: FleetPlan) -> dict:
    """Each UAV's horizon energy and budget (Wh, with an airframe) and its path's least
    clearance from the zones (metres, with zones), None where the scenario has none."""
    energy, budgets, clearance = [], [], []
    for k, vehicle in enumerate(result.fleet.vehicles):
        q = result.trajectories[k]
        if vehicle.airframe is not None:
            energy.append(horizon_energy_j(q, vehicle, vehicle.airframe) / JOULES_PER_WH)
            budgets.append(vehicle.energy_budget_wh)
        if vehicle.zones is not None and not vehicle.zones.empty:
            clearance.append(vehicle.zones.path_clearance(flown_path(q, vehicle)))
    return {'energy_wh': energy or None,
            'energy_budget_wh': budgets if any(b is not None for b in budgets) else None,
            'zone_clearance_m': clearance or None}


def fleet_to_dict(result: FleetPlan, settings: FleetSettings,
                  required_separation_m: float | None = None) -> dict:
    """The JSON result: trajectories (K x M x 2, metres), power (K x N x M, watts), times,
    rates (N, bit/s, summed over the UAVs), min_throughput, and how it was reached;
    min_separation_m is d_min as asked (``required_separation_m``, default the plan's),
    planned_separation_m what the plan keeps at its slots (more when the missions needed it)."""
    fleet = result.fleet
    return {
        'uavs': fleet.num_uavs,
        'trajectories': result.trajectories.tolist(),
        'times': result.times.tolist(),
        'power': result.power.tolist(),
        'rates': result.rates.tolist(),
        'min_throughput': result.min_throughput,
        'starts_m': [list(point) for point in fleet.starts_m],
        'goals_m': [list(point) for point in fleet.goals_m],
        'min_separation_m': (fleet.min_separation_m if required_separation_m is None
                             else required_separation_m),
        'planned_separation_m': fleet.min_separation_m,
        'closest_approach_m': (closest_approach_m(result.trajectories)
                               if fleet.num_uavs > 1 else None),
        'single_uav_throughputs': dict(result.single_throughputs),
        'start': result.start,
        'start_throughputs': dict(result.start_throughputs),
        'left_out': dict(result.left_out),
        'history': [{'step': s.kind, 'min_throughput': s.min_throughput}
                    for s in result.history],
        'status': result.status,
        'solve_time_s': result.solve_time_s,
        'scenario': scenario_to_dict(fleet.scenario),
        **vehicle_figures(result),
        'power_method': settings.power_method,
        **run_record(settings.single),
    }


def format_fleet(result: FleetPlan) -> str:
    """The fleet's table: its min throughput against each UAV's single-UAV plan."""
    fleet, scenario = result.fleet, result.fleet.scenario
    lines = [f'K = {counted(fleet.num_uavs, "UAV")}, N = '
             f'{counted(scenario.num_nodes, "node")}, M = {scenario.num_slots} slots of '
             f'{scenario.slot_s:g} s, P_T = {scenario.power_budget_w:g} W per UAV, '
             f'H = {scenario.altitude_m:g} m, V = {scenario.max_speed_mps:g} m/s, '
             f'd_min = {fleet.min_separation_m:g} m',
             f'{"method":<42}{"min avg throughput (bit/s)":>28}',
             f'{"fleet (joint power and trajectories)":<42}{result.min_throughput:>28.4f}']
    lines += [f'{"UAV " + name.split()[1] + " alone (single-UAV plan)":<42}{value:>28.4f}'
              for name, value in result.single_throughputs.items()]
    closest = (f', closest approach {closest_approach_m(result.trajectories):.1f} m'
               if fleet.num_uavs > 1 else '')
    lines.append(f'{result.outer_iterations} power steps, {result.trajectory_steps} trajectory '
                 f'steps, {result.status}, start: {result.start}{closest}, plan time '
                 f'{result.solve_time_s:.2f} s')
    lines += [f'start {name!r} left out: {why}' for name, why in result.left_out.items()]
    figures = vehicle_figures(result)
    budgets = figures['energy_budget_wh'] or [None] * fleet.num_uavs
    for k, (energy, budget) in enumerate(zip(figures['energy_wh'] or (), budgets)):
        lines.append(f'UAV {k + 1} horizon energy {energy:.4g} Wh'
                     + ('' if budget is None else f' (budget {budget:.4g} Wh)'))
    if figures['zone_clearance_m'] is not None:
        lines.append('least clearance from the zones: ' + ', '.join(
            f'UAV {k + 1} {c:.2f} m' for k, c in enumerate(figures['zone_clearance_m']))
            + f' (margin {fleet.scenario.zones.margin_m:g} m)')
    return '\n'.join(lines)


def shared_band_to_dict(result: SharedBandPlan, settings: FleetSettings) -> dict:
    """The shared band's JSON result: trajectories (K x M x 2, metres), power (K x M, watts:
    one per UAV and slot), schedule (K x N x M, the share of each slot UAV k gives node n),
    rates (N, bit/s) and min_throughput (bit/s), B times Wu's bit/s/Hz."""
    fleet = result.fleet
    bandwidth = fleet.scenario.bandwidth_hz
    return {
        'model': 'shared band',
        'power_control': result.power_control,
        'uavs': fleet.num_uavs,
        'trajectories': result.trajectories.tolist(),
        'times': fleet.scenario.times_s.tolist(),
        'power': result.power.tolist(),
        'schedule': result.schedule.tolist(),
        'rates': (bandwidth * result.throughputs).tolist(),
        'min_throughput': bandwidth * result.min_throughput,
        'starts_m': [list(point) for point in fleet.starts_m],
        'goals_m': [list(point) for point in fleet.goals_m],
        'min_separation_m': fleet.min_separation_m,
        'closest_approach_m': (closest_approach_m(result.trajectories)
                               if fleet.num_uavs > 1 else None),
        'history': [{'step': kind, 'min_throughput': bandwidth * value}
                    for kind, value in result.history],
        'scenario': scenario_to_dict(fleet.scenario),
        **run_record(settings.single),
    }


def plan_shared(fleet: FleetScenario, settings: FleetSettings, *,
                power_control: bool) -> tuple[SharedBandPlan, list[str]]:
    """Wu's shared band from the orthogonal fleet's trajectories, without power control, then
    (``power_control``) with it from there; the plan and its table's lines."""
    check_shared_band(fleet)
    start = plan_fleet(fleet, settings)
    without = plan_shared_band(fleet, start.trajectories, power_control=False)
    result = (plan_shared_band(fleet, without.trajectories, power=without.power)
              if power_control else without)
    bandwidth = fleet.scenario.bandwidth_hz
    rows = [('shared band, power control', result.min_throughput)] if power_control else []
    rows.append(('shared band, no power control', without.min_throughput))
    lines = [f'{"method":<42}{"min avg throughput (bit/s)":>28}']
    lines += [f'{label:<42}{bandwidth * value:>28.4f}' for label, value in rows]
    closest = (f', closest approach {closest_approach_m(result.trajectories):.1f} m'
               if fleet.num_uavs > 1 else '')
    lines.append(f'{len(result.history)} blocks (schedule, power, trajectories){closest}')
    return result, lines


def command(args: argparse.Namespace, base: Scenario, single: SolverSettings, *,
            limits: VehicleLimits, home: Home, json_text: Callable[[object], str]) -> int:
    """Plan the fleet, print its table, write what was asked; 0 on success."""
    from uav_comm_planner.vehicle.mavlink.files import check_mission_path, write_mission_file
    from uav_comm_planner.vehicle.mavlink.items import build_mission_items
    if args.no_power_control and not args.shared_band:
        raise PlannerError('--no-power-control is for --shared-band (on orthogonal channels '
                           'the power step is the plan)')
    fleet = fleet_request(args, base, home)
    missions = (fleet_mission_paths(args.mission, fleet.num_uavs)
                if args.mission is not None else [])
    for path in missions:
        check_mission_path(path)
    settings = FleetSettings(single=single)
    if args.shared_band:
        if missions:
            raise PlannerError('--shared-band writes --json and --figure; its missions are '
                               'not exported yet')
        shared, lines = plan_shared(fleet, settings, power_control=not args.no_power_control)
        print(f'K = {counted(fleet.num_uavs, "UAV")} on one shared band, N = '
              f'{counted(fleet.scenario.num_nodes, "node")}, d_min = '
              f'{fleet.min_separation_m:g} m\n' + '\n'.join(lines))
        text = (json_text(shared_band_to_dict(shared, settings)) if args.json is not None
                else None)
        if text is not None:
            print(f'wrote {write_text_atomic(args.json, text)}')
        if args.figure is not None:
            from uav_comm_planner.tools.fleet_plots import fleet_figure
            print(f'wrote {fleet_figure(shared, args.figure)}')
        return 0
    if missions:
        result, apart = plan_for_missions(fleet, settings, limits, args.firmware)
    else:
        result, apart = plan_fleet(fleet, settings), None
    print(format_fleet(result))
    if apart is not None:
        print(apart)
    text = (json_text(fleet_to_dict(result, settings, fleet.min_separation_m))
            if args.json is not None else None)
    items = [build_mission_items(uav_result(result, k), home, end=args.mission_end,
                                 firmware=args.firmware, limits=limits)
             for k in range(len(missions))]
    if text is not None:
        print(f'wrote {write_text_atomic(args.json, text)}')
    if args.figure is not None:
        from uav_comm_planner.tools.fleet_plots import fleet_figure
        print(f'wrote {fleet_figure(result, args.figure)}')
    for path, vehicle_items in zip(missions, items):
        print(f'wrote {write_mission_file(vehicle_items, path, home, firmware=args.firmware)}')
    return 0


def check_not_fleet(args: argparse.Namespace) -> None:
    """Without --uavs: refuse the fleet's flags (PlannerError)."""
    for flag, given in (('--min-separation', args.min_separation is not None),
                        ('--shared-band', args.shared_band)):
        if given:
            raise InvalidScenarioError(f'{flag} needs --uavs K (a fleet)')


__all__ = ['add_arguments', 'check_not_fleet', 'command', 'fleet_request', 'fleet_to_dict',
           'format_fleet', 'plan_shared', 'shared_band_to_dict', 'vehicle_figures']
