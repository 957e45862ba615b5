"""The fleet's figure: every UAV's path, the distance between each pair over time against
d_min, and each UAV's transmit power per slot; matplotlib is imported only when drawing (as
in :mod:`.plots`, whose saving and units it uses)."""

from __future__ import annotations

import itertools
import os
from pathlib import Path

import numpy as np

from uav_comm_planner.core.fleet.planner import FleetPlan
from uav_comm_planner.core.fleet.shared_band import SharedBandPlan
from uav_comm_planner.core.model import flown_path
from uav_comm_planner.tools.plots import (_draw_zones, _legend_below, _pyplot, check_figure_path,
                                          format_rate, save_figure)

#: One colour per UAV (matplotlib's first ones), enough for MAX_UAVS.
UAV_COLOURS = ('tab:blue', 'tab:orange', 'tab:green', 'tab:purple', 'tab:brown', 'tab:pink',
               'tab:olive', 'tab:cyan')


def slot_power(result: FleetPlan | SharedBandPlan) -> np.ndarray:
    """Each UAV's transmit power per slot, all nodes together: (K, M) watts."""
    power = np.asarray(result.power)
    return power.sum(axis=1) if power.ndim == 3 else power


def draw_fleet(result: FleetPlan | SharedBandPlan, *, title: str = ''):
    """Paths (with the zones and their margin, where there are some), pair distances and power
    per UAV in three panels (a fleet on orthogonal channels or on the shared band); returns the
    figure."""
    plt = _pyplot()
    fleet, scenario = result.fleet, result.fleet.scenario
    times = scenario.times_s
    power = slot_power(result)
    figure, (ax_path, ax_gap, ax_power) = plt.subplots(1, 3, figsize=(15, 5.2),
                                                       layout='constrained')
    for k, (q_k, vehicle) in enumerate(zip(result.trajectories, fleet.vehicles)):
        colour = UAV_COLOURS[k % len(UAV_COLOURS)]
        path = flown_path(q_k, vehicle)
        ax_path.plot(path[:, 0], path[:, 1], '.-', color=colour, markersize=4,
                     label=f'UAV {k + 1}')
        ax_path.plot(*vehicle.start_m, 's', color=colour, markersize=8)
        ax_path.plot(*vehicle.goal_m, '*', color=colour, markersize=12)
        ax_power.step(times, power[k], where='mid', color=colour, label=f'UAV {k + 1}')
    w = scenario.nodes
    if scenario.zones is not None and not scenario.zones.empty:
        _draw_zones(ax_path, scenario.zones,
                    np.vstack([*result.trajectories, w, fleet.starts_m, fleet.goals_m]))
    ax_path.plot(w[:, 0], w[:, 1], '^', color='tab:red', markersize=9, label='ground nodes')
    ax_path.set(xlabel='x (m)', ylabel='y (m)', title='trajectories (square: q0, star: qF)')
    ax_path.set_aspect('equal', adjustable='datalim')
    ax_path.margins(0.08)
    _legend_below(ax_path, columns=3)
    for j, k in itertools.combinations(range(fleet.num_uavs), 2):
        gap = np.linalg.norm(result.trajectories[j] - result.trajectories[k], axis=1)
        ax_gap.plot(times, gap, label=f'UAV {j + 1} - UAV {k + 1}')
    if fleet.min_separation_m > 0:
        ax_gap.axhline(fleet.min_separation_m, color='grey', linestyle=':',
                       label=f'd_min = {fleet.min_separation_m:g} m')
    ax_gap.set(xlabel='time (s)', ylabel='distance (m)', title='distance between UAVs')
    ax_gap.set_ylim(bottom=0.0)
    _legend_below(ax_gap)
    ax_power.set(xlabel='time (s)', ylabel='transmit power, all nodes (W)',
                 title='transmit power per UAV')
    ax_power.set_ylim(bottom=0.0)
    ax_power.ticklabel_format(axis='y', useOffset=False)
    _legend_below(ax_power, columns=min(fleet.num_uavs, 4))
    if isinstance(result, SharedBandPlan):
        stated = (f'{result.min_throughput:.4f} bit/s/Hz on one shared band '
                  f'({"with" if result.power_control else "without"} power control)')
    else:
        stated = format_rate(result.min_throughput)
    figure.suptitle(title or (f'{fleet.num_uavs} UAVs, {scenario.num_nodes} nodes: min average '
                              f'throughput {stated}, '
                              f'$P_T$ = {scenario.power_budget_w:g} W per UAV'))
    return figure


def fleet_figure(result: FleetPlan | SharedBandPlan, path: str | os.PathLike, *,
                 title: str = '') -> Path:
    """Draw :func:`draw_fleet` into ``path`` (.png, .pdf or .svg) atomically."""
    check_figure_path(path)
    return save_figure(draw_fleet(result, title=title), path)


__all__ = ['draw_fleet', 'fleet_figure', 'slot_power', 'UAV_COLOURS']
