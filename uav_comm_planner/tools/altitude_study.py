"""``uav-comm-planner altitude-study``: the best hover altitude over a node against the
environment, and the plan of the letter's case I with altitudes in each environment.

Part one holds a UAV at one point (start and goal equal, a horizontal speed of 1 cm/s) serving
one node at horizontal distances r, and compares the altitude :func:`plan_with_altitude` plans
with a search every centimetre of the gain g(r, h). Part two plans case I with altitudes in
every channel. Both at a radio where altitude matters (B = 1 MHz, -145 dBm/Hz, P_T = 0.1 W).
The figure: the hover altitude against r (search as lines, plans as markers), and the altitude
of case I's plans along the flight (matplotlib imported only when drawing).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
import os
from pathlib import Path
from typing import Sequence

import numpy as np

from uav_comm_planner.core.altitude import AltitudeLimits, AltitudePlan, plan_with_altitude
from uav_comm_planner.core.channel import channel_names
from uav_comm_planner.core.scenario import paper_scenario, Scenario, SolverSettings
from uav_comm_planner.files import write_text_atomic
from uav_comm_planner.tools.plots import _pyplot, check_figure_path, save_figure

DESCRIPTION = ('the best hover altitude over a node against the environment, and case I '
               'planned with altitudes in each (docs/channel.md)')
#: Where altitude matters: B = 1 MHz, -145 dBm/Hz, P_T = 0.1 W.
RADIO = dict(bandwidth_hz=1e6, noise_psd_dbm_per_hz=-145.0, power_budget_w=0.1)
DISTANCES_M = (100.0, 200.0, 300.0, 500.0, 1000.0)
HOVER_RANGE_M = (20.0, 3000.0)
CASE_RANGE_M = (30.0, 300.0)
CLIMB_MPS = 5.0


@dataclass(frozen=True)
class AltitudeStudy:
    """``searched`` and ``planned`` hover altitudes (channels x distances) metres, and the
    plans of case I by channel."""

    channels: tuple[str, ...]
    distances_m: tuple[float, ...]
    searched: np.ndarray
    planned: np.ndarray
    plans: dict[str, AltitudePlan]

    def to_dict(self) -> dict:
        return {
            'radio': dict(RADIO), 'distances_m': list(self.distances_m),
            'hover': {name: {'searched_m': self.searched[i].tolist(),
                             'planned_m': self.planned[i].tolist()}
                      for i, name in enumerate(self.channels)},
            'case_I': {name: {'altitudes_m': plan.altitudes.tolist(),
                              'min_throughput': plan.min_throughput,
                              'fixed_altitude_m': plan.fixed_altitude_m,
                              'fixed_altitude_throughput': plan.fixed.min_throughput}
                       for name, plan in self.plans.items()},
            'case_range_m': list(CASE_RANGE_M), 'max_climb_mps': CLIMB_MPS}


def hover_scenario(channel: str, r: float) -> Scenario:
    """One node at horizontal distance r from a UAV held at (0, 0)."""
    return Scenario(ground_nodes_m=((r, 0.0),), start_m=(0.0, 0.0), goal_m=(0.0, 0.0),
                    max_speed_mps=0.01, horizon_s=20.0, num_slots=10, channel=channel, **RADIO)


def searched_altitude(channel: str, r: float) -> float:
    """argmax_h g(r, h) over the hover range, every centimetre."""
    heights = np.arange(*HOVER_RANGE_M, 0.01)
    gain = hover_scenario(channel, r).channel_model.gain(r * r, heights)
    return float(heights[np.argmax(gain)])


def run_study(num_slots: int = 50, channels: Sequence[str] | None = None) -> AltitudeStudy:
    """Both parts (module docstring); case I with ``num_slots`` slots over 50 s."""
    channels = tuple(channels or [name for name in channel_names() if name.startswith('los:')])
    hover = AltitudeLimits(HOVER_RANGE_M, CLIMB_MPS)
    searched = np.array([[searched_altitude(c, r) for r in DISTANCES_M] for c in channels])
    planned = np.array([[plan_with_altitude(hover_scenario(c, r), hover).altitudes.mean()
                         for r in DISTANCES_M] for c in channels])
    case = AltitudeLimits(CASE_RANGE_M, CLIMB_MPS)
    plans = {c: plan_with_altitude(paper_scenario('I', channel=c, num_slots=num_slots,
                                                  **RADIO), case, SolverSettings())
             for c in ('free-space',) + channels}
    return AltitudeStudy(channels, DISTANCES_M, searched, planned, plans)


def study_figure(study: AltitudeStudy, path: str | os.PathLike) -> Path:
    """The two panels (module docstring) into ``path`` (.png, .pdf or .svg)."""
    check_figure_path(path)
    plt = _pyplot()
    figure, (left, right) = plt.subplots(1, 2, figsize=(11.0, 4.6), layout='constrained')
    distances = np.array(study.distances_m)
    # One colour per channel in both panels; free space black.
    colours = {name: f'C{i}' for i, name in enumerate(study.channels)}
    for i, name in enumerate(study.channels):
        left.plot(distances, study.searched[i], '-', color=colours[name],
                  label=f'{name} (search)')
        left.plot(distances, study.planned[i], 'o', color=colours[name],
                  label=f'{name} (planned)')
    left.set_xlabel('horizontal distance to the node r (m)')
    left.set_ylabel('hover altitude (m)')
    left.set_title('best hover altitude over one node')
    left.legend(fontsize='small')
    for name, plan in study.plans.items():
        right.step(plan.times, plan.altitudes, where='mid', color=colours.get(name, 'k'),
                   label=f'{name}: {plan.min_throughput / 1e3:.1f} kbit/s')
    right.set_xlabel('time (s)')
    right.set_ylabel('altitude (m)')
    right.set_title(f'case I with altitudes {CASE_RANGE_M[0]:g} to {CASE_RANGE_M[1]:g} m, '
                    f'climb {CLIMB_MPS:g} m/s')
    right.legend(fontsize='small')
    figure.suptitle('B = 1 MHz, $\\sigma^2$ = -145 dBm/Hz, $P_T$ = 0.1 W')
    return save_figure(figure, path)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--slots', type=int, default=50, metavar='M',
                        help="slots of case I's plans over its 50 s (default 50)")
    parser.add_argument('--figure', type=Path, metavar='FILE.png', help='draw the study')
    parser.add_argument('--json', type=Path, metavar='FILE.json', help='write the numbers')


def command(args: argparse.Namespace) -> int:
    """Run the study, print its table, write the figure and the JSON if asked."""
    import json

    if args.figure is not None:
        check_figure_path(args.figure)
    study = run_study(args.slots)
    print(f'{"channel":<22}' + ''.join(f'{f"r = {r:g} m":>22}' for r in study.distances_m))
    for i, name in enumerate(study.channels):
        print(f'{name:<22}' + ''.join(f'{f"{p:.1f} ({s:.1f})":>22}' for p, s in
                                      zip(study.planned[i], study.searched[i])))
    print('hover altitude planned (searched), metres; case I with altitudes:')
    for name, plan in study.plans.items():
        print(f'  {name:<20} {plan.min_throughput:12.1f} bit/s (best fixed altitude '
              f'{plan.fixed_altitude_m:.1f} m: {plan.fixed.min_throughput:.1f}), altitudes '
              f'{plan.altitudes.min():.1f} to {plan.altitudes.max():.1f} m')
    if args.figure is not None:
        print(f'wrote {study_figure(study, args.figure)}')
    if args.json is not None:
        text = json.dumps(study.to_dict(), indent=1) + '\n'
        print(f'wrote {write_text_atomic(args.json, text)}')
    return 0


__all__ = ['add_arguments', 'AltitudeStudy', 'command', 'DESCRIPTION', 'run_study',
           'searched_altitude', 'study_figure']
