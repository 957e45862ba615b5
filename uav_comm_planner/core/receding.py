"""Receding horizon: replan the rest of a mission without forgetting what it already did.

A mission is the letter's problem over M slots of delta = T / M seconds with budget P_T. After
k elapsed slots, flown at positions q[1..k] with power p_n[m], node n holds

    D_n = delta sum_{m<=k} (B/N) log2(1 + p_n[m] a_n[m])      bits,

and sum_{m<=k} sum_n p_n[m] of the budget is spent. The replan chooses the remaining M' = M - k
waypoints (from the UAV's position to qF, same delta) and their power to maximise the whole
mission's min average throughput

    min_n (D_n + delta sum_{m>k} (B/N) log2(1 + p_n[m] a_n[m])) / T

subject to sum_{m>k} sum_n p_n[m] <= P_T - sum_{m<=k} sum_n p_n[m]. Dividing by (B/N) M' delta,
it is the letter's problem on the remaining slots with an offset per node,

    maximise min_n (o_n + mean_{m>k} log2(1 + p_n[m] a_n[m])),  o_n = D_n / (delta (B/N) M'),

which the water-filling (node n needs only (c - o_n)^+ for a common value c) and the SCA
bound (plus the constant o_n) solve unchanged (:func:`~uav_comm_planner.core.optimizer.plan`
with ``offsets``). The whole mission's rate is then R_n = (B/N) (o_n + mean_{m>k} ...) M' / M.
With no elapsed slot the offsets are zero and the replan is the letter's problem exactly.

Notation: p (N, k) watts, positions (k, 2) metres, D (N,) bits.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
import math
from typing import Callable, Sequence

import numpy as np

from uav_comm_planner.core import detour
from uav_comm_planner.core.energy import horizon_energy_j, JOULES_PER_WH
from uav_comm_planner.core.feasibility import retimed, within_speed_limit
from uav_comm_planner.core.model import snr_per_watt, spectral_efficiencies
from uav_comm_planner.core.optimizer import plan, plan_along, PlanResult, ZoneKeeper
from uav_comm_planner.core.plan_options import PlanOptions
from uav_comm_planner.core.scenario import DUPLICATE_NODE_DISTANCE_M, Scenario, SolverSettings
from uav_comm_planner.errors import InfeasibleHorizonError, InvalidScenarioError


@dataclass(frozen=True)
class FlownSlots:
    """The k elapsed slots of a mission, as the transmitter used them.

    power_w: p_n[m] (N, k) watts, for the nodes of the mission being replanned (a node that
    was not served in a slot has 0 there; :func:`power_for_nodes` maps a schedule onto a new
    node set); positions_m: (k, 2) metres, where the UAV was at each slot's time (flown, or
    as planned when no telemetry has it).
    """

    power_w: np.ndarray
    positions_m: np.ndarray

    def __post_init__(self) -> None:
        power = np.array(self.power_w, dtype=float, ndmin=2)
        positions = np.array(self.positions_m, dtype=float).reshape(-1, 2)
        if power.shape[1] != positions.shape[0]:
            raise InvalidScenarioError(
                f'flown slots: {power.shape[1]} slots of power but {positions.shape[0]} '
                f'positions; give one position per slot')
        if not (np.all(np.isfinite(power)) and np.all(np.isfinite(positions))):
            raise InvalidScenarioError('flown slots: power and positions must be finite')
        if np.any(power < 0.0):
            raise InvalidScenarioError('flown slots: power must be >= 0 W')
        for array in (power, positions):
            array.setflags(write=False)
        object.__setattr__(self, 'power_w', power)
        object.__setattr__(self, 'positions_m', positions)

    @classmethod
    def none(cls, num_nodes: int) -> 'FlownSlots':
        """No slot elapsed yet, for ``num_nodes`` nodes."""
        return cls(np.zeros((num_nodes, 0)), np.zeros((0, 2)))

    @property
    def num_slots(self) -> int:
        """k."""
        return int(self.power_w.shape[1])

    @property
    def energy_w(self) -> float:
        """sum_{m<=k} sum_n p_n[m]: the part of the budget P_T spent (the letter's units, W)."""
        return float(self.power_w.sum())

    def then(self, power_w: np.ndarray, positions_m: np.ndarray) -> 'FlownSlots':
        """These slots followed by more: power (N, j) watts at positions (j, 2) metres."""
        return FlownSlots(np.hstack([self.power_w, np.array(power_w, dtype=float, ndmin=2)]),
                          np.vstack([self.positions_m, np.reshape(positions_m, (-1, 2))]))


def power_for_nodes(from_nodes_m: Sequence[Sequence[float]], power_w: np.ndarray,
                    to_nodes_m: Sequence[Sequence[float]]) -> np.ndarray:
    """A schedule p (N0, k) for nodes ``from_nodes_m`` (N0, 2) seen by nodes ``to_nodes_m``
    (N1, 2): (N1, k) watts, a node's row where it is the same node (within
    DUPLICATE_NODE_DISTANCE_M), zeros for a node that was not served."""
    source = np.reshape(np.asarray(from_nodes_m, dtype=float), (-1, 2))
    target = np.reshape(np.asarray(to_nodes_m, dtype=float), (-1, 2))
    power = np.array(power_w, dtype=float, ndmin=2)
    mapped = np.zeros((len(target), power.shape[1]))
    if len(source) == 0:
        return mapped
    gaps = np.linalg.norm(target[:, None, :] - source[None, :, :], axis=-1)
    nearest = gaps.argmin(axis=1)
    same = gaps[np.arange(len(target)), nearest] < DUPLICATE_NODE_DISTANCE_M
    mapped[same] = power[nearest[same]]
    return mapped


def delivered_bits(mission: Scenario, flown: FlownSlots) -> np.ndarray:
    """D_n = delta sum_{m<=k} (B/N) log2(1 + p_n[m] a_n[m]) at the flown positions: (N,) bits."""
    if flown.power_w.shape[0] != mission.num_nodes:
        raise InvalidScenarioError(
            f'flown slots: power for {flown.power_w.shape[0]} nodes, the mission has '
            f'{mission.num_nodes}; map it with power_for_nodes')
    if flown.num_slots == 0:
        return np.zeros(mission.num_nodes)
    a = snr_per_watt(flown.positions_m, mission)
    bits_per_use = spectral_efficiencies(a, flown.power_w) * flown.num_slots
    return mission.slot_s * mission.bandwidth_hz / mission.num_nodes * bits_per_use


def rest_of_mission(mission: Scenario, position_m: Sequence[float], flown: FlownSlots, *,
                    energy_left_wh: float | None = None) -> Scenario:
    """The remaining M - k slots from ``position_m`` (:func:`clear_start`) to qF, same
    delta, with the budget left, and the energy budget left (:func:`flown_energy_wh`) when the
    mission has one; ``energy_left_wh``, when given, is the energy budget of the rest instead
    (measured: what the vehicle's battery has left for it, :mod:`uav_comm_planner.mission.
    battery`), whether or not the mission had one.

    Raises :class:`~uav_comm_planner.errors.InfeasibleHorizonError` when no slot remains or
    qF is out of reach, :class:`~uav_comm_planner.errors.InvalidScenarioError` when the
    budget is spent.
    """
    remaining = mission.num_slots - flown.num_slots
    if remaining < 1:
        raise InfeasibleHorizonError(
            f'the mission horizon is over ({flown.num_slots} of {mission.num_slots} slots '
            f'flown): start a new mission')
    budget_left = mission.power_budget_w - flown.energy_w
    if not budget_left > 0.0:
        raise InvalidScenarioError(
            f'the power budget is spent ({flown.energy_w:.6g} W of P_T = '
            f'{mission.power_budget_w:g} W in {flown.num_slots} slots): start a new mission')
    if remaining == mission.num_slots and tuple(position_m) == tuple(mission.start_m):
        return mission
    changes = dict(start_m=clear_start(mission, position_m), num_slots=remaining,
                   horizon_s=remaining * mission.slot_s, power_budget_w=budget_left)
    if energy_left_wh is not None:
        return _with_energy_left(mission, changes, energy_left_wh, flown)
    if mission.energy_budget_wh is None:
        return mission.replace(**changes)
    used_wh = flown_energy_wh(mission, flown)
    if not used_wh < mission.energy_budget_wh:
        raise InfeasibleHorizonError(
            f'the energy budget is spent: {used_wh:.4g} of {mission.energy_budget_wh:.4g} Wh '
            f'used in {flown.num_slots} slots; land, or start a new mission')
    try:
        return mission.replace(**changes, energy_budget_wh=mission.energy_budget_wh - used_wh)
    except InfeasibleHorizonError as exc:
        raise InfeasibleHorizonError(
            f'the energy budget left is too little for the rest: {used_wh:.4g} of '
            f'{mission.energy_budget_wh:.4g} Wh used in {flown.num_slots} slots; {exc}') \
            from None


def _with_energy_left(mission: Scenario, changes: dict, energy_left_wh: float,
                      flown: FlownSlots) -> Scenario:
    """The rest (``changes`` to ``mission``) with the energy budget ``energy_left_wh``."""
    if not energy_left_wh > 0.0:
        raise InfeasibleHorizonError(
            f'no energy is left for the rest: {energy_left_wh:.4g} Wh after {flown.num_slots} '
            f'slots; land, or start a new mission')
    try:
        return mission.replace(**changes, energy_budget_wh=energy_left_wh)
    except InfeasibleHorizonError as exc:
        raise InfeasibleHorizonError(
            f'the energy left, {energy_left_wh:.4g} Wh after {flown.num_slots} slots, is too '
            f'little for the rest; {exc}') from None


def flown_energy_wh(mission: Scenario, flown: FlownSlots) -> float:
    """The propulsion energy of the k flown legs q0 -> p_1 -> ... -> p_k (the slots'
    positions), each over one slot at its airspeed in the mission's wind, by the mission's
    airframe (:mod:`uav_comm_planner.core.energy`), Wh; 0 before the first slot."""
    if flown.num_slots == 0:
        return 0.0
    path = np.vstack([np.reshape(mission.start_m, (1, 2)), flown.positions_m])
    airspeed = np.linalg.norm(np.diff(path, axis=0) / mission.slot_s - mission.wind_mps, axis=1)
    return float(mission.airframe.level_power_w(airspeed).sum() * mission.slot_s
                 / JOULES_PER_WH)


#: The farthest :func:`clear_start` moves a replan's start: the node's radius for holding q0
#: (``ros.flight.START_RADIUS_M``), so that the vehicle where it was asked is still at the
#: new q0 and its first leg is not longer than the plan says by more than that.
CLEAR_START_MAX_M = 2.5


def clear_start(mission: Scenario, position_m: Sequence[float]) -> tuple[float, float]:
    """Where the rest of ``mission`` starts from ``position_m``: the position itself, or, when
    it is closer to a zone's edge than the margin but not in a zone (a vehicle tracking a plan
    that keeps the margin exactly drifts a little inside it), the nearest point that keeps the
    margin (:func:`~uav_comm_planner.core.detour.outside_point`) when that is at most
    :data:`CLEAR_START_MAX_M` away; the vehicle flies there first. A position in a zone, or
    farther in, is kept (and refused by the scenario)."""
    position = (float(position_m[0]), float(position_m[1]))
    zones = mission.zones
    if zones is None or zones.empty:
        return position
    clearance = float(zones.clearance([position])[0])
    if clearance >= zones.margin_m or clearance < 0.0:
        return position
    moved = detour.outside_point(zones, np.asarray(position))
    if moved is None or math.dist(moved, position) > CLEAR_START_MAX_M:
        return position
    return float(moved[0]), float(moved[1])


def lengthened(mission: Scenario, position_m: Sequence[float], flown: FlownSlots, *,
               extra_slots: int = 0) -> Scenario:
    """``mission`` with the fewest more slots of its delta that let its rest reach qF from
    ``position_m`` after the slots ``flown`` at the speed limit (the straight line at the
    fastest ground speed towards qF), plus ``extra_slots``; ``mission`` itself when its rest
    reaches qF already and no extra slot is asked. A mission that cannot keep qF in time is
    promised over a longer horizon (its whole-mission rates averaged over it) instead of
    being refused; but never lengthened by more than its own slots at once (qF farther than
    that stays refused by :func:`rest_of_mission`, goal unreachable)."""
    remaining = mission.num_slots - flown.num_slots
    distance = math.dist(position_m, mission.goal_m)
    needed = 1
    if distance > 0.0:
        direction = (np.asarray(mission.goal_m, float) - np.asarray(position_m, float)) / distance
        fastest = mission.fastest_ground_speed_mps(direction)
        if fastest > 0.0:
            # The rest of M' slots flies M' + 1 legs of delta seconds (the scenario's check).
            step = fastest * mission.slot_s
            needed = max(math.ceil(distance / step) - 1, 1)
            while distance > (needed + 1) * step * (1 + 1e-12):
                needed += 1
    extra = max(needed - remaining, 0) + extra_slots
    if extra == 0 or remaining < 1 or extra > mission.num_slots:
        return mission
    slots = mission.num_slots + extra
    return mission.replace(num_slots=slots, horizon_s=slots * mission.slot_s)


@dataclass(frozen=True)
class RecedingPlan:
    """A replan of the rest of a mission and what it promises for the whole mission.

    result: the plan of :func:`rest_of_mission` (its trajectory, times and power cover the
    remaining slots only; its rates count the offsets, see :class:`PlanResult`);
    delivered_bits: D_n (N,) bits before the replan; offsets: o (N,) bits per use;
    mission_rates: R_n (N,) bit/s over the whole mission; mission_min_throughput: min_n R_n.
    """

    mission: Scenario
    flown: FlownSlots
    result: PlanResult
    delivered_bits: np.ndarray
    offsets: np.ndarray
    mission_rates: np.ndarray
    mission_min_throughput: float

    @property
    def mission_energy_w(self) -> float:
        """sum of p over every slot, flown and planned: at most P_T."""
        return self.flown.energy_w + float(self.result.power.sum())


Planner = Callable[..., PlanResult]


#: Name of the start that continues the previous plan (see :func:`replan`).
PREVIOUS_PLAN_START = 'previous'
#: The starts of a warm replan besides the previous plan (:meth:`RecedingProblem.for_scenario`).
WARM_STARTS = ('hover',)
#: How many starts of a warm replan get an SCA step before one is continued: the best by its
#: power step (:attr:`~uav_comm_planner.core.scenario.SolverSettings.shortlist`).
WARM_SHORTLIST = 1


def rejoined(previous_q: np.ndarray, position_m: Sequence[float],
             rest: Scenario) -> np.ndarray | None:
    """The rest of the plan in force, ``previous_q`` (M', 2) metres, flown from
    ``position_m``: straight at the fastest ground speed to its first point j it can reach by
    slot j (a point the UAV is already at is reached in its own slot), then as planned. None when
    it has not the rest's M' slots or reaches none of its points in time (qF is checked by the
    caller, :func:`~uav_comm_planner.core.feasibility.within_speed_limit`)."""
    previous = np.asarray(previous_q, dtype=float)
    if previous.shape != (rest.num_slots, 2) or not np.all(np.isfinite(previous)):
        return None
    position = np.asarray(position_m, dtype=float)
    gaps = previous - position
    distances = np.linalg.norm(gaps, axis=1)
    for j, (gap, distance) in enumerate(zip(gaps, distances)):
        speed = (rest.fastest_ground_speed_mps(gap / distance) if distance > 0.0
                 else rest.max_speed_mps)
        if distance <= (j + 1) * speed * rest.slot_s * (1 - 1e-9):
            joined = previous.copy()
            joined[:j + 1] = position + np.arange(1, j + 2)[:, None] / (j + 1) * gap
            return joined
    return None


@dataclass(frozen=True)
class RecedingProblem:
    """The rest of a mission as the optimiser must solve it, and how its answer counts.

    rest: :func:`rest_of_mission`; delivered_bits: D_n (N,) bits so far; offsets: o (N,) bits
    per use, D_n over the rest's slots; previous_start: the rest of the plan in force,
    :func:`rejoined` from the UAV's position, when it keeps the speed limit and the zones
    (None: no plan in force, or none that gives a start); warm: whether the replan continues
    that start instead of searching the tours again (:meth:`for_scenario`).
    """

    mission: Scenario
    flown: FlownSlots
    rest: Scenario
    delivered_bits: np.ndarray
    offsets: np.ndarray
    previous_start: np.ndarray | None = None
    warm: bool = False

    @property
    def options(self) -> PlanOptions:
        """The optimiser's options for :attr:`rest`: the offsets, and the plan in force as
        one more start (:data:`PREVIOUS_PLAN_START`) when it gives one."""
        options = PlanOptions(offsets=self.offsets)
        if self.previous_start is None:
            return options
        return options.with_starts(**{PREVIOUS_PLAN_START: self.previous_start})

    def start_for(self, scenario: Scenario) -> np.ndarray | None:
        """The plan in force as a start for ``scenario`` (:attr:`rest`, or a slower one that
        a vehicle-aware plan tries): :attr:`previous_start`, :func:`~uav_comm_planner.core.
        feasibility.retimed` when ``scenario`` is slower than it (its path flown at the slower
        pace, its stops shortened, since the optimiser would otherwise blend it towards the
        straight line); None when it gives none."""
        start = self.previous_start
        if start is not None and not within_speed_limit(start, scenario):
            start = retimed(start, scenario)
            if start is not None and not _keeps_zones(start, scenario):
                start = None
        return start

    def for_scenario(self, settings: SolverSettings | None, scenario: Scenario | None = None,
                     *, warm: bool | None = None) -> tuple[SolverSettings | None, PlanOptions]:
        """The optimiser's settings and options for this replan of ``scenario`` (:attr:`rest`,
        or a slower one that a vehicle-aware plan tries); ``warm`` False asks a warm replan
        for the other tours: the full search without the plan in force, which the warm search
        has just continued (None: :attr:`warm`).

        The plan in force is one more start (:meth:`start_for`). A warm replan then runs that
        start and the hover start (:data:`WARM_STARTS`) with no screened tours:
        the plan in force already is the best tour the screening found for these nodes (under
        an energy budget, the straight line too), and
        the replan only moves its start to where the UAV is, so continuing it (one SCA step
        per power step, as the default continues its best tour) gives at least what flying on
        with it would, in a few trajectory steps instead of the screening's tours. That
        is what lets a replan in flight come back within a fraction of a second. Its steps
        keep the path no longer than they find it (``keep_path_length``): the plan in force
        was planned at the speed the vehicle flies it at on time, and a continuation free to
        lengthen it spends the slack the vehicle's corners and stops need (on an N = 20,
        M = 500 mission, 9 s late at qF where the plan in force was on time). Only the better
        of the two starts by its power step gets an SCA step (:data:`WARM_SHORTLIST`): giving
        both one, as a first plan does its shortlist, changed none of 49 replans measured
        (N = 4-20, M = 100-500) and cost one SOCP of the four or five of a replan. Where the
        previous plan gives no start for ``scenario``, the tours are screened as usual.
        """
        scenario = self.rest if scenario is None else scenario
        options = PlanOptions(offsets=self.offsets)
        if self.warm and warm is False:
            return settings, options
        start = self.start_for(scenario)
        if start is None:
            return settings, options
        options = options.with_starts(**{PREVIOUS_PLAN_START: start})
        if not self.warm:
            return settings, options
        # Under an energy budget the straight line is the start that costs least; without it,
        # a budget the plan in force and hovering exceed would be refused (and the rest
        # lengthened, which only costs more energy).
        starts = WARM_STARTS + (('straight',) if scenario.energy_budget_wh is not None else ())
        return dataclasses.replace(settings or SolverSettings(), starts=starts,
                                   screened_tours=0, keep_path_length=True,
                                   shortlist=WARM_SHORTLIST), options

    def kept(self, scenario: Scenario | None = None,
             settings: SolverSettings | None = None) -> PlanResult | None:
        """The plan in force flown on as it is from where the UAV is (its start for
        ``scenario``, :meth:`start_for`), with the power optimal for it and no trajectory
        step: what going on with it gives. None when it gives no start for ``scenario``."""
        scenario = self.rest if scenario is None else scenario
        start = self.start_for(scenario)
        if start is None:
            return None
        return plan_along(scenario, start, settings, name=PREVIOUS_PLAN_START,
                          offsets=self.offsets)

    def outcome(self, result: PlanResult) -> RecedingPlan:
        """What the plan ``result`` of :attr:`rest` (its rates counting the offsets) promises
        for the whole mission."""
        share = self.rest.num_slots / self.mission.num_slots
        mission_rates = np.asarray(result.rates, dtype=float) * share
        return RecedingPlan(mission=self.mission, flown=self.flown, result=result,
                            delivered_bits=self.delivered_bits, offsets=self.offsets,
                            mission_rates=mission_rates,
                            mission_min_throughput=float(mission_rates.min()))


def _over_budget(q: np.ndarray, scenario: Scenario) -> bool:
    """Whether ``q`` needs more than the scenario's energy budget (False without one)."""
    return (scenario.energy_budget_wh is not None and horizon_energy_j(
        q, scenario, scenario.airframe) > scenario.energy_budget_wh * JOULES_PER_WH)


def _keeps_zones(q: np.ndarray, scenario: Scenario) -> bool:
    return scenario.zones is None or scenario.zones.empty or ZoneKeeper(scenario).keeps(q)


def receding_problem(mission: Scenario, position_m: Sequence[float], flown: FlownSlots, *,
                     previous_q: np.ndarray | None = None, warm: bool = False,
                     energy_left_wh: float | None = None) -> RecedingProblem:
    """The rest of ``mission`` from ``position_m`` after the slots ``flown``, as a problem for
    the optimiser (module docstring). ``previous_q`` (M - k, 2) metres, the rest of the plan
    being flown, becomes one more start, :func:`rejoined` from ``position_m``, when that keeps
    the speed limit (and the zones); with ``warm`` (the plan in force serves the same nodes,
    and keeps the rest's energy budget if it has one) the replan then continues it
    (:meth:`RecedingProblem.for_scenario`). Raises the errors of :func:`rest_of_mission`
    (``energy_left_wh``: the rest's energy budget, measured)."""
    rest = rest_of_mission(mission, position_m, flown, energy_left_wh=energy_left_wh)
    delivered = delivered_bits(mission, flown)
    per_use = rest.slot_s * rest.bandwidth_hz / rest.num_nodes * rest.num_slots
    offsets = delivered / per_use
    start = None if previous_q is None else rejoined(previous_q, rest.start_m, rest)
    if start is not None and not (within_speed_limit(start, rest) and _keeps_zones(start, rest)):
        start = None
    if start is not None and _over_budget(start, rest):
        warm = False        # the plan in force is no tour to continue: search them again
    return RecedingProblem(mission=mission, flown=flown, rest=rest, delivered_bits=delivered,
                           offsets=offsets, previous_start=start,
                           warm=bool(warm) and start is not None)


def replan(mission: Scenario, position_m: Sequence[float], flown: FlownSlots,
           settings: SolverSettings | None = None, *, planner: Planner = plan,
           previous_q: np.ndarray | None = None, warm: bool = False,
           energy_left_wh: float | None = None, **plan_options) -> RecedingPlan:
    """Plan the rest of ``mission`` from ``position_m`` after the slots ``flown``.

    Maximises the whole mission's min average throughput under the whole mission's budget
    (module docstring). ``previous_q`` (M - k, 2) metres, the rest of the plan being flown,
    is one more start for Algorithm 1 (:func:`rejoined` from ``position_m``) when it keeps the
    speed limit: the replan then promises at least what going on with it would give; ``warm``
    continues it instead of screening the tours again (:meth:`RecedingProblem.for_scenario`).
    ``plan_options`` go to ``planner`` (:func:`plan`: ``power_method``,
    ``trajectory_method``). With no flown slot and ``position_m`` = q0 it returns the letter's
    plan exactly. ``energy_left_wh``: the rest's energy budget, measured
    (:func:`rest_of_mission`). Raises the errors of :func:`rest_of_mission` and of the planner.
    """
    problem = receding_problem(mission, position_m, flown, previous_q=previous_q, warm=warm,
                               energy_left_wh=energy_left_wh)
    settings, options = problem.for_scenario(settings)
    result = planner(problem.rest, settings, **options.keywords(), **plan_options)
    return problem.outcome(result)


def mission_rates_flown(mission: Scenario, power_w: np.ndarray,
                        positions_m: np.ndarray) -> np.ndarray:
    """R_n (N,) bit/s of a whole mission from every slot's power (N, M) and position (M, 2):
    (1/T) sum_m delta (B/N) log2(1 + p_n[m] a_n[m]); slots not flown count as no data."""
    flown = FlownSlots(power_w, positions_m)
    return delivered_bits(mission, flown) / mission.horizon_s


__all__ = ['CLEAR_START_MAX_M', 'PREVIOUS_PLAN_START', 'WARM_STARTS', 'FlownSlots', 'RecedingPlan',
           'RecedingProblem',
           'delivered_bits', 'lengthened', 'mission_rates_flown', 'power_for_nodes',
           'clear_start', 'flown_energy_wh', 'receding_problem', 'rejoined', 'replan',
           'rest_of_mission']
