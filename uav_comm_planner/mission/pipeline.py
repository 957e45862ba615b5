"""The one planning pipeline: plan, make the plan flyable, build its mission items once.

:func:`plan_mission` is what the node's worker and the ``uav-comm-planner plan`` command both
call, so that the same request gives the same plan and the same items on either route:

1. the optimiser (the core's :func:`~uav_comm_planner.core.optimizer.plan`, or any function
   of the same signature) plans the whole mission, or the rest of a mission in flight by the
   receding horizon (:mod:`uav_comm_planner.core.receding`); a rest that cannot keep qF in
   time is lengthened by whole slots until it can (the mission's promise slows, stated over
   the longer horizon, instead of the replan being refused);
2. for a vehicle-aware request, :func:`~uav_comm_planner.vehicle.flyable.plan_for_vehicle`
   times it for the vehicle and the plan returned is the plan as flown;
3. the mission items are built from that plan, once; writing a mission file or uploading it
   uses these items. With zones, items whose legs enter a keep-out zone or leave the
   operating area are not built (``items_error`` gives the clearance); the zones' fence
   items are built beside them (uploaded before the mission), and a .plan file carries the
   zones as its geoFence.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math
import os
from pathlib import Path
import time
from typing import Callable

from uav_comm_planner.core.optimizer import (plan, plan_along, PlanResult, prepare_zones,
                                             stop_checker)
from uav_comm_planner.core.plan_options import PlanOptions
from uav_comm_planner.core.receding import (lengthened, receding_problem, RecedingPlan,
                                            RecedingProblem)
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.errors import (InfeasibleHorizonError, InvalidScenarioError, PlannerError,
                                     WalledInError)
from uav_comm_planner.files import OutputFolder
from uav_comm_planner.mission.policy import (FIRST_PLAN, Optimiser, plan_for_vehicle,
                                             PlanningPolicy, Source, WARM_REPLAN)
from uav_comm_planner.mission.request import MissionRequest
from uav_comm_planner.vehicle.fence import fence_from_zones
from uav_comm_planner.vehicle.flyable import VehiclePlan
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.mavlink.fence import fence_items, mission_clearance
from uav_comm_planner.vehicle.mavlink.files import write_mission_file
from uav_comm_planner.vehicle.mavlink.items import build_mission_items, MissionItem

#: ``planner(scenario, settings, **options) -> PlanResult``, with the keywords of the core's
#: plan() (``should_stop``, ``offsets``, ``extra_starts``).
Planner = Callable[..., PlanResult]
#: The start name of a rest of mission that a stream caught up.
CAUGHT_UP = 'caught up'


@dataclass(frozen=True)
class MissionPlan:
    """A planned mission.

    result: the plan to publish (as the vehicle flies it, for a vehicle-aware request);
    vehicle_plan: the optimiser's plan and the mission's timing (vehicle-aware requests);
    receding: for a replan in flight, what it promises for the whole mission; items: the
    mission items (None when not asked for, or when they cannot be built: ``items_error``
    then says why; the plan itself stands); fence: the fence items of the plan's zones, with
    the items (None without zones).
    """

    request: MissionRequest
    result: PlanResult
    vehicle_plan: VehiclePlan | None = None
    receding: RecedingPlan | None = None
    items: tuple[MissionItem, ...] | None = None
    items_error: str = ''
    fence: tuple[MissionItem, ...] | None = None

    @property
    def optimised(self) -> PlanResult:
        """The optimiser's plan: the ideal plan of a vehicle-aware request, else ``result``."""
        return self.result if self.vehicle_plan is None else self.vehicle_plan.ideal

    @property
    def min_throughput(self) -> float:
        """The min average throughput over the whole mission, bit/s."""
        if self.receding is not None:
            return self.receding.mission_min_throughput
        return float(self.result.min_throughput)

    def for_output(self, *, home: Home, end: str, firmware: str) -> 'MissionPlan':
        """This plan with its items for another home, mission end or firmware (a change of
        output settings after planning); itself when they are the same."""
        request = self.request
        if (home, end, firmware) == (request.home, request.end, request.firmware) \
                and request.items:
            return self
        request = replace(request, home=home, end=end, firmware=firmware, items=True)
        return replace(self, request=request,
                       **_items(request, self.vehicle_plan or self.result))

    def write(self, path: str | os.PathLike, *, folder: OutputFolder | None = None) -> Path:
        """Write the mission items as the file ``path`` (.waypoints or .plan; with ``folder``
        a bare name inside it), atomically; raises
        :class:`~uav_comm_planner.errors.MissionExportError` (or the reason the items could
        not be built) on failure."""
        if self.items is None:
            raise PlannerError(self.items_error or 'this plan was made without mission items')
        return write_mission_file(self.items, path, self.request.home,
                                  firmware=self.request.firmware, folder=folder,
                                  zones=self.request.planned_scenario.zones)


def plan_mission(request: MissionRequest, *, planner: Planner = plan,
                 should_stop: Callable[[], bool] | None = None) -> MissionPlan:
    """Plan ``request`` (module docstring); ``should_stop`` is passed on to the planner, which
    asks it between steps, and to the building of the paths around the zones (which is done
    first, :func:`~uav_comm_planner.core.optimizer.prepare_zones`). Raises the planner's
    errors (:class:`~uav_comm_planner.errors.PlannerError` and its subclasses)."""
    options = PlanOptions(should_stop=should_stop)
    prepare_zones(request.planned_scenario, stop_checker(should_stop))
    if request.in_flight is None:
        result, vehicle_plan = _plan_scenario(request, request.planned_scenario,
                                              _sources(planner, options), FIRST_PLAN)
        receding = None
    else:
        result, vehicle_plan, receding = _plan_rest(request, planner, options)
    items = _items(request, vehicle_plan or result) if request.items else {}
    return MissionPlan(request, result, vehicle_plan, receding, **items)


def _sources(planner: Planner, options: PlanOptions,
             problem: RecedingProblem | None = None) -> dict[Source, Optimiser]:
    """The candidate plans' sources (:class:`~uav_comm_planner.mission.policy.Source`) for a
    request: ``planner`` with ``options``; for the rest of a mission in flight, with
    ``problem``'s settings and options for each scenario tried (:meth:`~uav_comm_planner.core.
    receding.RecedingProblem.for_scenario`), the plan in force flown on
    (:meth:`~uav_comm_planner.core.receding.RecedingProblem.kept`) and the other tours."""
    def optimiser(scenario: Scenario, settings: SolverSettings | None) -> PlanResult:
        asked = options
        if problem is not None:
            settings, asked = problem.for_scenario(settings, scenario)
            asked = replace(asked, should_stop=options.should_stop)
        return planner(scenario, settings, **asked.keywords())

    def other_tours(scenario: Scenario, settings: SolverSettings | None) -> PlanResult | None:
        if problem.for_scenario(settings, scenario)[0] is settings:
            return None                     # the optimiser searched them all at this speed
        wider, asked = problem.for_scenario(settings, scenario, warm=False)
        asked = replace(asked, should_stop=options.should_stop)
        return planner(scenario, wider, **asked.keywords())

    if problem is None or not problem.warm:
        return {Source.OPTIMISER: optimiser}
    return {Source.OPTIMISER: optimiser, Source.PLAN_IN_FORCE: problem.kept,
            Source.OTHER_TOURS: other_tours}


def _plan_scenario(request: MissionRequest, scenario: Scenario,
                   sources: dict[Source, Optimiser], policy: PlanningPolicy
                   ) -> tuple[PlanResult, VehiclePlan | None]:
    """``scenario`` planned for ``request``: by its optimiser, or for a vehicle-aware request
    by ``policy`` with ``sources`` (:func:`~uav_comm_planner.mission.policy.plan_for_vehicle`)."""
    if not request.vehicle_aware:
        return sources[Source.OPTIMISER](scenario, request.settings), None
    vehicle_plan = plan_for_vehicle(scenario, request.vehicle, request.settings,
                                    firmware=request.firmware, sources=sources, policy=policy)
    return vehicle_plan.flown, vehicle_plan


def _plan_rest(request: MissionRequest, planner: Planner, options: PlanOptions
               ) -> tuple[PlanResult, VehiclePlan | None, RecedingPlan]:
    """The rest of a mission in flight; when qF cannot be kept in time (by the speed limit,
    or by the vehicle's timing), the mission is lengthened by whole slots until it can (the
    policy's ``lengthen_attempts`` times at most, each by its ``lengthen_share`` of the
    slots), and the plan promises the whole mission over that longer horizon. A warm replan
    continues the plan in force (:data:`~uav_comm_planner.mission.policy.WARM_REPLAN`)."""
    began = time.perf_counter()
    rest = request.in_flight
    if rest.caught_up is not None:
        return _caught_up(request, began)
    mission = lengthened(rest.mission(request.planned_scenario), rest.position_m, rest.flown)
    attempts = 0
    while True:
        problem = receding_problem(mission, rest.position_m, rest.flown,
                                   previous_q=rest.previous_q, warm=rest.warm,
                                   energy_left_wh=rest.energy_left_wh)
        policy = WARM_REPLAN if problem.warm else FIRST_PLAN
        try:
            result, vehicle_plan = _plan_scenario(request, problem.rest,
                                                  _sources(planner, options, problem), policy)
        except WalledInError:
            raise                           # no longer horizon finds a way round the zones
        except InfeasibleHorizonError:
            attempts += 1
            if attempts > policy.lengthen_attempts:
                raise
            more = max(1, math.ceil(problem.rest.num_slots * policy.lengthen_share))
            mission = lengthened(mission, rest.position_m, rest.flown, extra_slots=more)
            continue
        # The plan's solve time is the whole replan's, the shorter horizons tried included.
        if vehicle_plan is not None:
            vehicle_plan = vehicle_plan.timed_from(began)
            result = vehicle_plan.flown
        else:
            result = replace(result, solve_time_s=time.perf_counter() - began)
        return result, vehicle_plan, problem.outcome(result)


def _caught_up(request: MissionRequest, began: float
               ) -> tuple[PlanResult, None, RecedingPlan]:
    """The rest of a mission in flight as a stream that caught up the plan in force flies it
    (:mod:`uav_comm_planner.mission.catch_up`): its points as they are, the power optimal
    for them with the data delivered so far; no vehicle timing (the stream keeps the time)."""
    rest = request.in_flight
    problem = receding_problem(rest.mission(request.planned_scenario), rest.position_m,
                               rest.flown)
    result = plan_along(problem.rest, rest.caught_up, request.settings, name=CAUGHT_UP,
                        offsets=problem.offsets)
    result = replace(result, solve_time_s=time.perf_counter() - began)
    return result, None, problem.outcome(result)


def _items(request: MissionRequest, planned: VehiclePlan | PlanResult) -> dict:
    """``items`` and ``fence`` (or ``items_error``) of a :class:`MissionPlan` for
    ``request``."""
    try:
        items = tuple(build_mission_items(planned, request.home, end=request.end,
                                          firmware=request.firmware, limits=request.vehicle))
    except PlannerError as exc:
        return {'items': None, 'fence': None, 'items_error': str(exc)}
    zones = request.planned_scenario.zones
    if zones is None or zones.empty:
        return {'items': items, 'fence': None}
    clearance = mission_clearance(items, request.home, zones)
    if clearance < 0:
        return {'items': None, 'fence': None, 'items_error': (
            f'the mission\'s legs enter the zones: their least clearance is '
            f'{clearance:.2f} m (a keep-out zone entered or the operating area left); '
            f'no mission is written or uploaded')}
    try:
        fence = tuple(fence_items(fence_from_zones(zones, request.home)))
    except InvalidScenarioError as exc:
        return {'items': None, 'fence': None, 'items_error': f'the zones make no fence: {exc}'}
    return {'items': items, 'fence': fence}


__all__ = ['CAUGHT_UP', 'MissionPlan', 'Planner', 'plan_mission']
