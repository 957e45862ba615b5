"""Joint transmit-power and trajectory planning for a communication UAV.

The numerical core (scenario, model, power, trajectory, optimizer) has no ROS in it::

    from uav_comm_planner import plan, paper_scenario
    result = plan(paper_scenario('I'))
    result.min_throughput, result.baselines['straight'], result.baselines['static']
"""

from uav_comm_planner.errors import (InfeasibleHorizonError, InvalidScenarioError,
                                     MissionExportError, PlannerError, SolverError)
from uav_comm_planner.core.optimizer import plan, PlanResult
from uav_comm_planner.core.scenario import paper_scenario, Scenario, SolverSettings

__all__ = [
    'InfeasibleHorizonError', 'InvalidScenarioError', 'MissionExportError', 'PlanResult',
    'PlannerError', 'Scenario', 'SolverError', 'SolverSettings', 'paper_scenario', 'plan',
]
