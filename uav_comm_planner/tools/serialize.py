"""Scenarios and plans as plain JSON-ready dictionaries (the command line's file format)."""

from __future__ import annotations

import dataclasses
import importlib.metadata
import math
from pathlib import Path
import re
from typing import Any, Mapping

from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.core.propulsion import Airframe
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.core.zones import Zones
from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.vehicle.airframe import airframe_from_mapping

DISTRIBUTION = 'uav_comm_planner'


def package_version() -> str:
    """The installed package's version; from a source tree not installed, package.xml's.

    Installed (pip, ``make dev``, ``colcon build``) the version comes from the package's
    metadata; a checkout used through ``PYTHONPATH`` reads the ``<version>`` of the
    package.xml beside the sources; otherwise ``'unknown'``.
    """
    try:
        return importlib.metadata.version(DISTRIBUTION)
    except importlib.metadata.PackageNotFoundError:
        pass
    package_xml = Path(__file__).resolve().parents[2] / 'package.xml'
    try:
        found = re.search(r'<version>\s*([^<\s]+)\s*</version>',
                          package_xml.read_text(encoding='utf-8'))
    except OSError:
        found = None
    return found.group(1) if found else 'unknown'


def scenario_to_dict(scenario: Scenario) -> dict[str, Any]:
    """Every field of the scenario, points as [x, y] lists."""
    data = dataclasses.asdict(scenario)
    data['ground_nodes_m'] = [list(w) for w in scenario.ground_nodes_m]
    data['start_m'] = list(scenario.start_m)
    data['goal_m'] = list(scenario.goal_m)
    data['zones'] = None if scenario.zones is None else scenario.zones.to_dict()
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
    if data.get('zones') is not None and not isinstance(data['zones'], Zones):
        data = {**data, 'zones': Zones.from_dict(data['zones'])}
    if data.get('airframe') is not None and not isinstance(data['airframe'], Airframe):
        data = {**data, 'airframe': airframe_from_mapping(data['airframe'], 'airframe')}
    if base is None:
        if 'ground_nodes_m' not in data:
            raise InvalidScenarioError('a scenario needs ground_nodes_m: [[x, y], ...]')
        return Scenario(**data)
    return base.replace(**data)


def settings_to_dict(settings: SolverSettings) -> dict[str, Any]:
    """Every field of the solver settings, ``starts`` as a list."""
    data = dataclasses.asdict(settings)
    data['starts'] = list(settings.starts)
    return data


def settings_from_dict(data: Mapping[str, Any]) -> SolverSettings:
    """Solver settings from a dictionary of SolverSettings fields (a result file's
    'settings' also works); missing fields take the defaults, unknown keys are an error."""
    if 'settings' in data and isinstance(data['settings'], Mapping):
        data = data['settings']
    known = {f.name for f in dataclasses.fields(SolverSettings)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise InvalidScenarioError(
            f'unknown solver setting(s) {unknown}; known settings: {sorted(known)}')
    values = dict(data)
    if 'starts' in values and isinstance(values['starts'], list):
        values['starts'] = tuple(values['starts'])
    return SolverSettings(**values)


def run_record(settings: SolverSettings | None) -> dict[str, Any]:
    """What a result file needs to be made again: the package version and the settings."""
    record: dict[str, Any] = {'version': package_version()}
    if settings is not None:
        record['settings'] = settings_to_dict(settings)
    return record


def result_to_dict(result: PlanResult, *, settings: SolverSettings | None = None,
                   optimised: PlanResult | None = None) -> dict[str, Any]:
    """The plan with the keys trajectory, times, power, rates, min_throughput, baselines,
    history and scenario (units: metres, seconds, watts, bit/s), plus how it was solved:
    the package ``version`` and, when given, the solver ``settings`` it ran with, so that
    ``uav-comm-planner plan --scenario FILE`` runs it again. ``upper_bound`` is the loose
    bound (every channel at its best), ``dual_upper_bound`` the Lagrangian dual bound over the
    flyable paths that the command line prints (of ``optimised``, the optimiser's plan when
    ``result`` is the plan as the vehicle flies it; default ``result``), null where there is
    none."""
    dual = (optimised or result).tight_upper_bound
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
        'dual_upper_bound': dual if math.isfinite(dual) else None,
        **run_record(settings),
    }
