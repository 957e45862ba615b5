"""``uav-comm-planner energy-sweep``: the min throughput against the propulsion energy budget,
the trade-off Zeng, Xu and Zhang (2019) study, as a table, a JSON file and a figure."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Sequence

import numpy as np

from uav_comm_planner.core.energy import horizon_energy_j, JOULES_PER_WH, least_horizon_energy_j
from uav_comm_planner.core.initial import straight_line
from uav_comm_planner.core.optimizer import plan
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.errors import InfeasibleHorizonError, PlannerError
from uav_comm_planner.tools.plots import _legend_below, _pyplot, check_figure_path, save_figure
from uav_comm_planner.vehicle.airframe import airframe_named

#: Budgets between the straight line's energy and the free plan's, by default.
DEFAULT_POINTS = 8
#: More budgets than this are refused before the first plan.
MAX_BUDGETS = 200


def sweep_budgets_wh(scenario: Scenario, settings: SolverSettings,
                     points: int = DEFAULT_POINTS) -> tuple[list[float], float, float]:
    """``points`` budgets from the straight line's energy to the throughput-optimal plan's
    (Wh), with those two energies."""
    line = horizon_energy_j(straight_line(scenario), scenario, scenario.airframe) / JOULES_PER_WH
    free = plan(scenario, settings)
    top = horizon_energy_j(free.trajectory, scenario, scenario.airframe) / JOULES_PER_WH
    return np.linspace(line, top, points).tolist(), line, top


def energy_sweep(scenario: Scenario, settings: SolverSettings,
                 budgets_wh: Sequence[float]) -> list[dict]:
    """One max-min plan per energy budget: rows of budget, min throughput and energy used
    (Wh); a budget no start keeps has no plan (None)."""
    rows = []
    least = least_horizon_energy_j(scenario, scenario.airframe) / JOULES_PER_WH
    for budget in budgets_wh:
        if budget <= least:
            rows.append({'budget_wh': budget, 'min_throughput': None, 'energy_wh': None})
            continue
        try:
            result = plan(scenario.replace(energy_budget_wh=budget), settings)
        except InfeasibleHorizonError:
            rows.append({'budget_wh': budget, 'min_throughput': None, 'energy_wh': None})
            continue
        rows.append({'budget_wh': budget, 'min_throughput': result.min_throughput,
                     'energy_wh': horizon_energy_j(result.trajectory, scenario,
                                                   scenario.airframe) / JOULES_PER_WH})
    return rows


def draw_energy_sweep(rows: Sequence[dict], scenario: Scenario, *, title: str = ''):
    """Min throughput against the energy each plan uses."""
    plt = _pyplot()
    figure, ax = plt.subplots(figsize=(6.4, 4.4), layout='constrained')
    planned = [row for row in rows if row['min_throughput'] is not None]
    ax.plot([row['energy_wh'] for row in planned], [row['min_throughput'] for row in planned],
            'o-', label='joint design with the energy budget')
    ax.set_xlabel("horizon's propulsion energy (Wh)")
    ax.set_ylabel('min average throughput (bit/s)')
    ax.grid(True, alpha=0.3)
    ax.set_title(title or f'throughput against energy, airframe {scenario.airframe.name}, '
                          f'{scenario.num_nodes} nodes, T = {scenario.horizon_s:g} s')
    _legend_below(ax)
    return figure


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--budgets-wh', metavar='WH,WH,...',
                        help='energy budgets of the horizon, Wh (default: '
                             f'{DEFAULT_POINTS} from the straight line\'s energy to the '
                             "throughput-optimal plan's)")
    parser.add_argument('--json', type=Path, metavar='FILE.json', help='write the table')
    parser.add_argument('--figure', type=Path, metavar='FILE.png',
                        help='draw throughput against energy (.png, .pdf or .svg)')


def parse_budgets(text: str) -> list[float]:
    try:
        values = [float(part) for part in text.split(',')]
    except ValueError:
        raise PlannerError(f'--budgets-wh takes numbers separated by commas, got {text!r}') \
            from None
    if not values or len(values) > MAX_BUDGETS:
        raise PlannerError(f'--budgets-wh takes 1 to {MAX_BUDGETS} budgets, got {len(values)}')
    if not all(np.isfinite(values)) or min(values) <= 0:
        raise PlannerError('every energy budget must be positive and finite')
    return values


def run(scenario: Scenario, settings: SolverSettings, args: argparse.Namespace,
        write_text) -> list[dict]:
    """The command's work: the table printed, the JSON and the figure written."""
    if args.airframe is None:
        raise PlannerError('energy-sweep needs --airframe (the propulsion model)')
    if args.figure is not None:
        check_figure_path(args.figure)
    scenario = scenario.replace(airframe=airframe_named(args.airframe))
    if args.budgets_wh is not None:
        budgets = parse_budgets(args.budgets_wh)
    else:
        budgets, line, top = sweep_budgets_wh(scenario, settings)
        print(f'straight line {line:.3f} Wh, throughput-optimal plan {top:.3f} Wh')
    rows = energy_sweep(scenario, settings, budgets)
    print(f'{"budget (Wh)":>12}{"min throughput":>16}{"energy (Wh)":>13}')
    for row in rows:
        if row['min_throughput'] is None:
            print(f'{row["budget_wh"]:>12.3f}{"no plan":>16}{"":>13}')
        else:
            print(f'{row["budget_wh"]:>12.3f}{row["min_throughput"]:>16.4f}'
                  f'{row["energy_wh"]:>13.3f}')
    if args.json is not None:
        write_text(args.json, {'airframe': scenario.airframe.name, 'rows': rows})
    if args.figure is not None:
        print(f'wrote {save_figure(draw_energy_sweep(rows, scenario), args.figure)}')
    return rows


__all__ = ['add_arguments', 'draw_energy_sweep', 'energy_sweep', 'parse_budgets', 'run',
           'sweep_budgets_wh']
