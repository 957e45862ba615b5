"""Scenarios and plans as plain JSON-ready dictionaries (the command line's file format)."""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping

from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.core.scenario import Scenario


def scenario_to_dict(scenario: Scenario) -> dict[str, Any]:
    """Every field of the scenario, points as [x, y] lists."""
    data = dataclasses.asdict(scenario)
    data['ground_nodes_m'] = [list(w) for w in scenario.ground_nodes_m]
    data['start_m'] = list(scenario.start_m)
    data['goal_m'] = list(scenario.goal_m)
    return data


def scenario_from_dict(data: Mapping[str, Any], base: Scenario | None = None) -> Scenario:
    """A scenario from a dictionary of Scenario fields (a result file's 'scenario' also works).

    Fields missing from ``data`` are taken from ``base``; unknown keys are an error.
    """
    if 'scenario' in data and isinstance(data['scenario'], Mapping):
        data = data['scenario']
    known = {f.name for f in dataclasses.fields(Scenario)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise InvalidScenarioError(
            f'unknown scenario field(s) {unknown}; known fields: {sorted(known)}')
    if base is None:
        if 'ground_nodes_m' not in data:
            raise InvalidScenarioError('a scenario needs ground_nodes_m: [[x, y], ...]')
        return Scenario(**data)
    return base.replace(**data)


def result_to_dict(result: PlanResult) -> dict[str, Any]:
    """The plan with the keys trajectory, times, power, rates, min_throughput, baselines,
    history and scenario (units: metres, seconds, watts, bit/s), plus how it was solved."""
    return {
        'trajectory': result.trajectory.tolist(),
        'times': result.times.tolist(),
        'power': result.power.tolist(),
        'rates': result.rates.tolist(),
        'min_throughput': result.min_throughput,
        'baselines': dict(result.baselines),
        'history': [{'step': s.kind, 'min_throughput': s.min_throughput}
                    for s in result.history],
        'scenario': scenario_to_dict(result.scenario),
        'solve_time_s': result.solve_time_s,
        'status': result.status,
        'outer_iterations': result.outer_iterations,
        'trajectory_steps': result.trajectory_steps,
        'start': result.start,
        'upper_bound': result.upper_bound,
    }
