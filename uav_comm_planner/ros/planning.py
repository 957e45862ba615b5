"""The node's plan requests, the worker that plans them off the executor, and the outcomes.

A :class:`PlanRequest` is a :class:`~uav_comm_planner.mission.request.MissionRequest` with
what the node needs to publish it (its output settings, its stamp, why it was asked).
:class:`PlanningWorker` plans one at a time on its own thread, the newest first, through the
one pipeline (:func:`~uav_comm_planner.mission.pipeline.plan_mission`), writes the mission
file when asked, and hands each :class:`PlanOutcome` back to the executor.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import os
from pathlib import Path as FilePath
from typing import Callable

from rclpy.node import Node

from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.core.receding import RecedingPlan
from uav_comm_planner.errors import PlanCancelledError, PlannerError
from uav_comm_planner.files import OutputFolder
from uav_comm_planner.mission.pipeline import MissionPlan, plan_mission, Planner
from uav_comm_planner.mission.request import MissionRequest
from uav_comm_planner.ros.handoff import ExecutorHandoff, LatestOnlyWorker
from uav_comm_planner.ros.params import NodeSettings
from uav_comm_planner.vehicle.flyable import VehiclePlan


@dataclass(frozen=True)
class PlanRequest:
    """What to plan, the settings to publish it with, and its plan stamp.

    start_ns: the plan stamp (node clock, nanoseconds) on every output of the plan; the
    planned poses are stamped start_ns + their planned time.
    """

    mission: MissionRequest
    output: NodeSettings
    start_ns: int
    reason: str

    @property
    def scenario(self):
        """The whole mission's scenario."""
        return self.mission.scenario


@dataclass(frozen=True)
class PlanOutcome:
    """A finished request: its plan, or the reason it failed, and the mission file written."""

    request: PlanRequest
    plan: MissionPlan | None = None
    error: str = ''
    mission_path: FilePath | None = None
    mission_error: str = ''
    cancelled: bool = False

    @property
    def result(self) -> PlanResult | None:
        """The plan to publish (as the vehicle flies it, for a vehicle-aware request)."""
        return None if self.plan is None else self.plan.result

    @property
    def vehicle_plan(self) -> VehiclePlan | None:
        return None if self.plan is None else self.plan.vehicle_plan

    @property
    def receding(self) -> RecedingPlan | None:
        """For a replan in flight: what it promises for the whole mission."""
        return None if self.plan is None else self.plan.receding

    @property
    def min_throughput(self) -> float:
        """The min average throughput over the whole mission, bit/s."""
        return self.plan.min_throughput


def open_mission_folder(output: NodeSettings) -> OutputFolder:
    """The node's mission folder, opened once at start-up (``mission_dir``; empty: the working
    directory); raises :class:`~uav_comm_planner.errors.PlannerError` when it cannot be
    opened, so that a node never starts with a mission folder it could only find later."""
    path = output.mission_dir or os.getcwd()
    try:
        return OutputFolder(path)
    except OSError as exc:
        raise PlannerError(f'mission_dir {path!r} cannot be opened as a folder: '
                           f'{exc.strerror or exc}') from None


def write_mission(outcome: PlanOutcome, output: NodeSettings,
                  folder: OutputFolder | None = None) -> FilePath:
    """Write an outcome's mission as ``mission_file`` inside ``mission_dir`` for ``output``'s
    home, end and firmware: inside ``folder`` (the mission folder the node opened at start-up,
    so that replacing the folder's path later cannot redirect the write), else at
    ``output.mission_path``; raises :class:`~uav_comm_planner.errors.PlannerError`
    (MissionExportError) on failure."""
    plan = outcome.plan.for_output(home=output.home, end=output.mission_end,
                                   firmware=output.mission_firmware)
    if folder is not None:
        return plan.write(output.mission_file, folder=folder)
    return plan.write(output.mission_path)


def attempt(planner: Planner, request: PlanRequest, *,
            should_stop: Callable[[], bool] | None = None,
            folder: OutputFolder | None = None) -> PlanOutcome:
    """Plan ``request`` and write its mission (into ``folder``, when given) if asked; every
    failure becomes the outcome.

    ``should_stop`` is passed on to the planner, which asks it between steps; a plan given up
    that way is an outcome with ``cancelled`` set.
    """
    try:
        planned = plan_mission(request.mission, planner=planner, should_stop=should_stop)
    except PlanCancelledError as exc:
        return PlanOutcome(request, error=str(exc), cancelled=True)
    except PlannerError as exc:
        return PlanOutcome(request, error=str(exc))
    except Exception as exc:  # noqa: B902 - a failed plan must not end the worker thread
        return PlanOutcome(request, error=f'unexpected {type(exc).__name__}: {exc}')
    outcome = PlanOutcome(request, planned)
    if not request.output.mission_file:
        return outcome
    try:
        return replace(outcome, mission_path=write_mission(outcome, request.output, folder))
    except PlannerError as exc:
        return replace(outcome, mission_error=str(exc))


class PlanningWorker:
    """Plans ``node``'s requests on one worker thread and hands the outcomes to ``deliver`` on
    the node's executor. A request that comes while a plan runs replaces any request still
    waiting and asks the running plan to give up at its next step."""

    def __init__(self, node: Node, planner: Planner,
                 deliver: Callable[[list[PlanOutcome]], None], *,
                 folder: OutputFolder | None = None) -> None:
        self._planner = planner
        self._folder = folder
        self._handoff: ExecutorHandoff[PlanOutcome] = ExecutorHandoff(node, deliver)
        self._worker: LatestOnlyWorker[PlanRequest] = LatestOnlyWorker(
            self._plan, name=f'{node.get_name()}.worker')

    def submit(self, request: PlanRequest) -> bool:
        """Plan ``request`` next; True when it replaced a request still waiting."""
        return self._worker.submit(request)

    def _plan(self, request: PlanRequest) -> None:
        self._handoff.put(attempt(self._planner, request, should_stop=self._worker.superseded,
                                  folder=self._folder))

    def stop(self) -> None:
        """Drop what waits, ask the running plan to give up, and deliver nothing more."""
        self._handoff.close()
        self._worker.stop()


__all__ = ['PlanOutcome', 'PlanRequest', 'PlanningWorker', 'attempt', 'open_mission_folder',
           'write_mission']
