"""Joint transmit-power and trajectory planning for a communication UAV.

The numerical core (scenario, model, power, trajectory, optimizer) has no ROS in it::

    from uav_comm_planner import plan, paper_scenario
    result = plan(paper_scenario('I'))
    result.min_throughput, result.baselines['straight'], result.baselines['static']
"""

import importlib

from uav_comm_planner.errors import (ComputeBudgetError, InfeasibleHorizonError,
                                     InvalidScenarioError, MissionExportError,
                                     PlanCancelledError, PlannerError, SolverError,
                                     WalledInError)

# The core (numpy, scipy, cvxpy) loads on first use, so that importing a light module of the
# package, such as the planner's entry point, does not wait for it.
_LAZY = {
    'plan': 'uav_comm_planner.core.optimizer',
    'PlanResult': 'uav_comm_planner.core.optimizer',
    'paper_scenario': 'uav_comm_planner.core.scenario',
    'Scenario': 'uav_comm_planner.core.scenario',
    'SolverSettings': 'uav_comm_planner.core.scenario',
}


def __getattr__(name: str) -> object:
    if name not in _LAZY:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    value = getattr(importlib.import_module(_LAZY[name]), name)
    globals()[name] = value
    return value


__all__ = [
    'ComputeBudgetError', 'PlanCancelledError', 'InfeasibleHorizonError',
    'InvalidScenarioError', 'MissionExportError', 'PlanResult',
    'PlannerError', 'Scenario', 'SolverError', 'SolverSettings', 'WalledInError',
    'paper_scenario', 'plan',
]
