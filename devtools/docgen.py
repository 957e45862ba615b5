"""The node's parameter tables for docs/node.md, generated from the parameters' own descriptors.

    python -m devtools.docgen            # rewrite the marked section of docs/node.md
    python -m devtools.docgen --check    # exit 1 if the file is not up to date

Every parameter of :func:`~uav_comm_planner.ros.params.parameter_specs` becomes one row
(name, ROS type, default, description with its constraints and range), one table per group
(scenario, solver, node), between the lines :data:`BEGIN` and :data:`END` of the file. Run by
``make docs``, from the checkout (it is not installed with the package).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
import sys
from typing import Sequence

from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.errors import PlannerError
from uav_comm_planner.files import write_text_atomic
from uav_comm_planner.ros.fleet_params import FleetNodeSettings
from uav_comm_planner.ros.params import NodeSettings, parameter_specs, ParameterSpec
from uav_comm_planner.vehicle.limits import VehicleLimits

BEGIN = ('<!-- BEGIN parameters: generated from the code by '
         '`python -m devtools.docgen`; do not edit by hand -->')
END = '<!-- END parameters -->'
DEFAULT_FILE = Path('docs') / 'node.md'

#: How ``ros2 param describe`` names the type of each kind of parameter.
ROS_TYPES = {'float': 'double', 'int': 'integer', 'bool': 'boolean', 'str': 'string',
             'pair': 'double array', 'pairs': 'double array', 'strings': 'string array'}
#: Heading of each group of parameters; a group not named here is headed by its class name.
HEADINGS = {Scenario: "Scenario (what is flown; defaults: the letter's case I at 10 m/s)",
            SolverSettings: 'Solver (how Algorithm 1 is run)',
            NodeSettings: 'Node (frame, mission file, vehicle-aware planning)',
            VehicleLimits: "Vehicle (the autopilot's waypoint limits; defaults: ArduCopter's)",
            FleetNodeSettings: 'Fleet (several UAVs planned together; [A fleet](#a-fleet))'}


def _literal(value: object) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str):
        return f"'{value}'"
    if isinstance(value, list):
        return '[' + ', '.join(_literal(v) for v in value) + ']'
    if isinstance(value, float) and math.isinf(value):
        return '.inf' if value > 0 else '-.inf'     # as YAML parameter files write it
    return repr(value)


def _number(value: float) -> str:
    return f'{value:g}'


def _description(spec: ParameterSpec) -> str:
    descriptor = spec.descriptor()
    parts = [descriptor.description]
    if descriptor.additional_constraints:
        parts.append(descriptor.additional_constraints)
    for limits in (*descriptor.floating_point_range, *descriptor.integer_range):
        parts.append(f'range {_number(limits.from_value)} to {_number(limits.to_value)}')
    return '; '.join(parts).replace('|', '\\|')


def parameter_tables(specs: Sequence[ParameterSpec] | None = None) -> str:
    """The Markdown tables, one per group, of every parameter in declaration order."""
    specs = parameter_specs() if specs is None else specs
    blocks = []
    for owner in dict.fromkeys(spec.owner for spec in specs):
        rows = [f'| `{spec.name}` | {ROS_TYPES[spec.kind]} | `{_literal(spec.default)}` | '
                f'{_description(spec)} |' for spec in specs if spec.owner is owner]
        blocks.append('\n'.join([f'**{HEADINGS.get(owner, owner.__name__)}**', '',
                                 '| name | type | default | description |',
                                 '| --- | --- | --- | --- |', *rows]))
    return '\n\n'.join(blocks)


def replace_section(text: str, tables: str) -> str:
    """``text`` with the lines between BEGIN and END replaced by ``tables``."""
    lines = text.split('\n')
    try:
        begin, end = lines.index(BEGIN), lines.index(END)
    except ValueError:
        raise PlannerError(f'the file has no line {BEGIN!r} followed by a line {END!r}')
    if end < begin:
        raise PlannerError(f'{END!r} comes before {BEGIN!r}')
    return '\n'.join(lines[:begin + 1] + ['', tables, ''] + lines[end:])


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='python -m devtools.docgen',
                                     description=__doc__.split('\n')[0])
    parser.add_argument('file', nargs='?', type=Path, default=DEFAULT_FILE,
                        help=f'Markdown file with the marked section (default {DEFAULT_FILE})')
    parser.add_argument('--check', action='store_true',
                        help='only compare: exit 1 if the section differs from the code')
    args = parser.parse_args(argv)
    try:
        text = args.file.read_text(encoding='utf-8')
        updated = replace_section(text, parameter_tables())
    except (OSError, PlannerError) as exc:
        print(f'docgen: error: {args.file}: {exc}', file=sys.stderr)
        return 2
    if args.check:
        if updated != text:
            print(f'{args.file}: the parameter tables differ from the code; run '
                  f'python -m devtools.docgen', file=sys.stderr)
            return 1
        return 0
    if updated != text:
        write_text_atomic(args.file, updated)
        print(f'wrote {args.file}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
