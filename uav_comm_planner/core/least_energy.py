"""The least propulsion energy such that every node gets at least a given throughput.

Zeng, Xu and Zhang (2019) trade throughput against the propulsion energy. With the energy
budget as a block of the trajectory step (:mod:`uav_comm_planner.core.sca.energy`), the max-min
plan at budget E gives the throughput E buys; :func:`least_energy_plan` searches E by bisection
between the least energy any flight of the horizon takes and the energy of the
throughput-optimal plan, and returns the least-energy plan it found whose every node gets the
target. Each plan is Algorithm 1's (a local optimum), so the search is a heuristic on E; its
answer always meets the target and never takes more energy than the throughput-optimal plan.
"""

from __future__ import annotations

import logging
from typing import Callable

from uav_comm_planner.core.energy import horizon_energy_j, JOULES_PER_WH
from uav_comm_planner.core.optimizer import plan, PlanResult
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.errors import InfeasibleHorizonError, InvalidScenarioError

logger = logging.getLogger(__name__)

#: Halvings of the energy interval.
ENERGY_BISECTIONS = 12


def plan_energy_wh(result: PlanResult) -> float:
    """The propulsion energy of a plan's horizon, Wh (its scenario's airframe)."""
    scenario = result.scenario
    return horizon_energy_j(result.trajectory, scenario, scenario.airframe) / JOULES_PER_WH


def least_energy_plan(scenario: Scenario, settings: SolverSettings | None = None, *,
                      target_bps: float, planner: Callable[..., PlanResult] = plan,
                      bisections: int = ENERGY_BISECTIONS, **options) -> PlanResult:
    """The least-energy plan found whose min throughput is at least ``target_bps`` (module
    docstring); ``planner`` and ``options`` as :func:`~uav_comm_planner.core.optimizer.plan`'s.
    Raises :class:`~uav_comm_planner.errors.InvalidScenarioError` without an airframe and
    :class:`~uav_comm_planner.errors.InfeasibleHorizonError` when even the throughput-optimal
    plan misses the target."""
    if scenario.airframe is None:
        raise InvalidScenarioError('the least-energy plan needs an airframe (its propulsion '
                                   'model): give airframe')
    if not (isinstance(target_bps, (int, float)) and target_bps > 0):
        raise InvalidScenarioError(f'the throughput target must be positive, got '
                                   f'{target_bps!r}')
    free = planner(scenario.replace(energy_budget_wh=scenario.energy_budget_wh), settings,
                   **options)
    if free.min_throughput < target_bps:
        raise InfeasibleHorizonError(
            f'no plan found reaches {target_bps:g} bit/s for every node: the throughput-optimal '
            f'plan gives {free.min_throughput:.6g} bit/s; lower the target, raise the power '
            f'budget or lengthen the horizon')
    best, best_wh = free, plan_energy_wh(free)
    least_wh = ((scenario.num_slots + 1) * scenario.slot_s
                * scenario.airframe.least_power()[1] / JOULES_PER_WH)
    low, high = least_wh * (1 + 1e-6), best_wh
    for _ in range(bisections):
        middle = 0.5 * (low + high)
        try:
            found = planner(scenario.replace(energy_budget_wh=middle), settings, **options)
        except InfeasibleHorizonError:
            low = middle
            continue
        if found.min_throughput >= target_bps:
            high = middle
            if plan_energy_wh(found) < best_wh:
                best, best_wh = found, plan_energy_wh(found)
        else:
            low = middle
    logger.debug('least energy for %g bit/s: %.4g Wh (throughput-optimal %.4g Wh)',
                 target_bps, best_wh, plan_energy_wh(free))
    return best


__all__ = ['ENERGY_BISECTIONS', 'least_energy_plan', 'plan_energy_wh']
