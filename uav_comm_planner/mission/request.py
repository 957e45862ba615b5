"""What to plan: the scenario, the solver settings, the vehicle and how its mission ends.

A :class:`MissionRequest` is what the node and the command line hand to
:func:`~uav_comm_planner.mission.pipeline.plan_mission`; :func:`vehicle_limits` is the one
precedence rule for the vehicle's limits, the same for both: values given explicitly (ROS
parameters set, command-line flags) over a ground station's parameter file over the values
read from the vehicle (the node's link) over the firmware's defaults.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math
import os
from typing import Collection, Mapping

import numpy as np

from uav_comm_planner.core.receding import FlownSlots
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.core.zones import Zones
from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.vehicle.firmware import firmware_named
from uav_comm_planner.vehicle.flyable import GOAL_TOLERANCE_SLOTS
from uav_comm_planner.vehicle.geodesy import default_home, Home
from uav_comm_planner.vehicle.leg_models import leg_model
from uav_comm_planner.vehicle.limits import (parameter_file_values, read_parameter_file,
                                             VehicleLimits, VehicleParameters)
from uav_comm_planner.vehicle.timing import leg_time


#: Where a limit comes from, highest precedence first (:func:`limit_sources`).
SOURCES = ('explicit', 'parameter file', 'vehicle', 'firmware default')


def vehicle_limits(explicit: Mapping[str, float] | None = None,
                   parameter_file: str | os.PathLike | None = None, *,
                   firmware: str = 'ardupilot',
                   read: VehicleParameters | None = None) -> VehicleLimits:
    """The vehicle's limits: ``explicit`` values (by :class:`VehicleLimits` field name) over
    the limits ``parameter_file`` sets for ``firmware`` over those ``read`` from the vehicle
    (when it runs ``firmware``) over the firmware's defaults
    (:attr:`~uav_comm_planner.vehicle.firmware.Firmware.default_limits`).

    A file the user gave wins over the vehicle: it is said deliberately, for this plan, while
    the vehicle's values are what it holds when nobody said otherwise.

    Raises :class:`~uav_comm_planner.errors.InvalidScenarioError` for an unreadable or
    malformed file, an unknown field or an invalid value.
    """
    limits = VehicleLimits.for_firmware(firmware)
    if read is not None and read.firmware == firmware:
        limits = VehicleLimits(**{**limits.__dict__, **read.limits()})
    if parameter_file:
        limits = read_parameter_file(parameter_file, firmware=firmware, base=limits)
    limits = replace(limits, **dict(explicit or {}))
    check_legs_timed(limits)
    return limits


def limit_sources(explicit: Collection[str] = (),
                  parameter_file: str | os.PathLike | None = None, *,
                  firmware: str = 'ardupilot',
                  read: VehicleParameters | None = None) -> dict[str, str]:
    """Where :func:`vehicle_limits` takes each limit ``firmware``'s parameters state from: a
    :data:`SOURCES` entry by :class:`VehicleLimits` field (``explicit``: the fields given
    explicitly). Raises InvalidScenarioError as :func:`vehicle_limits` does."""
    layers = (set(explicit),
              set(parameter_file_values(parameter_file, firmware=firmware))
              if parameter_file else set(),
              set(read.limits()) if read is not None and read.firmware == firmware else set())
    sources = {}
    for field, _ in firmware_named(firmware).parameters.values():
        sources[field] = next((source for source, fields in zip(SOURCES, layers)
                               if field in fields), SOURCES[-1])
    return sources


#: Leg lengths, metres, that :func:`check_legs_timed` times: a waypoint step to a crossing.
PROBE_LEGS_M = (0.1, 10.0, 1000.0, 100000.0)


def check_legs_timed(limits: VehicleLimits) -> None:
    """Refuse (InvalidScenarioError) limits whose S-curve cannot time a leg: each of
    PROBE_LEGS_M at the cruise speed must take a finite, positive time. Run when the limits are
    set (a node parameter, a command line flag, a parameter file), so that a plan made later
    never fails on them."""
    for length_m in PROBE_LEGS_M:
        try:
            seconds = leg_time(length_m, limits.cruise_speed_mps, limits)
        except (ArithmeticError, ValueError) as exc:
            seconds, why = math.nan, f': {exc}'
        else:
            why = ''
        if not (math.isfinite(seconds) and seconds > 0):
            raise InvalidScenarioError(
                f'the vehicle limits cannot time a {length_m:g} m leg (got {seconds!r} s{why}): '
                f'speed {limits.cruise_speed_mps:g} m/s, acceleration '
                f'{limits.max_accel_mpss:g} m/s/s, jerk {limits.max_jerk_mpsss:g} m/s/s/s, '
                f'jerk time {limits.jerk_time_s:g} s')


def check_goal_in_time(scenario: Scenario, limits: VehicleLimits,
                       firmware: str = 'ardupilot') -> None:
    """Refuse (InvalidScenarioError) a mission the vehicle cannot fly at all: even the straight
    line from q0 to qF, one leg from rest at the cruise speed (the fastest any plan flies it,
    in any wind, since the waypoint speed bounds the ground speed) timed as ``firmware`` times
    a leg (:func:`~uav_comm_planner.vehicle.leg_models.leg_model`), takes longer than the
    mission's M + 1 slots and the share of a slot qF may come after them
    (:data:`~uav_comm_planner.vehicle.flyable.GOAL_TOLERANCE_SLOTS`). Cheap, and run when the
    parameters are set, so that a node never accepts limits every later plan would fail on;
    it never refuses what the vehicle-aware planning would fly (that adds the holds to it)."""
    length_m = math.dist(scenario.start_m, scenario.goal_m)
    model = leg_model(firmware)
    line = np.array([scenario.start_m, scenario.goal_m], dtype=float)
    seconds = model.timed_s(model.profile(line, limits.cruise_speed_mps, limits))
    end_s = scenario.slot_s * (scenario.num_slots + 1 + GOAL_TOLERANCE_SLOTS)
    if seconds > end_s:
        raise InvalidScenarioError(
            f'the vehicle cannot reach qF in time with these limits: the straight line from q0 '
            f'to qF ({length_m:.6g} m) takes {seconds:.6g} s at cruise '
            f'{limits.cruise_speed_mps:g} m/s, acceleration {limits.max_accel_mpss:g} m/s/s, '
            f'jerk {limits.max_jerk_mpsss:g} m/s/s/s, and the mission ends after {end_s:g} s; '
            f'raise horizon_s or give the vehicle\'s real limits')


@dataclass(frozen=True)
class InFlight:
    """The rest of a mission in flight to replan (the receding horizon,
    :mod:`uav_comm_planner.core.receding`).

    position_m: where the rest starts; flown: the slots already flown (power mapped onto the
    mission's nodes); previous_q: (M - k, 2) metres, the rest of the plan in force as the
    optimiser planned it (for a vehicle-aware plan its ideal plan, which keeps the speed it was
    planned at), one more start; mission_id and segment: which mission, and which of its plans
    (:attr:`~uav_comm_planner.mission.progress.MissionProgress.segments`) was in force, cut
    after ``slots_kept`` of its slots when the replan takes over; mission_slots: the
    mission's slots so far when an earlier replan lengthened it (0: the scenario's own);
    warm: the plan in force serves the same nodes, so the replan continues it instead of
    screening the tours again
    (:meth:`~uav_comm_planner.core.receding.RecedingProblem.for_scenario`); energy_left_wh:
    the energy the vehicle's battery has left for the rest, measured (None: the mission's
    energy budget less the model's energy of the flown legs, if it has one). A stream that
    caught up the plan in force after a gap (:mod:`uav_comm_planner.mission.catch_up`) gives
    ``caught_up``, the rest's points (M - k, 2) as it flies them (planned with the power
    optimal for them, no trajectory step), ``restated``, (k, 2) positions of the plan in
    force's slots where the vehicle was instead of where it was planned (NaN: as planned),
    and ``start_s``, when the rest's clock starts (the end of the slot in progress).
    """

    position_m: tuple[float, float]
    flown: FlownSlots
    previous_q: np.ndarray
    mission_id: int
    segment: int
    slots_kept: int
    mission_slots: int = 0
    warm: bool = False
    energy_left_wh: float | None = None
    caught_up: np.ndarray | None = None
    restated: np.ndarray | None = None
    start_s: float | None = None

    def mission(self, scenario: Scenario) -> Scenario:
        """``scenario`` as long as the mission in flight is (lengthened by earlier replans)."""
        return with_slots(scenario, self.mission_slots)


def with_slots(scenario: Scenario, slots: int) -> Scenario:
    """``scenario`` lengthened to ``slots`` slots of its delta; itself when it has as many."""
    if slots <= scenario.num_slots:
        return scenario
    return scenario.replace(num_slots=slots, horizon_s=slots * scenario.slot_s)


@dataclass(frozen=True)
class MissionRequest:
    """A mission to plan.

    scenario and settings: what the optimiser solves (settings None: the defaults);
    vehicle_aware: plan for ``vehicle``'s limits and return the plan as it flies (else the
    optimiser's plan as is); firmware, end, home: how its mission items are built
    (``items=False`` builds none; home None: the firmware's simulator home,
    :func:`~uav_comm_planner.vehicle.geodesy.default_home`); in_flight: replan the rest of a
    mission in flight instead of the whole mission from the scenario's start; zones: where the
    vehicle may fly (for example read from a fence file), which replace the scenario's own when
    given (:attr:`planned_scenario`).
    """

    scenario: Scenario
    settings: SolverSettings | None = None
    vehicle: VehicleLimits = VehicleLimits()
    vehicle_aware: bool = True
    firmware: str = 'ardupilot'
    end: str = 'land'
    home: Home | None = None
    items: bool = True
    in_flight: InFlight | None = None
    zones: Zones | None = None

    def __post_init__(self) -> None:
        if self.home is None:
            object.__setattr__(self, 'home', default_home(self.firmware))
        if self.zones is not None and not isinstance(self.zones, Zones):
            raise InvalidScenarioError(
                f'zones must be a Zones or None, got {type(self.zones).__name__}')

    @property
    def planned_scenario(self) -> Scenario:
        """The scenario planned: ``scenario`` with the request's zones, when it has any
        (validated again: q0 and qF must keep their margin)."""
        if self.zones is None or self.zones == self.scenario.zones:
            return self.scenario
        return self.scenario.replace(zones=self.zones)


__all__ = ['InFlight', 'MissionRequest', 'SOURCES', 'limit_sources', 'vehicle_limits']
