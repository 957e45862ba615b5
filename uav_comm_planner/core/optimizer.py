"""Algorithm 1 of the letter: alternate the power step and the SCA trajectory loop."""

from __future__ import annotations

from dataclasses import dataclass, field
import functools
import logging
import math
import time
from typing import Callable, Mapping, Sequence

import numpy as np

from uav_comm_planner.core import detour, search
from uav_comm_planner.core.bound import dual_upper_bound
from uav_comm_planner.core.feasibility import project_onto_speed_limit
from uav_comm_planner.core.model import (average_rates, best_snr_per_watt, flown_path, LN2,
                                         snr_per_watt, spectral_efficiencies,
                                         spectral_efficiency_to_rate)
from uav_comm_planner.core.power import checked_offsets, waterfilling_power, waterfilling_powers
from uav_comm_planner.core.sca.block import BlockFactory
from uav_comm_planner.core.sca.program import no_start_error, start_filter
from uav_comm_planner.core.sca.reference import trajectory_step_cvxpy
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.core.search import Run, Step
from uav_comm_planner.core.steps import PowerSolver, step_solvers, TrajectorySolver
from uav_comm_planner.core.tours import distinct_tours, tour_draws
from uav_comm_planner.core.zone_rows import zone_model
from uav_comm_planner.errors import InvalidScenarioError, PlanCancelledError, SolverError

logger = logging.getLogger(__name__)

#: Asked between steps; True gives the plan up with :class:`PlanCancelledError`.
StopCheck = Callable[[], bool]


@dataclass(frozen=True)
class Start:
    """An initial trajectory for Algorithm 1: its ``name`` (as plans report it) and ``make``,
    which gives q (M, 2) metres for a scenario."""

    name: str
    make: Callable[[Scenario], np.ndarray] = field(repr=False, compare=False)

    @classmethod
    def given(cls, name: str, q: np.ndarray) -> 'Start':
        """A start that is the trajectory q (M, 2) metres itself, whatever the scenario."""
        trajectory = np.array(q, dtype=float)
        trajectory.setflags(write=False)
        return cls(name, lambda scenario: trajectory.copy())


#: Initial trajectories, by the names :attr:`SolverSettings.starts` uses (with zones, the
#: path around them and the tour outside them: :mod:`uav_comm_planner.core.detour`).
STARTS: dict[str, Start] = {
    'straight': Start('straight', detour.straight_start),
    'hover': Start('hover', detour.hover_start),
}


@dataclass(frozen=True)
class PlanResult:
    """A plan and how it was obtained.

    trajectory: q (M, 2) metres; times: (M,) seconds at which q[m] is reached;
    power: p (N, M) watts; rates: R_n (N,) bit/s; min_throughput: min_n R_n, bit/s;
    history: the true min rate after every power and trajectory step (never decreasing);
    baselines: min throughput of the straight line ('straight') and the static access point
    ('static'), each with its optimal power, bit/s.
    start: the initial trajectory of the kept plan ('straight', 'hover', a screened
    'tour k' of :func:`~uav_comm_planner.core.tours.random_tours`, 'tour k resplit' for that
    tour with its hover split searched (:mod:`.splits`), or an extra start's name);
    start_throughputs: the min throughput Algorithm 1 reached from each start tried, bit/s
    (for a screened start not continued, where its screening left it);
    upper_bound: :func:`throughput_upper_bound`, no plan can exceed it, bit/s (inf with
    offsets, where it does not hold);
    solve_time_s: wall time of the whole plan (every start and the baselines), seconds.
    offsets: o (N,) bits per use credited to each node before this plan (None: none, the
    letter's problem). With offsets, rates, min_throughput, history and baselines all count
    them: R_n = (B/N) (o_n + mean_m log2(1 + p_n[m] a_n[m])) (see
    :mod:`uav_comm_planner.core.receding`).
    """

    scenario: Scenario
    trajectory: np.ndarray
    times: np.ndarray
    power: np.ndarray
    rates: np.ndarray
    min_throughput: float
    history: tuple[Step, ...]
    baselines: dict[str, float] = field(default_factory=dict)
    outer_iterations: int = 0
    trajectory_steps: int = 0
    converged: bool = True
    solve_time_s: float = 0.0
    start: str = 'straight'
    upper_bound: float = math.inf
    start_throughputs: dict[str, float] = field(default_factory=dict)
    offsets: np.ndarray | None = None

    @property
    def status(self) -> str:
        return 'converged' if self.converged else 'iteration limit'

    @property
    def gap_to_upper_bound(self) -> float:
        """1 - min_throughput / upper_bound: the share of the bound not (yet) reached."""
        return 1.0 - self.min_throughput / self.upper_bound

    @functools.cached_property
    def tight_upper_bound(self) -> float:
        """The Lagrangian dual bound over every flyable trajectory
        (:func:`~uav_comm_planner.core.bound.dual_upper_bound`, at this plan's multipliers),
        or :attr:`upper_bound` where that is lower; no plan exceeds it, bit/s (inf with
        offsets). Computed on first use (0.1 to 1 s)."""
        if self.offsets is not None:
            return math.inf
        a = snr_per_watt(self.trajectory, self.scenario)
        return min(self.upper_bound, dual_upper_bound(self.scenario, self.power, a))

    @property
    def gap_to_tight_bound(self) -> float:
        """1 - min_throughput / tight_upper_bound: at most this share of the optimum is left."""
        return 1.0 - self.min_throughput / self.tight_upper_bound


def _tolerance(settings: SolverSettings, value: float) -> float:
    return max(settings.tolerance_bps, settings.relative_tolerance * abs(value))


def _offset_keywords(offsets: np.ndarray | None) -> dict[str, np.ndarray]:
    """``offsets=`` for a step only when there are offsets, so that any solver with the
    letter's signature serves the letter's problem."""
    return {} if offsets is None else {'offsets': offsets}


def optimal_power(q: np.ndarray, scenario: Scenario,
                  power_solver: PowerSolver = waterfilling_power, *,
                  offsets: np.ndarray | None = None) -> np.ndarray:
    """The max-min power schedule p (N, M) watts for a fixed trajectory q (M, 2)."""
    return power_solver(snr_per_watt(q, scenario), scenario.power_budget_w,
                        **_offset_keywords(offsets)).p


def baseline_rates(scenario: Scenario, power_solver: PowerSolver = waterfilling_power, *,
                   offsets: np.ndarray | None = None) -> dict[str, float]:
    """The letter's benchmarks, each with its optimal power: min throughput in bit/s. With
    zones, the straight line is the path around them and the static point the nearest one
    outside them (:mod:`uav_comm_planner.core.detour`)."""
    rates = {}
    for name, q in (('straight', detour.straight_start(scenario)),
                    ('static', detour.static_start(scenario))):
        p = optimal_power(q, scenario, power_solver, offsets=offsets)
        rates[name] = float(average_rates(q, p, scenario, offsets).min())
    return rates


def alternate(scenario: Scenario, q: np.ndarray, settings: SolverSettings, *,
              power_solver: PowerSolver = waterfilling_power,
              trajectory_solver: TrajectorySolver = trajectory_step_cvxpy,
              should_stop: StopCheck | None = None,
              offsets: np.ndarray | None = None, sca_steps: int | None = None) -> Run:
    """Algorithm 1 from trajectory q (M, 2) metres, as a :class:`Run`.

    Each outer iteration solves the power step, then runs SCA trajectory steps until one
    gains at most the tolerance; it stops when a power step gains at most the tolerance over
    the previous one (the letter's rule). A last power step on the final trajectory follows,
    which can only raise the objective (left out when no trajectory step followed the last
    power step). A trajectory step that would lower the true minimum
    rate (possible only through solver round-off) is discarded and ends its loop. Every
    trajectory is projected onto the speed limit (:func:`~uav_comm_planner.core.feasibility.
    project_onto_speed_limit`), so solver
    round-off never lets a leg exceed V delta; with zones, a step that solver round-off left
    below their margin is moved back towards the trajectory it started from
    (:class:`ZoneKeeper`), and the start must keep them.
    ``should_stop`` is asked before every step;
    when it returns True the run ends with :class:`~uav_comm_planner.errors.PlanCancelledError`.
    With ``offsets`` o (N,) bits per use, every step maximises min_n (o_n + mean_m log2(...)).
    ``sca_steps`` caps the SCA steps per power step (``settings.max_inner_iterations`` when
    None).
    """
    history: list[Step] = []
    check_stop = stop_checker(should_stop)
    offsets = checked_offsets(offsets, scenario.num_nodes)
    extra = _offset_keywords(offsets)

    def min_rate(a_now: np.ndarray, p_now: np.ndarray) -> float:
        efficiencies = spectral_efficiencies(a_now, p_now, offsets)
        return float(spectral_efficiency_to_rate(efficiencies.min(), scenario))

    def power_step(a_now: np.ndarray) -> tuple[np.ndarray, float]:
        check_stop()
        allocation = power_solver(a_now, scenario.power_budget_w, **extra)
        # The allocation's efficiency is min_n mean_m log2(1 + p a) of its own p.
        value = float(spectral_efficiency_to_rate(allocation.efficiency, scenario))
        history.append(Step('power', value))
        return allocation.p, value

    q = project_onto_speed_limit(q, scenario)
    keep = _zone_keeper(scenario)
    if keep is not None:
        keep.check_start(q)
    a = snr_per_watt(q, scenario)
    previous_power_value = -np.inf
    inner_total = 0
    converged = False
    outer = 0
    p = None
    for outer in range(1, settings.max_outer_iterations + 1):
        p, value = power_step(a)
        if value - previous_power_value <= _tolerance(settings, value):
            converged = True
            break
        previous_power_value = value
        for _ in range(settings.max_inner_iterations if sca_steps is None else sca_steps):
            check_stop()
            step = trajectory_solver(q, p, scenario, **extra)
            inner_total += 1
            q_new = project_onto_speed_limit(step.q, scenario)
            if keep is not None:
                q_new = keep(q_new, q)
            a_new = snr_per_watt(q_new, scenario)
            new_value = min_rate(a_new, p)
            if new_value < value:
                logger.debug('trajectory step lowered the objective by %.3g; kept the old one',
                             value - new_value)
                break
            history.append(Step('trajectory', new_value))
            gain = new_value - value
            q, a, value = q_new, a_new, new_value
            if gain <= _tolerance(settings, value):
                break
    else:
        if history[-1].kind == 'trajectory':   # else the last power step is on this trajectory
            p, value = power_step(a)
    if p is None:
        raise SolverError('Algorithm 1 ran no iteration; max_outer_iterations must be >= 1')
    return Run(q, p, tuple(history), outer, inner_total, converged)


class ZoneKeeper:
    """Keeps every trajectory of Algorithm 1 out of the zones by their margin, exactly.

    A step's answer q meets the restriction at q^k to the solver's tolerance, and the
    restriction asks for :data:`~uav_comm_planner.core.zone_rows.ZONE_CUSHION_M` more than
    the margin, so q nearly always keeps it. When it does not, the restriction's rows at level
    margin (half-planes, each of which q^k keeps) hold on the blend (1 - lam) q + lam q^k for
    lam = max over the rows of -s(q) / (s(q^k) - s(q)), s a row's slack; the blend also keeps
    the speed limits, which both keep (the limits are convex).
    """

    def __init__(self, scenario: Scenario):
        self.scenario = scenario
        self.model = zone_model(scenario.zones)

    def _clear(self, q: np.ndarray) -> bool:
        """Whether every leg of the path of q (M, 2) keeps the margin, to round-off."""
        path = flown_path(q, self.scenario)
        margin = self.scenario.zones.margin_m
        return bool(detour.segments_clear(self.scenario.zones, path[:-1], path[1:],
                                          margin_m=margin * (1 - 1e-9) - 1e-9).all())

    def keeps(self, q: np.ndarray) -> bool:
        """Whether q (M, 2) metres, projected onto the speed limits, keeps the margin (to
        round-off)."""
        q = np.asarray(q, dtype=float)
        if q.shape != (self.scenario.num_slots, 2) or not np.isfinite(q).all():
            return False
        return self._clear(project_onto_speed_limit(q, self.scenario))

    def check_start(self, q: np.ndarray) -> None:
        """Refuse a start that does not keep the zones' margin."""
        if not self._clear(q):
            zones = self.scenario.zones
            clearance = zones.path_clearance(flown_path(q, self.scenario))
            raise InvalidScenarioError(
                f'the start trajectory comes within {clearance:.3f} m of a zone, the margin is '
                f'{zones.margin_m:g} m: start from a path that keeps out of the zones')

    def __call__(self, q: np.ndarray, q_k: np.ndarray) -> np.ndarray:
        rows = self.model.rows(flown_path(q_k, self.scenario), cushion_m=0.0)
        new, old = rows.slack(q), rows.slack(q_k)
        short = new < 0.0
        if not short.any():
            return q
        lam = float(np.max(-new[short] / np.maximum(old[short] - new[short], 1e-300)))
        lam = min(1.0, lam * (1 + 1e-9) + 1e-12)
        return (1.0 - lam) * q + lam * q_k


def _zone_keeper(scenario: Scenario) -> ZoneKeeper | None:
    if scenario.zones is None or scenario.zones.empty:
        return None
    return ZoneKeeper(scenario)


def letter_rules(settings: SolverSettings) -> SolverSettings:
    """The letter's Algorithm 1 (:meth:`SolverSettings.letter`) within the iteration limits of
    ``settings``: the rules of the straight start's first run."""
    return SolverSettings.letter(max_outer_iterations=settings.max_outer_iterations,
                                 max_inner_iterations=settings.max_inner_iterations,
                                 max_nodes=settings.max_nodes,
                                 max_node_slots=settings.max_node_slots,
                                 compute_baselines=False)


def throughput_upper_bound(scenario: Scenario) -> float:
    """An upper bound of the max-min throughput, bit/s: (B/N) log2(1 + a_max P_T / (N M)).

    a_max (:func:`~uav_comm_planner.core.model.best_snr_per_watt`, N beta0 / (H^2 B sigma^2)
    in free space) is the SNR per watt right above a node. For any plan,
    node n's rate is (B/N) mean_m log2(1 + p_n[m] a_n[m]) <= (B/N) mean_m log2(1 + p_n[m] a_max)
    <= (B/N) log2(1 + a_max P_n / M) by Jensen's inequality, with P_n = sum_m p_n[m]; the node
    with the least P_n has P_n <= P_T / N, so min_n R_n is at most the bound.
    """
    n, m = scenario.num_nodes, scenario.num_slots
    bits = math.log1p(best_snr_per_watt(scenario) * scenario.power_budget_w / (n * m)) / LN2
    return float(spectral_efficiency_to_rate(np.float64(bits), scenario))


def stop_checker(should_stop: StopCheck | None) -> Callable[[], None]:
    """A check that raises PlanCancelledError when ``should_stop`` (None: never) says so."""
    def check() -> None:
        if should_stop is not None and should_stop():
            raise PlanCancelledError('plan cancelled between steps: a newer request came')
    return check


def plan(scenario: Scenario, settings: SolverSettings | None = None, *,
         power_method: str = 'waterfilling', trajectory_method: str = 'clarabel',
         should_stop: StopCheck | None = None, offsets: np.ndarray | None = None,
         extra_starts: Mapping[str, np.ndarray] | None = None,
         blocks: Sequence[BlockFactory] = ()) -> PlanResult:
    """Jointly optimise the trajectory and the transmit power for ``scenario``.

    Runs the letter's Algorithm 1 from every start in ``settings.starts`` (by default the
    straight line q0 -> qF at uniform speed and
    :func:`~uav_comm_planner.core.initial.hover_and_fly`) and ``settings.screened_tours``
    random tours, and returns the best as a :class:`PlanResult`; ties go to the earlier start.
    With screened tours or ``fast_steps`` (the default) the starts are screened and the best
    continued (:func:`.search.screened_runs`), the straight start being the letter's own run;
    otherwise each start is run to convergence. The default methods are the exact
    water-filling power step and the SCA step on a Clarabel solver updated in place (kept
    across plans of one size);
    ``power_method='conic', trajectory_method='cvxpy'`` rebuilds cvxpy problems every step
    (the reference). Raises
    :class:`~uav_comm_planner.errors.InvalidScenarioError` for a scenario outside the limits of
    ``settings`` (among them the compute budget N x M, checked before any work),
    :class:`~uav_comm_planner.errors.SolverError` when a convex step fails and
    :class:`~uav_comm_planner.errors.PlanCancelledError` when ``should_stop`` (asked between
    steps) returns True.

    ``offsets`` o (N,), bits per use, credit each node with data it already holds (the
    receding horizon, :func:`uav_comm_planner.core.receding.replan`); all zero is the same
    as none, the letter's problem exactly. ``extra_starts`` adds initial trajectories
    (M, 2) metres by name (for example the rest of the previous plan; a name of
    ``settings.starts`` is replaced by the trajectory given); each should keep the speed
    limit, since Algorithm 1 only improves on its start (projected onto it otherwise).

    With ``scenario.zones`` every slot point and every leg of every trajectory keeps out of
    the zones by their margin: the starts go round them (:mod:`uav_comm_planner.core.detour`),
    each SCA step adds their restriction (:mod:`uav_comm_planner.core.zone_rows`), and an extra
    start that does not keep them is left out. A request with no way round the zones within
    the horizon raises :class:`~uav_comm_planner.errors.InfeasibleHorizonError`.
    """
    if settings is None:
        settings = SolverSettings()
    elif not isinstance(settings, SolverSettings):
        raise InvalidScenarioError(
            f'settings must be SolverSettings or None, got {type(settings).__name__}')
    settings.check(scenario)
    if should_stop is not None and not callable(should_stop):
        raise InvalidScenarioError(f'should_stop must be callable, got {should_stop!r}')
    check_stop = stop_checker(should_stop)
    offsets = checked_offsets(offsets, scenario.num_nodes)
    with detour.asking(check_stop):
        prepare_zones(scenario, check_stop)
        return _best_plan(scenario, settings, power_method, trajectory_method, should_stop,
                          check_stop, offsets, extra_starts, tuple(blocks))


def prepare_zones(scenario: Scenario, check_stop: Callable[[], None]) -> None:
    """With zones, build their visibility graph (:func:`~uav_comm_planner.core.detour.
    corner_graph`: the work that grows with their corners) first, asking ``check_stop`` between
    its chunks, so that a plan cancelled while it is built stops there; the starts and paths
    around the zones then use the graph kept."""
    if scenario.zones is not None and not scenario.zones.empty:
        detour.corner_graph(scenario.zones, check_stop)


def _best_plan(scenario: Scenario, settings: SolverSettings, power_method: str,
               trajectory_method: str, should_stop: StopCheck | None,
               check_stop: Callable[[], None], offsets: np.ndarray | None,
               extra_starts: Mapping[str, np.ndarray] | None,
               blocks: tuple[BlockFactory, ...] = ()) -> PlanResult:
    """:func:`plan`'s work once its arguments are checked."""
    began = time.perf_counter()
    power_solver, trajectory_solver = step_solvers(scenario, power_method, trajectory_method,
                                                   keep_path_length=settings.keep_path_length,
                                                   blocks=blocks)
    starts = {name: STARTS[name] for name in settings.starts}
    keeper = _zone_keeper(scenario)
    for name, trajectory in (extra_starts or {}).items():
        if keeper is not None and not keeper.keeps(trajectory):
            logger.info('start %r left out: it does not keep out of the zones', name)
            continue
        starts[name] = Start.given(name, trajectory)
    admitted = start_filter(scenario, blocks)
    run_from = functools.partial(alternate, scenario, power_solver=power_solver,
                                 trajectory_solver=trajectory_solver, should_stop=should_stop,
                                 offsets=offsets)
    if settings.fast_steps or settings.screened_tours:
        draws = tour_draws(scenario, settings.screened_tours)
        tours = {name: q for name, q in distinct_tours(scenario, draws).items() if name not in
                 starts and (keeper is None or keeper.keeps(q))}    # none crossing a zone
        if blocks or scenario.energy_budget_wh is not None:
            tours = {name: q for name, q in tours.items() if admitted(q)}
            starts = {name: start for name, start in starts.items()
                      if admitted(start.make(scenario))}
        if not starts and not tours:
            raise no_start_error(scenario, STARTS['straight'].make(scenario))
        starts.update({name: Start.given(name, q) for name, q in tours.items()})
        extra = _offset_keywords(offsets)

        def value_of(a: np.ndarray) -> float:     # one power step on a: its efficiency
            check_stop()
            return waterfilling_power(a, scenario.power_budget_w, **extra).efficiency

        def screened(qs: Mapping[str, np.ndarray]) -> dict[str, Run]:
            check_stop()         # what alternate() gives with one power step, for each q
            allocations = _power_steps(scenario, list(qs.values()), power_solver, offsets)
            return {name: Run(q, allocation.p, (Step('power', float(
                spectral_efficiency_to_rate(allocation.efficiency, scenario))),), 1, 0, False)
                for (name, q), allocation in zip(qs.items(), allocations)}
        runs = search.screened_runs(
            scenario, {name: start.make for name, start in starts.items()},
            {name for name, start in starts.items() if start is STARTS['straight']},
            letter_rules(settings), settings, run_from, trajectory_solver,
            {name: draws[name] for name in tours}, screened, value_of,
            closed_form=scenario.power_budget_w if offsets is None else None)
    else:
        starts = {name: start for name, start in starts.items()
                  if admitted(start.make(scenario))}
        if not starts:
            raise no_start_error(scenario, STARTS['straight'].make(scenario))
        runs = {name: run_from(start.make(scenario), settings) for name, start in starts.items()}
    order = list(runs)
    values = {name: run.min_throughput for name, run in runs.items()}
    best = max(values, key=lambda name: (values[name], -order.index(name)))
    run = runs[best]
    q, p = run.q, run.p
    rates = average_rates(q, p, scenario, offsets)
    check_stop()
    baselines = (baseline_rates(scenario, power_solver, offsets=offsets)
                 if settings.compute_baselines else {})
    return PlanResult(
        scenario=scenario, trajectory=q, times=scenario.times_s, power=p, rates=rates,
        min_throughput=float(rates.min()), history=run.history, baselines=baselines,
        outer_iterations=run.outer_iterations, trajectory_steps=run.trajectory_steps,
        converged=run.converged,
        solve_time_s=time.perf_counter() - began, start=best,
        upper_bound=(throughput_upper_bound(scenario) if offsets is None else math.inf),
        start_throughputs=values, offsets=offsets)


def _power_steps(scenario: Scenario, trajectories: Sequence[np.ndarray],
                 power_solver: PowerSolver, offsets: np.ndarray | None) -> list:
    """The power step on each trajectory (M, 2) metres: the allocations, in order; the
    water-filling step of the letter's problem for all at once (:func:`~uav_comm_planner.
    core.power.waterfilling_powers`)."""
    if power_solver is not waterfilling_power or offsets is not None or not trajectories:
        return [power_solver(snr_per_watt(q, scenario), scenario.power_budget_w,
                             **_offset_keywords(offsets)) for q in trajectories]
    a = snr_per_watt(np.concatenate(trajectories), scenario)          # (N, K M)
    stacked = a.reshape(scenario.num_nodes, len(trajectories), scenario.num_slots)
    return waterfilling_powers(np.ascontiguousarray(stacked.transpose(1, 0, 2)),
                               scenario.power_budget_w)


def plan_along(scenario: Scenario, q: np.ndarray, settings: SolverSettings | None = None, *,
               name: str, offsets: np.ndarray | None = None) -> PlanResult:
    """The plan that flies the trajectory q (M, 2) metres of ``scenario`` as it is, with the
    power optimal for it: no trajectory step (``start`` is ``name``; the baselines as
    ``settings`` asks); ``offsets`` as in :func:`plan`. Unlike :func:`plan` it checks neither
    ``settings``' limits nor that q keeps the speed limit: q is a plan already made (the
    plan in force, a flown prediction)."""
    settings = SolverSettings() if settings is None else settings
    offsets = checked_offsets(offsets, scenario.num_nodes)
    began = time.perf_counter()
    q = np.asarray(q, dtype=float)
    p = optimal_power(q, scenario, offsets=offsets)
    rates = average_rates(q, p, scenario, offsets)
    value = float(rates.min())
    baselines = (baseline_rates(scenario, offsets=offsets) if settings.compute_baselines
                 else {})
    return PlanResult(
        scenario=scenario, trajectory=q, times=scenario.times_s, power=p, rates=rates,
        min_throughput=value, history=(Step('power', value),), baselines=baselines,
        solve_time_s=time.perf_counter() - began, start=name,
        upper_bound=(throughput_upper_bound(scenario) if offsets is None else math.inf),
        start_throughputs={name: value}, offsets=offsets)


__all__ = ['PlanResult', 'Run', 'Start', 'Step', 'StopCheck', 'alternate',
           'baseline_rates', 'letter_rules', 'optimal_power', 'plan', 'plan_along',
           'prepare_zones', 'step_solvers',
           'spectral_efficiency_to_rate', 'stop_checker', 'throughput_upper_bound']
