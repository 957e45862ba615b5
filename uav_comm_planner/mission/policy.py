"""Which plans a mission tries, and in what order, until the vehicle flies one on time.

The optimiser's plan moves at any speed up to V; the vehicle (:mod:`~uav_comm_planner.vehicle.
flyable`) may not fly it by the end of the horizon. What to try then is written here as data,
a :class:`PlanningPolicy`:

- the **planning speeds**, in order (1 and :data:`~uav_comm_planner.vehicle.flyable.
  SLOWER_PLANNING` shares of ``max_speed_mps``); at each, the optimiser's plan is tried first;
- the **fallbacks** at a speed where the vehicle cannot fly the optimiser's plan on time
  (:class:`Fallback`): a candidate plan from a :class:`Source` (the plan in force flown on, the
  optimiser at the next slower speed, the other tours), each taken at once when it flies and
  states within a share of the plan not flown, else the best flown of them;
- the **straight line** q0 -> qF as the last fallback, so that a request whose straight line
  fits the horizon is never refused;
- for the rest of a mission in flight, how many times the horizon is **lengthened** (by a share
  of its slots) when even that is late.

:data:`FIRST_PLAN` is a first plan's (and a replan's that searches again); :data:`WARM_REPLAN`
a warm replan's, which continues the plan in force. The sources are functions of a scenario and
settings that the mission layer (:mod:`~uav_comm_planner.mission.pipeline`) supplies;
:func:`plan_for_vehicle` runs a policy with them. The vehicle's schedule of each candidate is a
pure function of the plan and the vehicle's limits (:func:`~uav_comm_planner.vehicle.flyable.
vehicle_plan`).
"""

from __future__ import annotations

from dataclasses import dataclass
import enum
import time
from typing import Callable, Mapping

import numpy as np

from uav_comm_planner.core.optimizer import plan, PlanResult
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.errors import InfeasibleHorizonError, InvalidScenarioError, WalledInError
from uav_comm_planner.vehicle.firmware import firmware_named
from uav_comm_planner.vehicle.flyable import (check_speed, in_wind, SLOWER_PLANNING,
                                              straight_line_plan, vehicle_plan, VehiclePlan)
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.waypoints import zone_check

#: ``optimiser(scenario, settings) -> PlanResult`` (None: it has nothing to add here).
Optimiser = Callable[[Scenario, SolverSettings | None], PlanResult | None]

#: A warm replan's fallback within this share of the plan the vehicle cannot fly is taken as
#: it is (no wider search for a gain smaller than this).
WIDER_SEARCH_GAIN = 1e-3


class Source(enum.Enum):
    """Where a candidate plan comes from."""

    #: The request's optimiser: a first plan's search, a warm replan's continuation of the plan
    #: in force.
    OPTIMISER = 'optimiser'
    #: The plan in force flown on as it is from where the vehicle is (no trajectory step).
    PLAN_IN_FORCE = 'plan in force'
    #: The full search of the tours without the plan in force (a warm replan's other tours).
    OTHER_TOURS = 'other tours'


@dataclass(frozen=True)
class Fallback:
    """A candidate tried where the vehicle cannot fly the optimiser's plan at a speed.

    source: where it comes from; slower: planned this many speeds slower than the plan not
    flown (tried only where there is one, and a plan not flown); take_within: taken at once
    when the vehicle flies it and its throughput (``judged``: 'flown', as the vehicle flies
    it, or 'stated', as the optimiser states it) is within this share of the plan not flown
    (None: only ever one of those the best flown is chosen from).
    """

    source: Source
    slower: int = 0
    take_within: float | None = None
    judged: str = 'flown'

    def __post_init__(self) -> None:
        if self.judged not in ('flown', 'stated'):
            raise InvalidScenarioError(f"judged is 'flown' or 'stated', got {self.judged!r}")
        if self.slower < 0:
            raise InvalidScenarioError(f'slower is a count of speeds, got {self.slower!r}')


@dataclass(frozen=True)
class PlanningPolicy:
    """The plans tried for a vehicle, in order (module docstring)."""

    speed_shares: tuple[float, ...] = (1.0,) + SLOWER_PLANNING
    fallbacks: tuple[Fallback, ...] = ()
    straight_line: bool = True
    lengthen_attempts: int = 5
    lengthen_share: float = 0.1

    @property
    def sources(self) -> frozenset[Source]:
        """The sources this policy asks for."""
        return frozenset({Source.OPTIMISER, *(f.source for f in self.fallbacks)})


#: A first plan, and a replan that searches again: each speed's optimiser plan, then slower.
FIRST_PLAN = PlanningPolicy()
#: A warm replan: where the vehicle cannot fly the continued plan in force at a speed, the plan
#: in force flown on as it is, then the continuation at the next slower speed, each taken when
#: within :data:`WIDER_SEARCH_GAIN`; else the best flown of those and of the other tours.
WARM_REPLAN = PlanningPolicy(fallbacks=(
    Fallback(Source.PLAN_IN_FORCE, take_within=WIDER_SEARCH_GAIN, judged='flown'),
    Fallback(Source.OPTIMISER, slower=1, take_within=WIDER_SEARCH_GAIN, judged='stated'),
    Fallback(Source.OTHER_TOURS)))


class _Attempts:
    """Each source's plan at each planning speed, planned at most once; ``errors``: why each
    plan that was refused or not flyable was, in the order met."""

    def __init__(self, scenario: Scenario, limits: VehicleLimits, settings: SolverSettings | None,
                 firmware: str, sources: Mapping[Source, Optimiser], shares: tuple[float, ...]):
        self.errors: list[Exception] = []
        self._scenario, self._limits, self._settings = scenario, limits, settings
        self._firmware, self._sources, self._shares = firmware, sources, shares
        self._tried: dict[tuple[Source, int], tuple[PlanResult | None, VehiclePlan | None]] = {}

    def __call__(self, source: Source, step: int) -> tuple[PlanResult | None, VehiclePlan | None]:
        """The ideal plan of ``source`` at speed ``step`` (None when refused or not given) and
        the vehicle's plan of it (None when the vehicle cannot fly it on time)."""
        key = (source, step)
        if key not in self._tried:
            self._tried[key] = self._plan(self._sources.get(source), self._shares[step])
        return self._tried[key]

    def _plan(self, optimiser: Optimiser | None, share: float
              ) -> tuple[PlanResult | None, VehiclePlan | None]:
        if optimiser is None:
            return None, None
        scenario = self._scenario
        try:
            ideal = optimiser(scenario if share == 1.0 else scenario.replace(
                max_speed_mps=share * scenario.max_speed_mps), self._settings)
            if ideal is None:
                return None, None
        except WalledInError:
            raise                           # no slower speed finds a way round the zones
        except InfeasibleHorizonError as exc:
            self.errors.append(exc)
            return None, None
        try:
            return ideal, vehicle_plan(ideal, self._limits, firmware=self._firmware)
        except InfeasibleHorizonError as exc:
            self.errors.append(exc)
            return ideal, None


def _fallen_back(policy: PlanningPolicy, attempts: _Attempts, step: int,
                 ideal: PlanResult | None) -> VehiclePlan | None:
    """The policy's fallbacks at ``step``, where the vehicle cannot fly ``ideal`` (None: the
    optimiser refused): the first taken within its share, else the best flown of those tried
    (ties to the later), None when none flies."""
    tried = []
    for fallback in policy.fallbacks:
        if fallback.slower and (ideal is None
                                or step + fallback.slower >= len(policy.speed_shares)):
            continue
        candidate, flown = attempts(fallback.source, step + fallback.slower)
        if flown is None:
            continue
        tried.append(flown)
        judged = (flown.flown if fallback.judged == 'flown' else candidate).min_throughput
        if (fallback.take_within is not None and ideal is not None
                and judged >= ideal.min_throughput * (1 - fallback.take_within)):
            return flown
    return max(reversed(tried), key=lambda p: p.flown.min_throughput) if tried else None


def plan_for_vehicle(scenario: Scenario, limits: VehicleLimits | None = None,
                     settings: SolverSettings | None = None, *, firmware: str = 'ardupilot',
                     sources: Mapping[Source, Optimiser] | Optimiser = plan,
                     policy: PlanningPolicy = FIRST_PLAN) -> VehiclePlan:
    """Plan ``scenario`` for a vehicle with ``limits`` (None: ``firmware``'s defaults,
    :meth:`VehicleLimits.for_firmware`) by ``policy`` (module docstring): the mission and what
    it delivers. ``sources`` gives each source's optimiser (a single optimiser: the
    :attr:`Source.OPTIMISER`; a source not given has nothing to add).

    In wind (``scenario.wind_speed_mps`` > 0) the plan keeps the vehicle's airspeed
    (:attr:`VehicleLimits.airspeed_mps`, unless the scenario gives its own) and every leg is
    flown at a ground speed it holds on its slowest heading. The ideal plan returned at a
    slower speed carries the slower scenario. With zones, no leg of the mission is straightened
    across them, and the straight line is no fallback where it crosses one. Raises
    :class:`~uav_comm_planner.errors.InfeasibleHorizonError` before solving when the planning
    speed exceeds the vehicle's, or the wind the vehicle's airspeed, and when not even the
    straight line fits the horizon (saying the horizon it needs).
    """
    began = time.perf_counter()
    firmware_named(firmware)                 # an unknown name is refused before any solve
    limits = VehicleLimits.for_firmware(firmware) if limits is None else limits
    if callable(sources):
        sources = {Source.OPTIMISER: sources}
    check_speed(scenario, limits)
    scenario = in_wind(scenario, limits)
    attempts = _Attempts(scenario, limits, settings, firmware, sources, policy.speed_shares)
    for step in range(len(policy.speed_shares)):
        ideal, flown = attempts(Source.OPTIMISER, step)
        if flown is None:
            flown = _fallen_back(policy, attempts, step, ideal)
        if flown is not None:
            return flown.timed_from(began)
    first_error = attempts.errors[0] if attempts.errors else None
    keeps = zone_check(scenario.zones)
    if not policy.straight_line or (keeps is not None and not keeps(
            np.asarray(scenario.start_m, float), np.asarray(scenario.goal_m, float))):
        if first_error is None:
            raise InfeasibleHorizonError('no plan of this request flies on time')
        raise first_error                   # the straight line would cross a zone
    return straight_line_plan(scenario, limits, settings, firmware, sources[Source.OPTIMISER],
                              first_error).timed_from(began)


__all__ = ['FIRST_PLAN', 'Fallback', 'Optimiser', 'PlanningPolicy', 'Source', 'WARM_REPLAN',
           'WIDER_SEARCH_GAIN', 'plan_for_vehicle']
