"""Plan requests and the one worker thread that plans them, newest request first.

No ROS here: the node hands :class:`PlanRequest` objects to a :class:`LatestOnlyWorker`,
which runs :func:`attempt` on its own thread and hands back a :class:`PlanOutcome`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import functools
import inspect
from pathlib import Path as FilePath
import threading
from typing import Callable, Generic, TypeVar

from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.core.receding import as_flown, FlownSlots, RecedingPlan, replan
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.errors import PlanCancelledError, PlannerError
from uav_comm_planner.ros.params import NodeSettings
from uav_comm_planner.vehicle.flyable import plan_for_vehicle, VehiclePlan
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink.files import export_mission

#: How long shutting down waits for a plan in progress before leaving it to its daemon thread.
WORKER_STOP_TIMEOUT_S = 5.0

#: (scenario, settings) -> plan; one that also takes the keyword ``should_stop`` (as the core's
#: plan() does) is asked to give up when a newer request arrives.
Planner = Callable[..., PlanResult]
Request = TypeVar('Request')


class LatestOnlyWorker(Generic[Request]):
    """Runs ``job`` on one thread, one request at a time; newer requests replace waiting ones.

    Nothing queues up: at most one request waits while a job runs, and it is the newest.
    A running job may ask :meth:`superseded` between its steps and give up when a newer
    request waits (or the worker stops). ``job`` must not raise.
    """

    def __init__(self, job: Callable[[Request], None], *, name: str) -> None:
        self._job = job
        self._condition = threading.Condition()
        self._waiting: Request | None = None
        self._stopping = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def submit(self, request: Request) -> bool:
        """Queue ``request`` in place of any waiting one; True if one was replaced."""
        with self._condition:
            replaced = self._waiting is not None
            self._waiting = request
            self._condition.notify()
        return replaced

    def superseded(self) -> bool:
        """True when the running job should give up: a newer request waits, or stopping."""
        return self._waiting is not None or self._stopping

    def stop(self, timeout_s: float = WORKER_STOP_TIMEOUT_S) -> None:
        """Drop any waiting request and wait up to ``timeout_s`` for the running job, which
        :meth:`superseded` asks to give up."""
        with self._condition:
            self._stopping = True
            self._waiting = None
            self._condition.notify()
        self._thread.join(timeout_s)

    def _next(self) -> Request | None:
        with self._condition:
            while self._waiting is None and not self._stopping:
                self._condition.wait()
            request, self._waiting = self._waiting, None
            return None if self._stopping else request

    def _run(self) -> None:
        while (request := self._next()) is not None:
            self._job(request)


@dataclass(frozen=True)
class RecedingRequest:
    """The rest of a mission in flight to replan (see :mod:`uav_comm_planner.core.receding`).

    position_m: where the rest starts; flown: the slots already flown (power mapped onto the
    mission's nodes); previous_q: the rest of the plan in force, one more start;
    segment: the plan in force (a :class:`~uav_comm_planner.ros.progress.Segment`), cut after
    ``slots_kept`` of its slots when the replan takes over.
    """

    position_m: tuple[float, float]
    flown: FlownSlots
    previous_q: object
    segment: object
    slots_kept: int


@dataclass(frozen=True)
class PlanRequest:
    """What to plan, the settings to publish it with, and its plan stamp.

    start_ns: the plan stamp (node clock, nanoseconds) on every output of the plan; the
    planned poses are stamped start_ns + their planned time. ``receding``: plan the rest of
    the mission in flight instead of the whole mission from ``start_m``.
    """

    scenario: Scenario
    settings: SolverSettings
    output: NodeSettings
    start_ns: int
    reason: str
    vehicle: VehicleLimits = VehicleLimits()
    receding: RecedingRequest | None = None


@dataclass(frozen=True)
class PlanOutcome:
    """A finished request: its plan, or the reason it failed, and the mission file written.

    ``result`` is the plan to publish: as the vehicle flies it when the request is
    vehicle-aware (``vehicle_plan`` then holds the optimiser's plan and the mission's timing).
    receding: for a replan of a mission in flight, what it promises for the whole mission.
    """

    request: PlanRequest
    result: PlanResult | None = None
    vehicle_plan: VehiclePlan | None = None
    error: str = ''
    mission_path: FilePath | None = None
    mission_error: str = ''
    cancelled: bool = False
    receding: RecedingPlan | None = None

    @property
    def min_throughput(self) -> float:
        """The min average throughput over the whole mission, bit/s."""
        if self.receding is not None:
            return self.receding.mission_min_throughput
        return float(self.result.min_throughput)


def write_mission(outcome: PlanOutcome, output: NodeSettings) -> FilePath:
    """Write an outcome's plan to ``output.mission_path`` (``mission_file`` inside
    ``mission_dir``); raises MissionExportError on failure."""
    return export_mission(outcome.vehicle_plan or outcome.result, output.mission_path,
                          output.home, end=output.mission_end,
                          firmware=output.mission_firmware, limits=outcome.request.vehicle)


def accepts_should_stop(planner: Callable[..., object]) -> bool:
    """Whether ``planner`` takes the keyword ``should_stop`` (as the core's plan() does)."""
    try:
        parameters = inspect.signature(planner).parameters.values()
    except (TypeError, ValueError):
        return False
    return any(p.name == 'should_stop' or p.kind is inspect.Parameter.VAR_KEYWORD
               for p in parameters)


def _plan_whole(planner: Planner,
                request: PlanRequest) -> tuple[VehiclePlan | None, PlanResult]:
    """The whole mission: for the vehicle (its plan as flown) or the optimiser's plan."""
    if not request.output.vehicle_aware:
        return None, planner(request.scenario, request.settings)
    vehicle_plan = plan_for_vehicle(request.scenario, request.vehicle, request.settings,
                                    firmware=request.output.mission_firmware, planner=planner)
    return vehicle_plan, vehicle_plan.flown


def _plan_rest(planner: Planner, request: PlanRequest, planned: list, scenario: Scenario,
               settings: SolverSettings | None, *, offsets=None,
               extra_starts=None) -> PlanResult:
    """The rest of a mission in flight, as :func:`~uav_comm_planner.core.receding.replan`
    asks for it: with the offsets; for the vehicle, the plan as flown with its power for the
    offsets (the vehicle plan is appended to ``planned``)."""
    optimiser = functools.partial(planner, offsets=offsets, extra_starts=extra_starts)
    if not request.output.vehicle_aware:
        return optimiser(scenario, settings)
    vehicle_plan = plan_for_vehicle(scenario, request.vehicle, settings,
                                    firmware=request.output.mission_firmware,
                                    planner=optimiser)
    planned.append(vehicle_plan)
    return as_flown(vehicle_plan.flown, offsets)


def attempt(planner: Planner, request: PlanRequest, *,
            should_stop: Callable[[], bool] | None = None) -> PlanOutcome:
    """Plan ``request`` and write its mission if asked; every failure becomes the outcome.

    ``should_stop``, when given, is passed on to the planner, which asks it between steps;
    a plan given up that way is an outcome with ``cancelled`` set. A vehicle-aware request
    is planned for its vehicle (the outcome's ``result`` is then the plan as flown); a
    request in flight replans the rest of the mission (the receding horizon).
    """
    if should_stop is not None:
        planner = functools.partial(planner, should_stop=should_stop)
    vehicle_plan = None
    receding = None
    try:
        if request.receding is None:
            vehicle_plan, result = _plan_whole(planner, request)
        else:
            rest = request.receding
            planned: list[VehiclePlan] = []
            receding = replan(request.scenario, rest.position_m, rest.flown, request.settings,
                              planner=functools.partial(_plan_rest, planner, request, planned),
                              previous_q=rest.previous_q)
            result = receding.result
            vehicle_plan = planned[-1] if planned else None
    except PlanCancelledError as exc:
        return PlanOutcome(request, error=str(exc), cancelled=True)
    except PlannerError as exc:
        return PlanOutcome(request, error=str(exc))
    except Exception as exc:  # noqa: B902 - a failed plan must not end the worker thread
        return PlanOutcome(request, error=f'unexpected {type(exc).__name__}: {exc}')
    outcome = PlanOutcome(request, result, vehicle_plan, receding=receding)
    if not request.output.mission_file:
        return outcome
    try:
        return replace(outcome, mission_path=write_mission(outcome, request.output))
    except PlannerError as exc:
        return replace(outcome, mission_error=str(exc))
