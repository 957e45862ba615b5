"""Joint transmit-power and trajectory planning for a communication UAV.

The numerical core (scenario, model, power, trajectory, optimizer) has no ROS in it::

    from uav_comm_planner import plan, paper_scenario
    result = plan(paper_scenario('I'))
    result.min_throughput, result.baselines['straight'], result.baselines['static']

The mission layer plans for a vehicle, as the node and the command line do::

    from uav_comm_planner import MissionRequest, paper_scenario, plan_mission, VehicleLimits
    scenario = paper_scenario('I', max_speed_mps=10.0, horizon_s=300.0)
    mission = plan_mission(MissionRequest(scenario, vehicle=VehicleLimits()))
    mission.result.min_throughput, mission.items
"""

import importlib

from uav_comm_planner.errors import (ComputeBudgetError, InfeasibleHorizonError,
                                     InvalidScenarioError, MissionExportError,
                                     PlanCancelledError, PlannerError, SolverError,
                                     WalledInError)

# The core (numpy, scipy, cvxpy), and the mission layer and vehicle limits above it, load on
# first use, so that importing a light module of the package, such as the planner's entry
# point, does not wait for them.
_LAZY = {
    'plan': 'uav_comm_planner.core.optimizer',
    'PlanResult': 'uav_comm_planner.core.optimizer',
    'paper_scenario': 'uav_comm_planner.core.scenario',
    'Scenario': 'uav_comm_planner.core.scenario',
    'SolverSettings': 'uav_comm_planner.core.scenario',
    'MissionPlan': 'uav_comm_planner.mission.pipeline',
    'plan_mission': 'uav_comm_planner.mission.pipeline',
    'MissionRequest': 'uav_comm_planner.mission.request',
    'VehicleLimits': 'uav_comm_planner.vehicle.limits',
}


def __getattr__(name: str) -> object:
    if name not in _LAZY:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    value = getattr(importlib.import_module(_LAZY[name]), name)
    globals()[name] = value
    return value


__all__ = [
    'ComputeBudgetError', 'PlanCancelledError', 'InfeasibleHorizonError',
    'InvalidScenarioError', 'MissionExportError', 'MissionPlan', 'MissionRequest', 'PlanResult',
    'PlannerError', 'Scenario', 'SolverError', 'SolverSettings', 'VehicleLimits',
    'WalledInError', 'paper_scenario', 'plan', 'plan_mission',
]
