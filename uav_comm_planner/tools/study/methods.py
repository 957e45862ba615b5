"""The methods a Monte Carlo study compares on every scenario: Algorithm 1 with the default and
the letter's settings, the letter's two baselines, and two upper bounds of every plan (the
closed form, and the dual bound over the flyable paths).

A method is a label for the figures and a function ``Scenario -> Outcome``; :data:`METHODS`
names each by the prefix of its table columns, so a new method is one more entry there.
"""

from __future__ import annotations

from dataclasses import dataclass
import functools
from typing import Callable

import numpy as np

from uav_comm_planner.core import initial
from uav_comm_planner.core.bound import dual_upper_bound
from uav_comm_planner.core.model import average_rates, snr_per_watt
from uav_comm_planner.core.optimizer import optimal_power, plan, throughput_upper_bound
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.tools.plots import METHOD_LABELS


@dataclass(frozen=True)
class Outcome:
    """What one method achieved on one scenario: min_n R_n in bit/s and how it got there."""

    min_throughput_bps: float
    iterations: int | None = None      # outer iterations (power steps) of Algorithm 1
    sca_steps: int | None = None       # trajectory (SCA) steps, all starts together
    status: str = 'exact'
    #: The plan (q (M, 2) metres, p (N, M) watts) a planning method made; None for a bound.
    plan: tuple[np.ndarray, np.ndarray] | None = None


@dataclass(frozen=True)
class Method:
    """A planning method of the study: a label for figures and ``run(scenario) -> Outcome``."""

    label: str
    run: Callable[[Scenario], Outcome]


def algorithm_outcome(settings: SolverSettings, scenario: Scenario) -> Outcome:
    """Algorithm 1 (:func:`~uav_comm_planner.core.optimizer.plan`) with ``settings``."""
    result = plan(scenario, settings)
    return Outcome(result.min_throughput, result.outer_iterations, result.trajectory_steps,
                   result.status, (result.trajectory, result.power))


def fixed_path_outcome(path: Callable[[Scenario], np.ndarray], scenario: Scenario) -> Outcome:
    """A fixed trajectory q = path(scenario) (M, 2) with its optimal (water-filling) power."""
    q = path(scenario)
    p = optimal_power(q, scenario)
    return Outcome(float(average_rates(q, p, scenario).min()), plan=(q, p))


def upper_bound_outcome(scenario: Scenario) -> Outcome:
    """:func:`~uav_comm_planner.core.optimizer.throughput_upper_bound`: no plan exceeds it."""
    return Outcome(throughput_upper_bound(scenario), status='bound')


def dual_bound_outcome(scenario: Scenario) -> Outcome:
    """:func:`~uav_comm_planner.core.bound.dual_upper_bound` at the multipliers of the
    hover-and-fly start with its optimal power (valid at any multipliers; no plan exceeds it),
    or the closed-form bound where that is lower."""
    q = initial.hover_and_fly(scenario)
    dual = dual_upper_bound(scenario, optimal_power(q, scenario), snr_per_watt(q, scenario))
    return Outcome(min(dual, throughput_upper_bound(scenario)), status='bound')


#: Every method a study can run, by column prefix; a new method is one more entry.
METHODS: dict[str, Method] = {
    'default': Method('default plan (straight and hover starts)',
                      functools.partial(algorithm_outcome,
                                        SolverSettings(compute_baselines=False))),
    'letter': Method("letter's Algorithm 1",
                     functools.partial(algorithm_outcome,
                                       SolverSettings.letter(compute_baselines=False))),
    'straight': Method(METHOD_LABELS['straight'],
                       functools.partial(fixed_path_outcome, initial.straight_line)),
    'static': Method(METHOD_LABELS['static'],
                     functools.partial(fixed_path_outcome, initial.static_point)),
    'bound': Method('upper bound', upper_bound_outcome),
    'dual_bound': Method('upper bound, dual over the flyable paths', dual_bound_outcome),
}
#: The methods that bound every plan from above rather than plan.
BOUNDS = ('bound', 'dual_bound')
#: The letter's benchmarks, against which the figures show the gain of the other methods.
BASELINES = ('straight', 'static')
