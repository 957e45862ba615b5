"""Command line: ``uav-comm-planner plan``, ``sweep``, ``upload`` and ``montecarlo``.

Both take the letter's case (``--case I`` or ``II``) or a scenario file, with flags that
override single settings; bad input ends with a one-line error
(``uav-comm-planner: error: ...``, no usage block) and exit status 2. Every check (arguments,
scenario, output paths and formats, finite output) passes before the first file is written.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import math
from pathlib import Path
import sys
from typing import Sequence

from uav_comm_planner.core.channel import FREE_SPACE
from uav_comm_planner.core.numbers import counted
from uav_comm_planner.core.optimizer import plan, PlanResult
from uav_comm_planner.core.scenario import paper_scenario, Scenario, SolverSettings
from uav_comm_planner.core.zones import Zones
from uav_comm_planner.errors import PlannerError
from uav_comm_planner.files import check_output_path, read_json_file, write_text_atomic
from uav_comm_planner.tools import (altitude_cli, altitude_study, energy_sweep, fading_cli,
                                    fit_airframe, fleet_cli)
from uav_comm_planner.tools.arguments import _ends, _floats, _home, _nodes, _wind
from uav_comm_planner.tools.energy_cli import (add_airframe_argument, add_energy_arguments,
                                               energy_record, energy_request, format_energy,
                                               planner_for)
from uav_comm_planner.tools.plots import check_figure_path, make_folder, METHOD_LABELS
from uav_comm_planner.tools.serialize import (package_version, result_to_dict, run_record,
                                              scenario_from_dict, scenario_to_dict,
                                              settings_from_dict)
from uav_comm_planner.tools.study import command as montecarlo
from uav_comm_planner.vehicle.firmware import FIRMWARES
from uav_comm_planner.vehicle.geodesy import default_home
from uav_comm_planner.vehicle.mavlink.items import MISSION_ENDS

#: The budgets of the letter's Fig. 2, watts.
SWEEP_BUDGETS_W = (0.5, 1.0, 2.0, 5.0, 10.0, 20.0)

PROG = 'uav-comm-planner'
#: A scenario file larger than this is refused before it is parsed.
MAX_SCENARIO_FILE_BYTES = 16 * 1024 * 1024
#: A sweep plans once per budget: more budgets than this are refused before the first plan.
MAX_SWEEP_BUDGETS = 1000


class CommandLineError(Exception):
    """A bad argument, found by the parser."""


class OneLineArgumentParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors raise :class:`CommandLineError` instead of printing the
    usage block and exiting; :func:`main` prints them as one line and returns 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise CommandLineError(message)


# Scenario field -> (flag, help) for the single-value overrides.
_SCALAR_FLAGS = {
    'altitude_m': ('--altitude', 'UAV altitude H, metres'),
    'max_speed_mps': ('--speed', 'maximum speed V, m/s'),
    'horizon_s': ('--horizon', 'horizon T, seconds'),
    'num_slots': ('--slots', 'number of slots M'),
    'bandwidth_hz': ('--bandwidth', 'total bandwidth B, Hz'),
    'noise_psd_dbm_per_hz': ('--noise-dbm', 'noise PSD sigma^2, dBm/Hz'),
    'reference_gain': ('--beta0', 'channel gain beta0 at 1 m (linear)'),
    'power_budget_w': ('--budget', 'power budget P_T, watts'),
}


# VehicleLimits field -> (flag, help), over the parameter file.
_VEHICLE_FLAGS = {
    'max_speed_mps': ('--wp-speed', 'waypoint speed, m/s (WPNAV_SPEED / 100; default 10)'),
    'max_accel_mpss': ('--wp-accel', 'waypoint acceleration, m/s/s (WPNAV_ACCEL / 100; 2.5)'),
    'max_jerk_mpsss': ('--wp-jerk', 'waypoint jerk, m/s/s/s (WPNAV_JERK; default 1)'),
    'airframe_speed_mps': ('--airframe-speed',
                           'the top speed the airframe reaches, m/s, if below the waypoint '
                           'speed'),
    'gust_margin_mps': ('--gust-margin',
                        'airspeed kept in reserve for gusts when planning for a wind, m/s '
                        '(default 1)'),
}
#: The vehicle's flags store under this prefix, apart from the planning speed --speed.
_VEHICLE_DEST = 'vehicle_'


def _add_scenario_arguments(parser: argparse.ArgumentParser) -> None:
    source = parser.add_mutually_exclusive_group()
    source.add_argument('--case', default='I', choices=['I', 'II', 'i', 'ii'],
                        help="the letter's case: I ends at (2000, 0), II at (2000, 500)")
    source.add_argument('--scenario', type=Path, metavar='FILE.json',
                        help='scenario file: a JSON object of Scenario fields (a result file '
                             'written by --json also works)')
    parser.add_argument('--nodes', type=_nodes, metavar='X,Y;X,Y;...',
                        help='ground node positions, metres')
    parser.add_argument('--start', type=_ends, metavar='X,Y',
                        help='launch point q0, metres (one per UAV with --uavs: X,Y;X,Y)')
    parser.add_argument('--goal', type=_ends, metavar='X,Y',
                        help='landing point qF, metres (one per UAV with --uavs: X,Y;X,Y)')
    parser.add_argument('--wind', type=_wind, metavar='SPEED,FROM_DEG',
                        help='the wind to plan for: m/s, and the direction it blows from in '
                             'degrees clockwise from north (as weather reports and '
                             'SIM_WIND_DIR give it), e.g. 6,90 for 6 m/s from the east')
    for field, (flag, text) in _SCALAR_FLAGS.items():
        kind = int if field == 'num_slots' else float
        parser.add_argument(flag, dest=field, type=kind, help=text)
    parser.add_argument('--channel', default=None, metavar='NAME',
                        help="air-to-ground channel (docs/channel.md): free-space (the "
                             "letter's, the default), free-space:alpha=A (path-loss exponent "
                             "A), los:suburban, los:urban, los:dense-urban, los:highrise-urban "
                             "(Al-Hourani's line-of-sight probability)")
    parser.add_argument('--tolerance', type=float, default=None,
                        help='absolute convergence tolerance epsilon, bit/s (default 0: the '
                             'relative tolerance 1e-4 alone; --letter uses 0.01)')
    parser.add_argument('--max-nodes', type=int, default=None, help='largest number of nodes')
    parser.add_argument('--max-node-slots', type=int, default=None,
                        help='compute budget: largest N x M, nodes times slots (default '
                             f'{SolverSettings().max_node_slots})')
    parser.add_argument('--letter', action='store_true',
                        help="run the letter's Algorithm 1 exactly: straight-line start only, "
                             'absolute tolerance 0.01 bit/s (default: best of the straight and '
                             'hover-and-fly starts, relative tolerance 1e-4)')


def read_scenario_file(path: Path) -> dict:
    """The JSON object of a scenario file; refuses (PlannerError) a file that is not a regular
    file (a device, pipe or folder, refused without blocking), not UTF-8, not JSON, nested too
    deeply, larger than MAX_SCENARIO_FILE_BYTES or not an object at the top."""
    name = str(path)
    data = read_json_file(path, max_bytes=MAX_SCENARIO_FILE_BYTES, what='scenario file',
                          error=PlannerError)
    if not isinstance(data, dict):
        raise PlannerError(f'scenario file {name!r} must hold a JSON object {{"field": value, '
                           f'...}}, not {type(data).__name__}')
    return data


def _scenario_data(args: argparse.Namespace) -> dict:
    """The scenario file's object, read once per command: the scenario, the settings and the
    budgets all come from the same read, never from a file changed in between."""
    data = getattr(args, '_scenario_data', None)
    if data is None:
        data = read_scenario_file(args.scenario)
        args._scenario_data = data
    return data


def _scenario(args: argparse.Namespace, vehicle=None, altitudes: bool = False) -> Scenario:
    """The scenario the flags describe; planned for ``vehicle`` (VehicleLimits) in wind, its
    airspeed is the vehicle's (the airframe's less the gust margin). Its altitude range (from
    the file or the flags) is refused unless ``altitudes`` (the commands that plan it)."""
    if args.scenario is not None:
        data = _scenario_data(args)
        fields = data['scenario'] if isinstance(data.get('scenario'), dict) else data
        nodes = fields.get('ground_nodes_m')
        if isinstance(nodes, list):
            # The limit before the scenario's own checks, which grow with the nodes.
            _settings(args).check_node_count(len(nodes))
        base = scenario_from_dict(data)
    else:
        base = paper_scenario(args.case)
    changes = {field: getattr(args, field) for field in _SCALAR_FLAGS
               if getattr(args, field) is not None}
    for field, name in (('ground_nodes_m', 'nodes'), ('channel', 'channel')):
        if getattr(args, name) is not None:
            changes[field] = getattr(args, name)
    for field, name in (('start_m', 'start'), ('goal_m', 'goal')):
        ends = getattr(args, name)
        if ends is None:
            continue
        if len(ends) != 1 and getattr(args, 'uavs', None) is None:
            raise PlannerError(f'--{name} takes one point X,Y ({len(ends)} given: several '
                               f'need --uavs K)')
        changes[field] = ends[0]       # a fleet's first UAV's: the shared scenario is valid
    if args.wind is not None:
        changes['wind_speed_mps'], changes['wind_from_deg'] = args.wind
        airspeed = None if vehicle is None else vehicle.airspeed_for_wind_mps(args.wind[0])
        if airspeed is not None:
            changes['max_airspeed_mps'] = airspeed
    changes.update(altitude_cli.scenario_changes(args, base))
    scenario = base.replace(**changes) if changes else base
    if not altitudes:
        altitude_cli.refuse_altitudes(scenario)
    return scenario


def _settings(args: argparse.Namespace) -> SolverSettings:
    changes = {}
    if args.tolerance is not None:
        changes['tolerance_bps'] = args.tolerance
    if args.max_nodes is not None:
        changes['max_nodes'] = args.max_nodes
    if args.max_node_slots is not None:
        changes['max_node_slots'] = args.max_node_slots
    if args.letter:
        return SolverSettings.letter(**changes)
    if args.scenario is not None:
        # A result file records the settings it was made with: run it again with them.
        data = _scenario_data(args)
        if 'settings' in data:
            recorded = data['settings']
            if not isinstance(recorded, dict):
                raise PlannerError(f'settings in {str(args.scenario)!r} must be a JSON object '
                                   f'of solver settings, not {type(recorded).__name__}')
            return settings_from_dict({**recorded, **changes})
    return SolverSettings(**changes)


def format_plan(result: PlanResult) -> str:
    """The short table of one plan: the proposed method against both baselines."""
    scenario = result.scenario
    rows = [(METHOD_LABELS['proposed'], result.min_throughput)]
    rows += [(METHOD_LABELS[key], result.baselines[key]) for key in ('straight', 'static')
             if key in result.baselines]
    rows.append(('upper bound (every channel at its best)', result.upper_bound))
    if math.isfinite(result.tight_upper_bound):
        rows.append(('upper bound (dual over the flyable paths)', result.tight_upper_bound))
    lines = [f'N = {scenario.num_nodes} nodes, M = {scenario.num_slots} slots of '
             f'{scenario.slot_s:g} s, P_T = {scenario.power_budget_w:g} W, '
             f'H = {scenario.altitude_m:g} m, V = {scenario.max_speed_mps:g} m/s'
             + (f', wind {scenario.wind_speed_mps:g} m/s from {scenario.wind_from_deg:g} deg '
                f'(airspeed {scenario.airspeed_mps:g} m/s)' if scenario.wind_speed_mps else '')
             + (f', channel {scenario.channel}' if scenario.channel != FREE_SPACE else ''),
             f'{"method":<42}{"min avg throughput (bit/s)":>28}']
    lines += [f'{label:<42}{value:>28.4f}' for label, value in rows]
    lines.append(f'{result.outer_iterations} power steps, {result.trajectory_steps} trajectory '
                 f'steps, {result.status}, start: {result.start}, '
                 f'plan time {result.solve_time_s:.2f} s'
                 + (f', at most {result.gap_to_tight_bound:.2%} below the optimum'
                    if math.isfinite(result.tight_upper_bound) else ''))
    return '\n'.join(lines)


def _vehicle_limits(args: argparse.Namespace):
    """The vehicle's limits by the one precedence rule
    (:func:`~uav_comm_planner.mission.request.vehicle_limits`): flags over the parameter file
    over ArduCopter's defaults."""
    from uav_comm_planner.mission.request import vehicle_limits
    explicit = {field: getattr(args, _VEHICLE_DEST + field) for field in _VEHICLE_FLAGS
                if getattr(args, _VEHICLE_DEST + field) is not None}
    return vehicle_limits(explicit, args.vehicle_params, firmware=args.firmware)


def _vehicle_asked(args: argparse.Namespace) -> bool:
    return (args.vehicle or args.mission is not None or args.vehicle_params is not None
            or any(getattr(args, _VEHICLE_DEST + field) is not None for field in _VEHICLE_FLAGS))


def format_flown(vehicle_plan) -> str:
    """The vehicle-aware lines under the plan's table."""
    flown, ideal, schedule = vehicle_plan.flown, vehicle_plan.ideal, vehicle_plan.schedule
    limits = vehicle_plan.limits
    end_s = ideal.scenario.slot_s * (ideal.scenario.num_slots + 1)
    lines = [f'{"as the vehicle flies it (the plan to state)":<42}'
             f'{flown.min_throughput:>28.4f}',
             f'vehicle: cruise {limits.describe_cruise()}, acceleration '
             f'{limits.max_accel_mpss:g} m/s/s, jerk {limits.max_jerk_mpsss:g} m/s/s/s; '
             f'{counted(len(schedule.legs), "leg")}, {counted(len(schedule.stops) - 2, "stop")}, '
             f'qF reached at '
             f'{schedule.arrival_s:.1f} s of {end_s:g}']
    return '\n'.join(lines)


def _check_outputs(*paths: Path | None, figure: Path | None = None) -> None:
    """Fail before planning, not after, when an output file cannot be placed or its format
    is unknown: each path must be a regular file (or absent) in a writable folder; a figure's
    folder is made if missing."""
    if figure is not None:
        check_figure_path(figure)
        make_folder(figure.parent)
    for path in (*paths, figure):
        if path is not None:
            check_output_path(path)


def json_text(data: object) -> str:
    """``data`` as indented JSON; refuses (PlannerError) Infinity or NaN, which JSON lacks."""
    try:
        return json.dumps(data, indent=1, allow_nan=False) + '\n'
    except ValueError:
        raise PlannerError('the result holds a non-finite number (Infinity or NaN); nothing '
                           'was written') from None


def _command_fleet(args: argparse.Namespace) -> int:
    """``plan --uavs K`` (:mod:`.fleet_cli`)."""
    missions = ([] if args.mission is None else
                fleet_cli.fleet_mission_paths(args.mission, args.uavs))
    _check_outputs(args.json, *missions, figure=args.figure)
    home = args.home if args.home is not None else default_home(args.firmware)
    return fleet_cli.command(args, _scenario(args), _settings(args),
                             limits=_vehicle_limits(args), home=home, json_text=json_text)


def _command_plan(args: argparse.Namespace) -> int:
    if args.uavs is not None:
        return _command_fleet(args)
    fleet_cli.check_not_fleet(args)
    _check_outputs(args.json, args.mission, figure=args.figure)
    fading = fading_cli.fading_from(args)
    vehicle = _vehicle_limits(args) if _vehicle_asked(args) else None
    scenario = _scenario(args, vehicle, altitudes=True)
    altitudes = altitude_cli.altitude_limits(args, vehicle is not None, scenario)
    if altitudes is not None:
        return altitude_cli.run(args, scenario, altitudes, _settings(args),
                                lambda record: print(
                                    f'wrote {write_text_atomic(args.json, json_text(record))}'),
                                fading, vehicle=vehicle,
                                home=args.home or default_home(args.firmware))
    if args.mission is not None:
        from uav_comm_planner.vehicle.mavlink.files import check_mission_path
        check_mission_path(args.mission)
    from uav_comm_planner.mission.pipeline import plan_mission
    from uav_comm_planner.mission.request import MissionRequest
    vehicle_aware = _vehicle_asked(args)
    limits = _vehicle_limits(args)
    home = args.home if args.home is not None else default_home(args.firmware)
    zones = None
    if args.fence is not None:
        from uav_comm_planner.vehicle.fence import read_zones
        zones = read_zones(args.fence, home, margin_m=args.fence_margin)
    scenario, energy = energy_request(args, _scenario(args, limits if vehicle_aware else None),
                                      firmware=args.firmware if vehicle_aware else None)
    request = MissionRequest(
        scenario, _settings(args), limits,
        vehicle_aware=vehicle_aware, firmware=args.firmware, end=args.mission_end,
        home=home, items=args.mission is not None, zones=zones)
    planned = plan_mission(request, planner=planner_for(energy))
    if vehicle_aware:
        print(format_plan(planned.vehicle_plan.ideal))
        print(format_flown(planned.vehicle_plan))
    else:
        print(format_plan(planned.result))
    result = planned.result
    if energy is not None:
        print(format_energy(result, energy))
    evaluation = fading_cli.evaluate(fading, result.trajectory, result.power, result.scenario)
    # Every check before the first file: the JSON text and the mission's rows.
    text = (json_text({**result_to_dict(result, settings=request.settings,
                                        optimised=planned.optimised),
                       **energy_record(result, energy), **fading_cli.fading_record(evaluation)})
            if args.json is not None else None)
    if args.mission is not None and planned.items is None:
        raise PlannerError(planned.items_error)
    if text is not None:
        print(f'wrote {write_text_atomic(args.json, text)}')
    if args.figure is not None:
        from uav_comm_planner.tools.plots import plan_figure
        print(f'wrote {plan_figure(result, args.figure, as_flown=vehicle_aware)}')
    if args.mission is not None:
        print(f'wrote {planned.write(args.mission)}')
    return 0


def _sweep_budgets(args: argparse.Namespace) -> list[float]:
    """--budgets, else the budgets of a sweep file given as --scenario, else the letter's."""
    if args.budgets is not None:
        return args.budgets
    if args.scenario is not None:
        recorded = _scenario_data(args).get('budgets_w')
        if recorded is not None:
            if isinstance(recorded, list) and len(recorded) > MAX_SWEEP_BUDGETS:
                raise PlannerError(f'budgets_w in {str(args.scenario)!r} holds '
                                   f'{len(recorded)} budgets, more than {MAX_SWEEP_BUDGETS}')
            try:
                if not isinstance(recorded, list) or not recorded or any(
                        isinstance(v, (bool, str)) for v in recorded):
                    raise TypeError
                return [float(v) for v in recorded]
            except (TypeError, ValueError, OverflowError):
                raise PlannerError(f'budgets_w in {str(args.scenario)!r} must be a list of '
                                   f'numbers, at least one, got {_short(recorded)}') from None
    return list(SWEEP_BUDGETS_W)


def _short(value: object, limit: int = 80) -> str:
    """``repr(value)`` cut to ``limit`` characters, for a one-line error about a file's
    content."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit] + '...'


def _check_budget_count(budgets: Sequence[float]) -> None:
    if len(budgets) > MAX_SWEEP_BUDGETS:
        raise PlannerError(f'{len(budgets)} budgets given, more than {MAX_SWEEP_BUDGETS}: a '
                           f'sweep plans once per budget')


def _command_sweep(args: argparse.Namespace) -> int:
    _check_outputs(args.json, figure=args.figure)
    # The sweep's table is the proposed plan against both baselines, whatever a result file
    # recorded.
    scenario = _scenario(args)
    settings = dataclasses.replace(_settings(args), compute_baselines=True)
    budgets = _sweep_budgets(args)
    _check_budget_count(budgets)
    scenarios = [scenario.replace(power_budget_w=budget) for budget in budgets]
    for each in scenarios:
        settings.check(each)
    rows: dict[str, list[float]] = {'proposed': [], 'straight': [], 'static': [], 'bound': []}
    # 'bound': the dual bound over the flyable paths, at each plan's multipliers.
    print(f'{"P_T (W)":>8}{"proposed":>12}{"straight":>12}{"static":>12}{"dual bound":>12}'
          f'{"time (s)":>10}')
    for budget, each in zip(budgets, scenarios):
        result = plan(each, settings)
        values = [result.min_throughput, result.baselines['straight'], result.baselines['static'],
                  result.tight_upper_bound]
        for key, value in zip(rows, values):
            rows[key].append(value)
        print(f'{budget:>8g}' + ''.join(f'{v:>12.4f}' for v in values)
              + f'{result.solve_time_s:>10.2f}')
    if args.json is not None:
        record = {'budgets_w': budgets,
                  'min_throughput': {key: rows[key] for key in ('proposed', 'straight', 'static')},
                  'dual_upper_bound': rows['bound'],
                  'scenario': scenario_to_dict(scenario), **run_record(settings)}
        print(f'wrote {write_text_atomic(args.json, json_text(record))}')
    if args.figure is not None:
        from uav_comm_planner.tools.plots import sweep_figure
        print(f'wrote {sweep_figure(budgets, rows, args.figure, scenario=scenario)}')
    return 0


def _command_energy_sweep(args: argparse.Namespace) -> int:
    _check_outputs(args.json, figure=args.figure)

    def write(path: Path, record: dict) -> None:
        print(f'wrote {write_text_atomic(path, json_text(record))}')
    energy_sweep.run(_scenario(args), _settings(args), args, write)
    return 0


def _command_upload(args: argparse.Namespace) -> int:
    from uav_comm_planner.vehicle.mavlink.link import LinkSettings
    from uav_comm_planner.vehicle.mavlink.upload import upload_files

    done = upload_files(args.connect, mission=args.mission, fence=args.fence,
                        settings=LinkSettings(timeout_s=args.timeout, retries=args.retries),
                        connect_timeout_s=args.connect_timeout,
                        home_limit_m=args.max_home_distance)
    if args.fence is not None:
        print(f'{args.fence}: {done.fence_items} fence items uploaded to {args.connect} and '
              f'read back identical')
    if args.mission is not None:
        print(f'{args.mission}: {done.mission_items} items uploaded to {args.connect} and '
              f'read back identical')
    return 0


def _simulator_homes() -> str:
    """Each firmware's simulator home, as ``--home`` takes it."""
    return '; '.join(f'{name} ' + ','.join(f'{v:.10g}' for v in firmware.sitl_home)
                     for name, firmware in FIRMWARES.items())


def _parameter_keys() -> str:
    """Each firmware's limit parameters, as ``--vehicle-params`` reads them."""
    return '; '.join(f'{", ".join(firmware.parameters)} ({name})'
                     for name, firmware in FIRMWARES.items())


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineArgumentParser(
        prog=PROG,
        description='Joint transmit-power and trajectory planning for a communication UAV.')
    parser.add_argument('--version', action='version', version=f'%(prog)s {package_version()}')
    commands = parser.add_subparsers(dest='command', required=True)

    plan_parser = commands.add_parser('plan', help='plan one scenario and print the table')
    _add_scenario_arguments(plan_parser)
    plan_parser.add_argument('--json', type=Path, metavar='FILE.json', help='write the plan')
    plan_parser.add_argument('--figure', type=Path, metavar='FILE.png',
                             help="draw the letter's Fig. 1 for this plan (.png, .pdf or .svg)")
    plan_parser.add_argument('--mission', type=Path, metavar='FILE.waypoints|FILE.plan',
                             help='write a MAVLink mission: QGC WPL 110 or QGroundControl .plan')
    plan_parser.add_argument('--home', type=_home, metavar='LAT,LON,ALT',
                             help='where x = east, y = north metres start: degrees, degrees, '
                                  "metres above sea level (default: the --firmware simulator's "
                                  'home, %s; give your own field\'s)'
                                  % _simulator_homes())
    plan_parser.add_argument('--fence', type=Path, metavar='FENCE.plan|FENCE.geojson',
                             help="where the vehicle may fly: a .plan file's geoFence or a "
                                  'GeoJSON FeatureCollection, anchored at --home '
                                  '(docs/fences.md); a .plan mission carries it as its fence')
    plan_parser.add_argument('--fence-margin', type=float, default=Zones.margin_m, metavar='M',
                             help='clearance kept from every fence edge, metres (default '
                                  f'{Zones.margin_m:g})')
    plan_parser.add_argument('--mission-end', choices=MISSION_ENDS, default='land',
                             help='land at the goal or return to launch (default land)')
    plan_parser.add_argument('--firmware', choices=list(FIRMWARES), default='ardupilot',
                             help='autopilot the mission is for (default ardupilot)')
    vehicle = plan_parser.add_argument_group(
        'vehicle', 'plan for the vehicle that flies it (implied by --mission or any option '
        "here): the plan as the vehicle flies it, with the autopilot's S-curve legs, is the "
        'one stated and written; defaults are ArduCopter\'s')
    vehicle.add_argument('--vehicle', action='store_true',
                         help='plan for the vehicle even without a mission file')
    vehicle.add_argument('--vehicle-params', type=Path, metavar='FILE',
                         help='parameter file saved by a ground station (NAME,VALUE or NAME '
                              'VALUE lines); the keys read: '
                              + _parameter_keys()
                              + '; --wp-speed, --wp-accel and --wp-jerk win over it')
    for field, (flag, text) in _VEHICLE_FLAGS.items():
        vehicle.add_argument(flag, dest=_VEHICLE_DEST + field, type=float, help=text)
    add_energy_arguments(plan_parser)
    altitude_cli.add_arguments(plan_parser)
    fading_cli.add_arguments(plan_parser)
    fleet_cli.add_arguments(plan_parser)
    plan_parser.set_defaults(handler=_command_plan)

    sweep_parser = commands.add_parser('sweep', help='min throughput against the power budget')
    _add_scenario_arguments(sweep_parser)
    sweep_parser.add_argument('--budgets', type=_floats, default=None, metavar='W,W,...',
                              help='power budgets P_T, watts (default: those of a sweep file '
                                   "given as --scenario, else the letter's %s)"
                                   % ','.join(f'{b:g}' for b in SWEEP_BUDGETS_W))
    sweep_parser.add_argument('--json', type=Path, metavar='FILE.json', help='write the table')
    sweep_parser.add_argument('--figure', type=Path, metavar='FILE.png',
                              help="draw the letter's Fig. 2 (.png, .pdf or .svg)")
    sweep_parser.set_defaults(handler=_command_sweep)

    energy_parser = commands.add_parser(
        'energy-sweep', help='min throughput against the propulsion energy budget')
    _add_scenario_arguments(energy_parser)
    add_airframe_argument(energy_parser)
    energy_sweep.add_arguments(energy_parser)
    energy_parser.set_defaults(handler=_command_energy_sweep)

    upload_parser = commands.add_parser(
        'upload', help='upload a mission and/or a fence over MAVLink and verify them by reading '
                       'them back')
    upload_parser.add_argument('mission', type=Path, nargs='?',
                               metavar='MISSION.waypoints|MISSION.plan')
    upload_parser.add_argument('--fence', type=Path, metavar='FENCE.plan|FENCE.geojson',
                               help="the geofence to upload first: a .plan file's geoFence or "
                                    'a GeoJSON FeatureCollection (docs/fences.md)')
    upload_parser.add_argument('--connect', required=True, metavar='URL',
                               help='pymavlink URL: tcp:127.0.0.1:5760, udpin:0.0.0.0:14550, '
                                    '/dev/ttyACM0,115200')
    upload_parser.add_argument('--timeout', type=float, default=2.0, metavar='S',
                               help='seconds to wait for each answer (default 2)')
    upload_parser.add_argument('--retries', type=int, default=5,
                               help='resends of an unanswered message (default 5)')
    upload_parser.add_argument('--connect-timeout', type=float, default=30.0, metavar='S',
                               help='seconds to wait for the heartbeat (default 30)')
    upload_parser.add_argument('--max-home-distance', type=float, default=1000.0, metavar='M',
                               help="refuse a mission whose home or first waypoint is farther "
                                    "than this from the vehicle's home (or position), metres "
                                    "(default 1000; inf: no check)")
    upload_parser.set_defaults(handler=_command_upload)

    study_parser = commands.add_parser('montecarlo', help=montecarlo.DESCRIPTION,
                                       description=montecarlo.DESCRIPTION)
    montecarlo.add_arguments(study_parser)
    study_parser.set_defaults(handler=montecarlo.command)

    altitude_parser = commands.add_parser('altitude-study', help=altitude_study.DESCRIPTION,
                                          description=altitude_study.DESCRIPTION)
    altitude_study.add_arguments(altitude_parser)
    altitude_parser.set_defaults(handler=altitude_study.command)

    fit_parser = commands.add_parser('fit-airframe', help=fit_airframe.DESCRIPTION,
                                     description=fit_airframe.DESCRIPTION)
    fit_airframe.add_arguments(fit_parser)
    fit_parser.set_defaults(handler=fit_airframe.command)
    return parser


def _error_line(exc: BaseException) -> str:
    return ' '.join(str(exc).split()) or type(exc).__name__


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status: 0, or 2 after a one-line error."""
    logging.basicConfig(level=logging.WARNING, format='%(levelname)s %(name)s: %(message)s')
    try:
        args = build_parser().parse_args(argv)
        return args.handler(args)
    except (CommandLineError, PlannerError, OSError) as exc:
        print(f'{PROG}: error: {_error_line(exc)}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f'{PROG}: interrupted', file=sys.stderr)
        return 130


if __name__ == '__main__':
    sys.exit(main())
