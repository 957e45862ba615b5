"""What to plan: the scenario, the solver settings, the vehicle and how its mission ends.

A :class:`MissionRequest` is what the node and the command line hand to
:func:`~uav_comm_planner.mission.pipeline.plan_mission`; :func:`vehicle_limits` is the one
precedence rule for the vehicle's limits, the same for both: values given explicitly (ROS
parameters set, command-line flags) over a ground station's parameter file over ArduCopter's
defaults.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import os
from typing import Mapping

import numpy as np

from uav_comm_planner.core.receding import FlownSlots
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.vehicle.geodesy import DEFAULT_HOME, Home
from uav_comm_planner.vehicle.limits import read_parameter_file, VehicleLimits


def vehicle_limits(explicit: Mapping[str, float] | None = None,
                   parameter_file: str | os.PathLike | None = None, *,
                   firmware: str = 'ardupilot') -> VehicleLimits:
    """The vehicle's limits: ``explicit`` values (by :class:`VehicleLimits` field name) over
    the limits ``parameter_file`` sets for ``firmware`` over the defaults.

    Raises :class:`~uav_comm_planner.errors.InvalidScenarioError` for an unreadable or
    malformed file, an unknown field or an invalid value.
    """
    limits = VehicleLimits()
    if parameter_file:
        limits = read_parameter_file(parameter_file, firmware=firmware, base=limits)
    return replace(limits, **dict(explicit or {}))


@dataclass(frozen=True)
class InFlight:
    """The rest of a mission in flight to replan (the receding horizon,
    :mod:`uav_comm_planner.core.receding`).

    position_m: where the rest starts; flown: the slots already flown (power mapped onto the
    mission's nodes); previous_q: (M - k, 2) metres, the rest of the plan in force, one more
    start; mission_id and segment: which mission, and which of its plans
    (:attr:`~uav_comm_planner.mission.progress.MissionProgress.segments`) was in force, cut
    after ``slots_kept`` of its slots when the replan takes over.
    """

    position_m: tuple[float, float]
    flown: FlownSlots
    previous_q: np.ndarray
    mission_id: int
    segment: int
    slots_kept: int


@dataclass(frozen=True)
class MissionRequest:
    """A mission to plan.

    scenario and settings: what the optimiser solves (settings None: the defaults);
    vehicle_aware: plan for ``vehicle``'s limits and return the plan as it flies (else the
    optimiser's plan as is); firmware, end, home: how its mission items are built
    (``items=False`` builds none); in_flight: replan the rest of a mission in flight instead
    of the whole mission from the scenario's start.
    """

    scenario: Scenario
    settings: SolverSettings | None = None
    vehicle: VehicleLimits = VehicleLimits()
    vehicle_aware: bool = True
    firmware: str = 'ardupilot'
    end: str = 'land'
    home: Home = Home(*DEFAULT_HOME)
    items: bool = True
    in_flight: InFlight | None = None


__all__ = ['InFlight', 'MissionRequest', 'vehicle_limits']
