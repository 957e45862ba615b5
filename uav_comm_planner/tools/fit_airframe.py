"""``uav-comm-planner fit-airframe``: an airframe file fitted to the user's own flight log."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.files import check_output_path, write_text_atomic
from uav_comm_planner.vehicle.airframe import airframe_yaml
from uav_comm_planner.vehicle.airframe_fit import fit_flight_log, STEADY_WINDOW_S

DESCRIPTION = ('fit an airframe (propulsion power against airspeed and climb rate) to a MAVLink '
               'flight log and write it as a YAML airframe file')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The command's arguments."""
    parser.add_argument('log', type=Path, metavar='LOG.tlog',
                        help='telemetry log with BATTERY_STATUS or SYS_STATUS (voltage and '
                             'current) and VFR_HUD or GLOBAL_POSITION_INT (speeds): level '
                             f'legs at several steady airspeeds, {2 * STEADY_WINDOW_S:g} s or '
                             'more each, in still air; a climb and a descent for their terms')
    parser.add_argument('--name', required=True, help="the airframe's name")
    parser.add_argument('--output', required=True, type=Path, metavar='FILE.yaml',
                        help='the airframe file written (replaced atomically)')
    parser.add_argument('--top-airspeed', type=float, default=None, metavar='M/S',
                        help="the airframe's top airspeed (default: the fastest steady "
                             'airspeed in the log)')


def command(args: argparse.Namespace) -> int:
    """Fit, write the file, print a summary; errors are typed (one line, exit 2), and every
    argument is checked before the log is read."""
    check_output_path(args.output)
    if not args.name.strip():
        raise InvalidScenarioError('--name must not be empty')
    top = args.top_airspeed
    if top is not None and not (math.isfinite(top) and top > 0):
        raise InvalidScenarioError(f'--top-airspeed must be a positive number of m/s, got {top:g}')
    fit, in_flight = fit_flight_log(args.log, args.name, top_airspeed_mps=top)
    airframe = fit.airframe
    vertical = [f'{label} {value:+.2f} W per m/s' if fitted else f'{label} not fitted (none '
                f'in the log)' for label, value, fitted in (
                    ('climb', airframe.climb_w_per_mps, fit.fitted_climb),
                    ('descent', airframe.descent_w_per_mps, fit.fitted_descent))]
    source = (f'fitted by uav-comm-planner fit-airframe to {args.log.name}: {fit.samples} '
              f'steady samples of {in_flight} in flight, airspeeds up to '
              f'{fit.fastest_mps:.1f} m/s; RMS {fit.rms_w:.2f} W (largest {fit.max_error_w:.2f} '
              f'W); {"; ".join(vertical)}')
    write_text_atomic(args.output, airframe_yaml(airframe, source))
    least_speed, least_power = airframe.least_power()
    print(f'{args.output}: airframe {airframe.name!r} from {fit.samples} steady samples '
          f'({in_flight} in flight): hover {airframe.hover_power_w:.1f} W, least '
          f'{least_power:.1f} W at {least_speed:.1f} m/s, '
          f'{float(airframe.level_power_w(airframe.top_airspeed_mps)):.1f} W at the top '
          f'airspeed {airframe.top_airspeed_mps:.2f} m/s; {"; ".join(vertical)}; fit RMS '
          f'{fit.rms_w:.2f} W')
    return 0


__all__ = ['add_arguments', 'command', 'DESCRIPTION']
