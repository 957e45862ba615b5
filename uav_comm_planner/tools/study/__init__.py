"""Monte Carlo studies: many random scenarios, every method on each, planned on Dask.

Each module imports only those before it: :mod:`.methods` (the methods compared),
:mod:`.design` (the settings, their draws and the scenario of every row), :mod:`.tables` (the
rows, the Parquet and CSV tables, the summary), :mod:`.runner` (Dask, progress, resumption,
Ctrl-C, the scaling measurement), :mod:`.command` (``uav-comm-planner montecarlo``) and
:mod:`.plots` (the figures, drawn from a table). The names a caller needs are here too. See
``docs/studies.md``.
"""

from uav_comm_planner.tools.study.design import Draw, scenario_at, StudyDesign, StudyError
from uav_comm_planner.tools.study.methods import algorithm_outcome, Method, METHODS, Outcome
from uav_comm_planner.tools.study.runner import run_study
from uav_comm_planner.tools.study.tables import read_table

__all__ = ['Draw', 'METHODS', 'Method', 'Outcome', 'StudyDesign', 'StudyError',
           'algorithm_outcome', 'read_table', 'run_study', 'scenario_at']
