"""Figures of the letter's evaluation; matplotlib is imported only when a figure is drawn."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

from uav_comm_planner.files import write_with
from uav_comm_planner.core.model import flown_path, speeds
from uav_comm_planner.core.optimizer import PlanResult

METHOD_LABELS = {'proposed': 'proposed (joint power and trajectory)',
                 'straight': 'straight line, optimal power',
                 'static': 'static access point, optimal power'}


def _pyplot():
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def _save(figure, path: str | os.PathLike) -> Path:
    fmt = Path(path).suffix.lstrip('.') or 'png'
    written = write_with(path, lambda temporary: figure.savefig(temporary, format=fmt, dpi=120))
    _pyplot().close(figure)
    return written


def plan_figure(result: PlanResult, path: str | os.PathLike, *, title: str = '') -> Path:
    """The letter's Fig. 1 for one plan: trajectory, speed per leg, power per node per slot."""
    plt = _pyplot()
    scenario = result.scenario
    figure, (ax_path, ax_speed, ax_power) = plt.subplots(1, 3, figsize=(16, 4.6))
    path_xy = flown_path(result.trajectory, scenario)
    ax_path.plot(path_xy[:, 0], path_xy[:, 1], '.-', color='tab:blue', label='UAV path')
    w = scenario.nodes
    ax_path.plot(w[:, 0], w[:, 1], '^', color='tab:red', markersize=10, label='ground nodes')
    for n, (x, y) in enumerate(w, start=1):
        ax_path.annotate(f'node {n}', (x, y), textcoords='offset points', xytext=(6, 6))
    ax_path.plot(*scenario.start_m, 's', color='k', markersize=9, label='start')
    ax_path.plot(*scenario.goal_m, '*', color='k', markersize=13, label='end')
    ax_path.set(xlabel='x (m)', ylabel='y (m)', title='trajectory')
    ax_path.set_aspect('equal', adjustable='datalim')
    ax_path.legend(loc='best', fontsize=8)

    leg_end_times = scenario.path_times_s[1:]
    ax_speed.step(leg_end_times, speeds(result.trajectory, scenario), where='pre')
    ax_speed.axhline(scenario.max_speed_mps, color='grey', linestyle=':', label='V')
    ax_speed.set(xlabel='time (s)', ylabel='speed (m/s)', title='speed')
    ax_speed.legend(loc='best', fontsize=8)

    styles = ('o-', 's--', '^:', 'd-.', 'v-')
    for n, p_n in enumerate(result.power, start=1):
        ax_power.plot(result.times, p_n, styles[(n - 1) % len(styles)], markersize=3,
                      label=f'node {n}')
    ax_power.set(xlabel='time (s)', ylabel='transmit power (W)', title='transmit power')
    ax_power.legend(loc='best', fontsize=8)
    figure.suptitle(title or f'min average throughput {result.min_throughput:.3f} bit/s')
    figure.tight_layout()
    return _save(figure, path)


def sweep_figure(budgets_w: Sequence[float], rows: dict[str, Sequence[float]],
                 path: str | os.PathLike, *, title: str = '') -> Path:
    """The letter's Fig. 2: minimum average throughput against the power budget P_T."""
    plt = _pyplot()
    figure, ax = plt.subplots(figsize=(6.4, 4.6))
    markers = {'proposed': 'o-', 'straight': 's--', 'static': '^:'}
    for name, values in rows.items():
        ax.plot(budgets_w, values, markers.get(name, '.-'), label=METHOD_LABELS.get(name, name))
    ax.set_xscale('log')
    ax.set(xlabel='power budget $P_T$ (W)', ylabel='min average throughput (bit/s)',
           title=title or 'min average throughput versus power budget')
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(loc='best', fontsize=8)
    figure.tight_layout()
    return _save(figure, path)
