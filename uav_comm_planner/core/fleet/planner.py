"""The fleet's alternating loop (Algorithm 1 for K UAVs) and its starts: :func:`plan_fleet`.

From each start (K, M, 2) metres the loop alternates the joint power step (:mod:`.power`) and
SCA trajectory steps over every UAV at once (:mod:`.step`), as the letter's Algorithm 1 does for
one UAV; every step keeps the speed limits, the power budgets, every UAV's zones and energy
budget, and d_min, and none lowers the true minimum throughput (a step that would, through
round-off, is discarded and ends its loop).
The starts (:mod:`.starts`):

* ``'partition'``: each UAV's single-UAV plan (:func:`~uav_comm_planner.core.optimizer.plan`)
  over its own group of nodes, pushed apart to d_min;
* ``'single k'``: UAV k flies its own single-UAV plan over all the nodes, the others their
  partition trajectories (or, where those cannot be placed, their straight lines) pushed apart
  from it (UAV k held fixed). UAV k's plan with its power
  and no power from the others is then a point of the fleet's problem, so the fleet's plan from
  this start is at least that single plan: K UAVs never serve the nodes worse than the best of
  the K single-UAV plans from their own ends (whenever the push-apart finds the others a place,
  which :attr:`FleetPlan.left_out` reports otherwise).

The best run is kept; ties go to the earlier start.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import logging
import math
import time
from typing import Callable

import numpy as np

from uav_comm_planner.core.detour import straight_start
from uav_comm_planner.core.fleet.model import fleet_rates, fleet_snr
from uav_comm_planner.core.fleet.power import common_value, coordinate_power, POWER_METHODS
from uav_comm_planner.core.fleet.scenario import FleetScenario
from uav_comm_planner.core.fleet.starts import partition, separate, straight_lines
from uav_comm_planner.core.fleet.step import FleetStep
from uav_comm_planner.core.model import spectral_efficiency_to_rate
from uav_comm_planner.core.optimizer import plan
from uav_comm_planner.core.scenario import SolverSettings
from uav_comm_planner.core.search import Step
from uav_comm_planner.errors import ComputeBudgetError, InvalidScenarioError

logger = logging.getLogger(__name__)

FLEET_STARTS = ('partition', 'single')


@dataclass(frozen=True)
class FleetSettings:
    """How a fleet plan is solved.

    power_method: 'joint' (the exact conic power step) or 'coordinate' (water-filling UAV by
    UAV, fast, possibly short of the joint optimum: :mod:`.power`); relative_tolerance: a step
    gaining at most this share ends its loop; max_outer_iterations, max_inner_iterations: the
    loops' limits; starts: of :data:`FLEET_STARTS`; single: the settings of the single-UAV
    plans the starts are made of.
    """

    power_method: str = 'joint'
    relative_tolerance: float = 1e-4
    max_outer_iterations: int = 30
    max_inner_iterations: int = 30
    starts: tuple[str, ...] = FLEET_STARTS
    single: SolverSettings = field(default_factory=lambda: SolverSettings(screened_tours=20))

    def __post_init__(self) -> None:
        if self.power_method not in POWER_METHODS:
            raise InvalidScenarioError(f'power_method must be one of {tuple(POWER_METHODS)}, '
                                       f'got {self.power_method!r}')
        if not (isinstance(self.relative_tolerance, float) and
                0.0 < self.relative_tolerance < 1.0):
            raise InvalidScenarioError(
                f'relative_tolerance must be in (0, 1), got {self.relative_tolerance!r}')
        for name in ('max_outer_iterations', 'max_inner_iterations'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise InvalidScenarioError(f'{name} must be an integer >= 1, got {value!r}')
        starts = tuple(self.starts)
        if not starts or any(name not in FLEET_STARTS for name in starts):
            raise InvalidScenarioError(
                f'starts must name one or more of {FLEET_STARTS}, got {self.starts!r}')
        object.__setattr__(self, 'starts', starts)
        if not isinstance(self.single, SolverSettings):
            raise InvalidScenarioError('single must be SolverSettings')


@dataclass(frozen=True)
class FleetPlan:
    """A fleet's plan.

    trajectories: q (K, M, 2) metres; power: p (K, N, M) watts; rates: R_n (N,) bit/s, summed
    over the UAVs; min_throughput: min_n R_n, bit/s; history: the true min throughput after
    every power and trajectory step of the kept run (never decreasing); start: the kept run's
    start; start_throughputs: what each start reached, bit/s; single_throughputs: UAV k's
    single-UAV plan over all nodes from its own ends ('single k'), bit/s; left_out: the starts
    not run, with why; solve_time_s: wall time, seconds.
    """

    fleet: FleetScenario
    trajectories: np.ndarray
    power: np.ndarray
    rates: np.ndarray
    min_throughput: float
    history: tuple[Step, ...]
    start: str
    start_throughputs: dict[str, float]
    single_throughputs: dict[str, float]
    left_out: dict[str, str]
    outer_iterations: int = 0
    trajectory_steps: int = 0
    converged: bool = True
    solve_time_s: float = 0.0

    @property
    def times(self) -> np.ndarray:
        """(M,) seconds at which every UAV reaches q_k[m]."""
        return self.fleet.scenario.times_s

    @property
    def status(self) -> str:
        return 'converged' if self.converged else 'iteration limit'


@dataclass(frozen=True)
class _Run:
    q: np.ndarray
    p: np.ndarray
    history: tuple[Step, ...]
    outer: int
    inner: int
    converged: bool

    @property
    def value(self) -> float:
        return self.history[-1].min_throughput


def _power_solver(fleet: FleetScenario,
                  method: str) -> Callable[[np.ndarray, np.ndarray | None], np.ndarray]:
    budget = fleet.scenario.power_budget_w
    if method == 'coordinate':
        return lambda a, p: coordinate_power(a, budget, p=p).p
    return lambda a, p: POWER_METHODS[method](a, budget).p


def alternate(fleet: FleetScenario, q: np.ndarray, settings: FleetSettings,
              step: FleetStep) -> _Run:
    """The alternating loop from q (K, M, 2) metres, separated and within the speed limits."""
    power_of = _power_solver(fleet, settings.power_method)
    history: list[Step] = []

    def rate(bits: float) -> float:
        return float(spectral_efficiency_to_rate(np.float64(bits), fleet.scenario))

    def tolerance(bits: float) -> float:
        return settings.relative_tolerance * abs(bits)

    a = fleet_snr(q, fleet)
    p, value, previous, inner, converged, outer = None, -math.inf, -math.inf, 0, False, 0
    for outer in range(1, settings.max_outer_iterations + 1):
        p_new = power_of(a, p)
        new_value = common_value(a, p_new)
        if new_value >= value:          # the power step's round-off never lowers the objective
            p, value = p_new, new_value
        history.append(Step('power', rate(value)))
        if value - previous <= tolerance(value):
            converged = True
            break
        previous = value
        for _ in range(settings.max_inner_iterations):
            q_new = step(q, p)
            inner += 1
            if q_new is None:
                break
            a_new = fleet_snr(q_new, fleet)
            new_value = common_value(a_new, p)
            if new_value < value:
                logger.debug('fleet trajectory step lowered the objective; kept the old one')
                break
            history.append(Step('trajectory', rate(new_value)))
            gain = new_value - value
            q, a, value = q_new, a_new, new_value
            if gain <= tolerance(value):
                break
    else:
        p_new = power_of(a, p)
        if common_value(a, p_new) >= value:
            p, value = p_new, common_value(a, p_new)
            history.append(Step('power', rate(value)))
    return _Run(q, p, tuple(history), outer, inner, converged)


def _starts(fleet: FleetScenario, settings: FleetSettings
            ) -> tuple[dict[str, np.ndarray], dict[str, float], dict[str, str]]:
    """The starts by name, the single-UAV plans' throughputs, and the starts left out."""
    groups = partition(fleet)
    own = []
    for k, (vehicle, group) in enumerate(zip(fleet.vehicles, groups)):
        if group:
            nodes = [fleet.scenario.ground_nodes_m[n] for n in group]
            own.append(plan(vehicle.replace(ground_nodes_m=nodes), settings.single).trajectory)
        else:
            own.append(straight_start(vehicle))
    own = np.stack(own)
    lines = straight_lines(fleet)
    starts, singles, left_out = {}, {}, {}
    if 'partition' in settings.starts:
        separated = separate(own, fleet)
        if separated is None:
            left_out['partition'] = 'the push-apart found no separated trajectories'
        else:
            starts['partition'] = separated
    # One UAV's 'single 1' is its partition start (all nodes in its group), unless only
    # 'single' is asked for.
    if 'single' in settings.starts and (fleet.num_uavs > 1 or 'partition' not in starts):
        for k, vehicle in enumerate(fleet.vehicles):
            name = f'single {k + 1}'
            single = plan(vehicle, settings.single)
            singles[name] = single.min_throughput
            separated = None
            for others in (own, lines):         # the others' own tours, else straight lines
                q = others.copy()
                q[k] = single.trajectory
                separated = separate(q, fleet, fixed=(k,))
                if separated is not None:
                    break
            if separated is None:
                left_out[name] = (f'the push-apart found the other UAVs no place at '
                                  f'{fleet.min_separation_m:g} m from UAV {k + 1}\'s plan')
            else:
                starts[name] = separated
    return starts, singles, left_out


def check_budget(fleet: FleetScenario, settings: SolverSettings) -> None:
    """Refuse (:class:`~uav_comm_planner.errors.ComputeBudgetError`) a fleet whose K x N x M
    exceeds ``settings.max_node_slots``."""
    size = fleet.num_uavs * fleet.scenario.num_nodes * fleet.scenario.num_slots
    if size > settings.max_node_slots:
        raise ComputeBudgetError(
            f'problem too large: K x N x M = {fleet.num_uavs} UAVs x '
            f'{fleet.scenario.num_nodes} nodes x {fleet.scenario.num_slots} slots = {size} '
            f'exceeds the compute budget max_node_slots = {settings.max_node_slots}; '
            f'lower num_slots, the node count or the UAVs')


def plan_fleet(fleet: FleetScenario, settings: FleetSettings | None = None) -> FleetPlan:
    """Plan every UAV's trajectory and power jointly (module docstring).

    Raises :class:`~uav_comm_planner.errors.InvalidScenarioError` for a fleet or settings out of
    their domain (:class:`~uav_comm_planner.errors.ComputeBudgetError` when K x N x M exceeds
    ``settings.single.max_node_slots``), or when no start keeps the separation, and
    :class:`~uav_comm_planner.errors.SolverError` when a convex step fails.
    """
    began = time.perf_counter()
    if not isinstance(fleet, FleetScenario):
        raise InvalidScenarioError(f'plan_fleet needs a FleetScenario, got '
                                   f'{type(fleet).__name__}')
    settings = FleetSettings() if settings is None else settings
    if not isinstance(settings, FleetSettings):
        raise InvalidScenarioError(
            f'settings must be FleetSettings or None, got {type(settings).__name__}')
    settings.single.check(fleet.scenario)
    check_budget(fleet, settings.single)
    starts, singles, left_out = _starts(fleet, settings)
    if not starts:
        raise InvalidScenarioError(
            f'no start keeps the separation of {fleet.min_separation_m:g} m ('
            + '; '.join(left_out.values()) + '): lower min_separation_m or move the ends apart')
    step = FleetStep(fleet)
    runs = {}
    for name, q in starts.items():
        runs[name] = alternate(fleet, q, settings, step)
    best = max(runs, key=lambda name: runs[name].value)
    run = runs[best]
    rates = fleet_rates(run.q, run.p, fleet)
    return FleetPlan(
        fleet=fleet, trajectories=run.q, power=run.p, rates=rates,
        min_throughput=float(rates.min()), history=run.history, start=best,
        start_throughputs={name: r.value for name, r in runs.items()},
        single_throughputs=singles, left_out=left_out, outer_iterations=run.outer,
        trajectory_steps=run.inner, converged=run.converged,
        solve_time_s=time.perf_counter() - began)


__all__ = ['check_budget', 'FLEET_STARTS', 'FleetPlan', 'FleetSettings', 'plan_fleet']
