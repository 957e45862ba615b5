"""Monte Carlo studies: many random scenarios, every method on each, planned on Dask.

The study is in :mod:`uav_comm_planner.tools.study.tables` and its figures in
:mod:`uav_comm_planner.tools.study.plots`; the names callers use are here too.
"""

from uav_comm_planner.tools.study.tables import (algorithm_outcome, Draw, Method, METHODS,
                                                 Outcome, read_table, run_study, scenario_at,
                                                 StudyDesign, StudyError)

__all__ = ['Draw', 'METHODS', 'Method', 'Outcome', 'StudyDesign', 'StudyError',
           'algorithm_outcome', 'read_table', 'run_study', 'scenario_at']
