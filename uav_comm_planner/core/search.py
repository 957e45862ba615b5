"""The default's search (:func:`~uav_comm_planner.core.optimizer.plan`): the letter's run,
screened tours, their hover splits searched, a shortlist and the best continued
(docs/benchmark.md, "Speed, and plans better than the letter's"); and the runs of Algorithm 1
it keeps (:class:`Run`, :class:`Step`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

from uav_comm_planner.core.sca.fast import LOOSE_TOLERANCE
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.core.splits import resplit
from uav_comm_planner.core.steps import TrajectorySolver


@dataclass(frozen=True)
class Step:
    """One entry of the objective history: which step ran and the true min rate after it."""

    kind: str            # 'power' or 'trajectory'
    min_throughput: float


@dataclass(frozen=True)
class Run:
    """One run of Algorithm 1 from one start: the trajectory q (M, 2) metres and power p
    (N, M) watts it ends with, the objective after every step, and how it ended."""

    q: np.ndarray
    p: np.ndarray
    history: tuple[Step, ...]
    outer_iterations: int
    trajectory_steps: int
    converged: bool

    @property
    def min_throughput(self) -> float:
        """The true min rate of (q, p), bit/s: the value after the last step."""
        return self.history[-1].min_throughput


#: How many screened starts are continued to convergence: the best after one outer iteration.
CONTINUED = 1
#: SCA steps per power step at the tight tolerance once the loose steps have converged.
FINAL_SCA_STEPS = 1
#: How many of the best screened tours get their hover split searched before the shortlist.
RESPLIT = 3


def joined(first: Run, *later: Run) -> Run:
    """A run continued by ``later`` runs, each started where the one before it ended."""
    runs = (first, *later)
    return Run(runs[-1].q, runs[-1].p, tuple(step for run in runs for step in run.history),
               sum(run.outer_iterations for run in runs),
               sum(run.trajectory_steps for run in runs), runs[-1].converged)


def screened_runs(scenario: Scenario, starts: Mapping[str, Callable[[Scenario], np.ndarray]],
                  letter: set[str], letter_settings: SolverSettings, settings: SolverSettings,
                  run_from: Callable[..., Run], trajectory_solver: TrajectorySolver,
                  draws: Mapping[str, tuple],
                  screened: Callable[[Mapping[str, np.ndarray]], dict[str, Run]],
                  value_of: Callable[[np.ndarray], float],
                  closed_form: float | None = None) -> dict[str, Run]:
    """Runs from every start (by name, the function that makes its trajectory), screened: the
    ``letter`` start runs the letter's Algorithm 1 exactly (``letter_settings``), every other
    start is screened by one power step on it;
    the tours of ``draws`` by ``screened`` (the same power step on every tour by name, all at
    once, without the checks a tour needs not: it is flown within the speed limit and out of
    the zones). The best
    :data:`RESPLIT` tours by it get their hover split searched (:func:`.splits.resplit`, each
    split valued by ``value_of``, the efficiency of one power step on its SNR per watt, or
    in closed form with ``closed_form``, the budget P_T, where that applies), each tour with
    the split found screened as 'tour k resplit'; the best ``settings.shortlist`` of all get
    one outer iteration, the best :data:`CONTINUED` of these are continued under ``settings``
    to convergence, then the letter's run if still ahead of all.

    Continuing with ``fast_steps`` alternates one SCA step at :data:`LOOSE_TOLERANCE` per
    power step until a power step gains at most the tolerance, then :data:`FINAL_SCA_STEPS`
    SCA steps per power step at the tight tolerance until the same rule stops it, so the last
    steps are tight. Every continuation keeps a step only when it does not lower the true
    minimum rate, and one that ends below where it began (by round-off, in its first power
    step) is dropped: no run ends below its screening, the straight start below the letter's.
    """
    runs: dict[str, Run] = {}
    screen = dataclasses.replace(settings, max_outer_iterations=1)
    # The tours, flown within the speed limit and out of the zones, screened all at once.
    tours = screened({name: make(scenario) for name, make in starts.items() if name in draws})
    for name, make in starts.items():
        if name in letter:
            trajectory_solver.set_tolerance(None)
            runs[name] = run_from(make(scenario), letter_settings)
        elif name in draws:
            runs[name] = tours[name]
        else:
            runs[name] = run_from(make(scenario), screen, sca_steps=0)
    done = search(scenario, runs, letter, settings, run_from, trajectory_solver, draws, value_of,
                  closed_form)
    for name in letter:
        if all(runs[name].min_throughput > runs[other].min_throughput for other in done):
            runs[name] = continued(runs[name], settings, run_from, trajectory_solver)
    trajectory_solver.set_tolerance(None)
    return runs


def search(scenario: Scenario, runs: dict[str, Run], letter: set[str],
           settings: SolverSettings, run_from: Callable[..., Run],
           trajectory_solver: TrajectorySolver, draws: Mapping[str, tuple],
           value_of: Callable[[np.ndarray], float], closed_form: float | None) -> list[str]:
    """:func:`screened_runs`' search after the letter's run, on ``runs`` (every start
    screened), in place: the splits searched, the shortlist and the best continued, whose
    names it returns."""
    screen = dataclasses.replace(settings, max_outer_iterations=1)
    loose = LOOSE_TOLERANCE if settings.fast_steps else None
    sca_steps = 1 if settings.fast_steps else None
    position: dict[str, int] = {}

    def ranked(names) -> list[str]:
        for name in runs:
            position.setdefault(name, len(position))
        return sorted(names, key=lambda name: (-runs[name].min_throughput, position[name]))

    tours = [name for name in ranked(runs) if name in draws]
    for name in tours[:RESPLIT]:        # the best screened tours, their splits searched
        q = resplit(scenario, draws[name], value_of, power_budget_w=closed_form)
        if q is not None:
            runs[f'{name} resplit'] = run_from(q, screen, sca_steps=0)
    shortlist = ranked(name for name in runs if name not in letter)[:settings.shortlist]
    trajectory_solver.set_tolerance(loose)
    for name in shortlist:
        runs[name] = joined(runs[name], run_from(runs[name].q, screen, sca_steps=sca_steps))
    done = ranked(shortlist)[:CONTINUED]
    for name in done:
        runs[name] = continued(runs[name], settings, run_from, trajectory_solver)
    return done


def continued(begun: Run, settings: SolverSettings, run_from: Callable[..., Run],
              trajectory_solver: TrajectorySolver) -> Run:
    """``begun`` continued to convergence (:func:`screened_runs`), or ``begun`` itself if
    that ends below it."""
    sca_steps = 1 if settings.fast_steps else None
    trajectory_solver.set_tolerance(LOOSE_TOLERANCE if settings.fast_steps else None)
    run = joined(begun, run_from(begun.q, settings, sca_steps=sca_steps))
    if settings.fast_steps:
        trajectory_solver.set_tolerance(None)
        run = joined(run, run_from(run.q, settings, sca_steps=FINAL_SCA_STEPS))
    trajectory_solver.set_tolerance(None)
    return run if run.min_throughput >= begun.min_throughput else begun


__all__ = ['CONTINUED', 'FINAL_SCA_STEPS', 'RESPLIT', 'Run', 'Step', 'continued', 'joined',
           'screened_runs', 'search']
