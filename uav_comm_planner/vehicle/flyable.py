"""Plans the vehicle flies as planned: the mission's timing and the plan it really delivers.

The optimiser's plan (Algorithm 1) moves at any speed up to V from one slot to the next. An
autopilot flies waypoints with a jerk-limited speed profile (:mod:`.timing`), so a mission that
simply lists the plan's points arrives late and delivers less. Here the plan becomes a flight
the autopilot keeps:

1. **Stops.** Runs of plan points within ``merge_radius_m`` of each other that last at least
   a slot, and at least as long as a stop costs (V / A + A / J + tj and the leg latency, 7.5 s at
   ArduCopter's defaults), are hovers: the vehicle stops there; a shorter hover is flown
   through slowly. q0 and qF are stops, and so is a turn sharper
   than ``MAX_TURN_DEG``, which the autopilot would cut. Stops closer together than the
   firmware flies a leg (PX4: its acceptance radius and a metre) are one.
2. **Legs.** The points between two stops become one leg, simplified to as few fly-through
   waypoints as keep it within ``path_tolerance_m`` of the plan (a turn of a few degrees costs
   no time), none closer than the distance the vehicle needs to reach its speed, since
   ArduCopter caps a leg's speed by its length.
3. **Timing.** A leg is flown at the speed that fits its S-curve (rest to rest, acceleration A,
   jerk J) into the plan's time for it; when even the cruise speed does not fit, the leg is
   centred on the plan's time and the holds on either side are shortened by what starting and
   stopping cost. A leg that starts behind the plan (its hold already at the shortest) is flown
   faster, up to its cruise, to end where the plan ends it, and so is one that would leave the
   later legs, at their cruise, too little time to reach qF: time lost at a corner is made up
   on the legs after it, and a leg leaves its stop before the plan's time only where even the
   cruise on every later leg would reach qF late. Holds are commanded in the firmware's
   resolution (ArduPilot: whole seconds) on the predicted clock, so rounding never
   accumulates. A flight that cannot reach qF by the end of the horizon is refused with the
   numbers.
4. **The plan flown.** The predicted position at every slot time is the vehicle-aware plan's
   trajectory, and its power schedule is the optimal one for those positions: the throughput
   it states is what the nodes get when the vehicle flies the mission.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
import math
import time
from typing import Callable

import numpy as np

from uav_comm_planner.core.model import flown_path
from uav_comm_planner.core.numbers import counted
from uav_comm_planner.core.optimizer import plan_along, PlanResult
from uav_comm_planner.core.scenario import MIN_STEP_M, Scenario, SolverSettings
from uav_comm_planner.errors import InfeasibleHorizonError, InvalidScenarioError
from uav_comm_planner.vehicle.climbs import (ClimbLimits, leg_limits, vertex_heights,
                                             with_altitude_bends)
from uav_comm_planner.vehicle.firmware import FIRMWARES
from uav_comm_planner.vehicle.leg_models import leg_model, LegModel, LegProfile
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.timing import (Dwell, Flight, Leg, LEG_LATENCY_S, ramp_distance,
                                             ramp_time)
from uav_comm_planner.vehicle.waypoints import (drop_short_steps, hover_runs, SegmentCheck,
                                                simplify, turn_angles_deg, zone_check)

#: Plan points closer than this are one stop (ArduCopter's default WPNAV_RADIUS is 2 m).
MERGE_RADIUS_M = 2.0
#: A leg's fly-through waypoints keep it within this distance of the plan's points.
PATH_TOLERANCE_M = 1.0
#: Slowest commanded speed; a slower leg waits at its start instead.
MIN_SPEED_MPS = 0.5
#: Sharper turns are stops: ArduCopter cuts a fly-through corner by up to WPNAV_RADIUS (2 m),
#: and by less below about 20 degrees (at 10 m/s and its default acceleration and jerk).
MAX_TURN_DEG = 20.0
#: When the vehicle cannot fly a plan on time, plan again this much slower (share of the
#: planning speed), leaving time for its starts and stops; at most this many times.
SLOWER_PLANNING = (0.9, 0.8, 0.7, 0.6, 0.5, 0.4)
#: qF may be reached at most this share of a slot after the plan's end.
GOAL_TOLERANCE_SLOTS = 0.25


@dataclass(frozen=True)
class Stop:
    """A waypoint where the vehicle comes to rest and holds for ``hold_s`` (commanded), at
    ``altitude_m`` (None: the plan's one altitude)."""

    position_m: np.ndarray
    hold_s: float
    altitude_m: float | None = None


@dataclass(frozen=True)
class Schedule:
    """A timed mission: stops[0] = q0, then for each leg its speed, its fly-through
    waypoints and the stop it ends at. ``flight`` is where the vehicle is when, from the
    moment it starts holding at q0."""

    stops: tuple[Stop, ...]
    legs: tuple[Leg, ...]
    flight: Flight
    firmware: str
    goal_reached_s: float | None = None

    @property
    def arrival_s(self) -> float:
        """Predicted arrival at qF (when the autopilot reports it reached), seconds from the
        start of the hold at q0: ``goal_reached_s`` when given, else the flight's end."""
        return self.flight.end_s if self.goal_reached_s is None else self.goal_reached_s


@dataclass(frozen=True)
class VehiclePlan:
    """A plan made for a vehicle: the optimiser's plan, the mission, and what it delivers.

    ``flown``: the plan as the vehicle flies it (trajectory = predicted positions at the slot
    times, power optimal for them); its ``min_throughput`` is the one to state.
    """

    ideal: PlanResult
    flown: PlanResult
    schedule: Schedule
    limits: VehicleLimits

    def timed_from(self, began_s: float) -> 'VehiclePlan':
        """This plan with the flown plan's ``solve_time_s`` counted from ``began_s`` (a
        :func:`time.perf_counter` reading: the whole planning for the vehicle)."""
        flown = dataclasses.replace(self.flown, solve_time_s=time.perf_counter() - began_s)
        return dataclasses.replace(self, flown=flown)


def _stop_index(points: np.ndarray, first: int, last: int) -> int:
    """The point of the run [first, last] the vehicle stops at: q0, qF, or the run's most
    central point."""
    if first == 0:
        return 0
    if last == len(points) - 1:
        return len(points) - 1
    run = points[first:last + 1]
    spread = np.linalg.norm(run[:, None, :] - run[None, :, :], axis=-1).max(axis=1)
    return first + int(np.argmin(spread))


def _stop_runs(points: np.ndarray, slot_s: float, merge_radius_m: float,
               path_tolerance_m: float, min_step_m: float,
               min_hover_s: float, keeps: SegmentCheck = None) -> list[tuple[int, int]]:
    """Index runs [i, j] of the points where the vehicle stops: q0, every hover that lasts at
    least ``min_hover_s`` (and a slot), every turn sharper than ``MAX_TURN_DEG``, and qF."""
    runs = [run for run in hover_runs(points, merge_radius_m)
            if (run[1] - run[0]) * slot_s >= min_hover_s - 1e-9
            or run[0] == 0 or run[1] == len(points) - 1]
    stops = []
    for run, following in zip(runs, runs[1:] + [None]):
        stops.append(run)
        if following is None:
            break
        chain = np.arange(run[1], following[0] + 1)
        kept = drop_short_steps(points[chain],
                                simplify(points[chain], path_tolerance_m, keeps),
                                min_step_m, keeps)
        sharp = turn_angles_deg(points[chain[kept]]) > MAX_TURN_DEG
        stops += [(int(chain[k]), int(chain[k])) for k, turn in zip(kept[1:-1], sharp) if turn]
    return stops


def _one_stop_when_close(points: np.ndarray, runs: list[tuple[int, int]],
                         shortest_m: float) -> tuple[list[tuple[int, int]], list[int]]:
    """``runs`` with every stop closer than ``shortest_m`` to the one before it merged into
    that one (the leg between them dropped, the run spanning both: q0 and qF stay where they
    are), and the point each run stops at (:func:`_stop_index`)."""
    merged, stops = [runs[0]], [_stop_index(points, *runs[0])]
    for run in runs[1:]:
        stop = _stop_index(points, *run)
        if np.linalg.norm(points[stop] - points[stops[-1]]) < shortest_m:
            merged[-1] = (merged[-1][0], run[1])
            stops[-1] = _stop_index(points, *merged[-1])
        else:
            merged.append(run)
            stops.append(stop)
    return merged, stops


def _quantise(hold_s: float, resolution_s: float) -> float:
    return round(max(hold_s, 0.0) / resolution_s) * resolution_s


def schedule_flight(result: PlanResult, limits: VehicleLimits, *, firmware: str = 'ardupilot',
                    merge_radius_m: float = MERGE_RADIUS_M,
                    path_tolerance_m: float = PATH_TOLERANCE_M,
                    stop_at_hovers: bool = True, altitudes: np.ndarray | None = None,
                    climb: ClimbLimits | None = None) -> Schedule:
    """The timed mission that flies ``result`` with the vehicle's ``limits`` (see the module
    docstring); with ``stop_at_hovers`` False it stops only at q0, qF and sharp turns. With
    ``altitudes`` (M,) metres, one per slot (q0 at the first, qF at the last), every waypoint
    carries its altitude and each leg is timed with the ``climb`` limits (ArduCopter's
    defaults when None) as :func:`~uav_comm_planner.vehicle.climbs.leg_limits` gives them.
    Raises :class:`~uav_comm_planner.errors.InfeasibleHorizonError` when the vehicle cannot
    reach qF by the end of the horizon."""
    scenario = result.scenario
    points = flown_path(np.asarray(result.trajectory, dtype=float), scenario)
    times = scenario.slot_s * np.arange(len(points), dtype=float)
    cruise = limits.cruise_speed_mps
    keeps = zone_check(scenario.zones)
    runs = _stop_runs(points, scenario.slot_s, merge_radius_m, path_tolerance_m,
                      2.0 * ramp_distance(cruise, limits),
                      max(scenario.slot_s, ramp_time(cruise, limits) + LEG_LATENCY_S)
                      if stop_at_hovers else math.inf, keeps)
    resolution = FIRMWARES[firmware].hold_resolution_s

    model = leg_model(firmware)
    runs, stop_indices = _one_stop_when_close(points, runs, model.shortest_leg_m(limits))
    positions = [points[index].copy() for index in stop_indices]
    heights = _point_heights(altitudes, len(points))
    paths, simplified, cruises, shapes = [], [], [], []  # per leg; shape: vertices, speed, profile
    path_heights, leg_limits_ = [], []
    for (_, last), (following, _), here, there in zip(runs, runs[1:], stop_indices,
                                                      stop_indices[1:]):
        # With zones the leg follows the plan from stop to stop (every step of it one of the
        # plan's legs), not from the stop straight to the run's last point.
        rows = (np.arange(here, there + 1) if keeps is not None
                else np.r_[here, last + 1:following, there])
        path = points[rows]
        paths.append(path)
        simplified.append(simplify(path, path_tolerance_m, keeps))
        climb_cap, own = (cruise, limits) if heights is None else leg_limits(
            path, heights[rows], limits, climb or ClimbLimits())
        path_heights.append(None if heights is None else heights[rows])
        if heights is not None:
            simplified[-1] = with_altitude_bends(path, heights[rows], simplified[-1],
                                                 path_tolerance_m)
        leg_limits_.append(own)
        cruises.append(min(_leg_cruise(path, scenario, cruise), climb_cap))
        shapes.append(_leg_shape(model, path, times[following] - times[last], cruises[-1],
                                 own, simplified[-1], keeps))
    # Centre each leg's motion on the plan's time for it, but start it no later than lets
    # every later leg, at its cruise and with the shortest holds, reach qF by the end of the
    # horizon; a leg behind the plan, or one that would leave the later legs too little time,
    # is flown faster (up to its cruise) to end where the plan, or the time left, ends it.
    fastest = [shape if shape[1] >= leg_cruise
               else _leg_shape(model, path, 0.0, leg_cruise, own, kept, keeps)
               for shape, path, leg_cruise, kept, own in zip(shapes, paths, cruises, simplified,
                                                             leg_limits_)]
    latest_holds = [model.min_hold_s(None if index == 0 else fastest[index - 1][2], cruise,
                                     limits) for index in range(len(shapes))]
    latest = times[-1]
    latest_starts = []
    for (_, _, profile), shortest in zip(reversed(fastest), reversed(latest_holds)):
        latest -= model.start_delay_s + model.reached_s(profile)
        latest_starts.append(latest)
        latest -= shortest
    latest_starts.reverse()
    deadlines = [start - shortest for start, shortest in
                 zip(latest_starts[1:], latest_holds[1:])] + [times[-1]]

    stops, legs, parts = [], [], []
    clock = 0.0                      # the hold at the current stop starts counting
    for index, (vertices, speed, profile) in enumerate(shapes):
        first, last = runs[index][1], runs[index + 1][0]
        minimum = model.min_hold_s(legs[-1].profile if legs else None, cruise, limits)
        timed = model.timed_s(profile)
        centred = 0.5 * (times[first] + times[last] - timed) - model.start_delay_s
        wanted = min(centred, latest_starts[index]) - clock
        hold = max(_quantise(wanted, resolution), minimum)
        if hold > wanted + 1e-9 and hold - resolution >= minimum:
            hold -= resolution       # round towards the earlier start when late
        behind_s = clock + hold - centred
        target = min(timed - behind_s if behind_s > 0.5 * resolution + 1e-9 else timed,
                     deadlines[index] - clock - hold - model.start_delay_s
                     - model.after_timed_s)
        if target < timed - 1e-6 and speed < cruises[index]:
            faster = _leg_shape(model, paths[index], target, cruises[index],
                                leg_limits_[index], simplified[index], keeps)
            if model.timed_s(faster[2]) < timed:    # PX4: fewer turns may fly slower
                vertices, speed, profile = faster
        here = None if heights is None else float(heights[stop_indices[index]])
        stops.append(Stop(positions[index], hold, here))
        parts.append(Dwell(positions[index], max(clock, legs[-1].end_s if legs else clock),
                           clock + hold, here))
        leg = Leg(vertices, speed, clock + hold + model.start_delay_s, profile,
                  None if heights is None else vertex_heights(vertices, paths[index],
                                                              path_heights[index]))
        legs.append(leg)
        parts.append(leg)
        clock = leg.start_s + model.reached_s(profile)
    # A plan that never leaves its first stop holds there for the whole horizon.
    final_hold = 0.0 if shapes else _quantise(times[-1], resolution)
    there = None if heights is None else float(heights[stop_indices[-1]])
    stops.append(Stop(positions[-1], final_hold, there))
    at_rest = max(clock, legs[-1].end_s if legs else clock)
    parts.append(Dwell(positions[-1], at_rest, max(at_rest, clock + final_hold), there))
    schedule = Schedule(tuple(stops), tuple(legs), Flight(tuple(parts)), firmware,
                        clock + final_hold)
    end = times[-1]
    if schedule.arrival_s > end + GOAL_TOLERANCE_SLOTS * scenario.slot_s:
        raise InfeasibleHorizonError(
            f'the vehicle cannot fly this plan on time: with cruise speed '
            f'{limits.describe_cruise()}, acceleration {limits.max_accel_mpss:g} m/s/s and '
            f'jerk {limits.max_jerk_mpsss:g} m/s/s/s it reaches the goal at '
            f'{schedule.arrival_s:.1f} s, the horizon ends at {end:g} s '
            f'({counted(len(legs), "leg")}, {counted(len(stops) - 2, "stop")}): lengthen '
            f'horizon_s by '
            f'{math.ceil(schedule.arrival_s - end)} s or more')
    return schedule


def _point_heights(altitudes: np.ndarray | None, count: int) -> np.ndarray | None:
    """The altitudes of the flown path's points q0, q[1..M], qF from the plan's (M,): q0 at
    the first slot's, qF at the last's; None without altitudes."""
    if altitudes is None:
        return None
    heights = np.asarray(altitudes, dtype=float)
    if heights.shape != (count - 2,) or not np.isfinite(heights).all():
        raise InvalidScenarioError(f'altitudes must be {count - 2} finite values, one per '
                                   f'slot, got shape {heights.shape}')
    return np.concatenate([heights[:1], heights, heights[-1:]])


def _leg_shape(model: LegModel, path: np.ndarray, planned_s: float, leg_cruise: float,
               limits: VehicleLimits, simplified: np.ndarray, keeps: SegmentCheck
               ) -> tuple[np.ndarray, float, LegProfile]:
    """A leg along ``path`` (K, 2) flown in ``planned_s`` or as close to it as ``leg_cruise``
    allows: its fly-through waypoints (``simplified``, the indices of ``path`` that keep it
    within the path tolerance, less the steps too short for its speed), its speed (in
    0.01 m/s, at least :data:`MIN_SPEED_MPS`) and its motion."""
    speed = max(model.speed_for_time(path, planned_s, leg_cruise, limits), MIN_SPEED_MPS)
    speed = min(round(speed, 2), leg_cruise)
    kept = drop_short_steps(path, simplified, 2.0 * ramp_distance(speed, limits), keeps)
    if model.per_vertex:             # the turns kept are what the time depends on
        speed = max(model.speed_for_time(path[kept], planned_s, leg_cruise, limits),
                    MIN_SPEED_MPS)
        speed = min(math.ceil(speed * 100.0) / 100.0, leg_cruise)
    return path[kept], speed, model.profile(path[kept], speed, limits)


def _leg_cruise(path: np.ndarray, scenario: Scenario, cruise: float) -> float:
    """The fastest a leg along ``path`` (K, 2) may be flown over the ground: the vehicle's
    cruise, and in wind the ground speed at the plan's airspeed on its slowest heading (the
    autopilot holds one commanded ground speed for the whole leg)."""
    if not scenario.airspeed_limited:
        return cruise
    steps = np.diff(path, axis=0)
    lengths = np.linalg.norm(steps, axis=1)
    headings = steps[lengths > 1e-9] / lengths[lengths > 1e-9, None]
    return min([cruise, *(scenario.ground_speed_at_airspeed_mps(u) for u in headings)])


def check_speed(scenario: Scenario, limits: VehicleLimits) -> None:
    """Refuse a planning speed above what the vehicle flies, with the numbers."""
    if scenario.max_speed_mps > limits.cruise_speed_mps * (1 + 1e-9):
        raise InfeasibleHorizonError(
            f'max_speed_mps {scenario.max_speed_mps:g} m/s is faster than the vehicle flies: '
            f'{limits.describe_cruise()}; plan with max_speed_mps <= '
            f'{limits.cruise_speed_mps:g} or give the vehicle\'s real limits')


def flown_result(ideal: PlanResult, schedule: Schedule) -> PlanResult:
    """The plan as flown: predicted positions at the slot times, power optimal for them.

    A replan in flight keeps its offsets (the data each node already holds): the power is
    optimal for them and the rates count them, as in the ideal plan.
    """
    scenario = ideal.scenario
    flown = plan_along(scenario, schedule.flight.positions(scenario.times_s),
                       SolverSettings(compute_baselines=False), name=ideal.start,
                       offsets=ideal.offsets)
    return dataclasses.replace(
        flown, baselines=ideal.baselines, outer_iterations=ideal.outer_iterations,
        trajectory_steps=ideal.trajectory_steps, converged=ideal.converged,
        solve_time_s=ideal.solve_time_s, upper_bound=ideal.upper_bound,
        start_throughputs=ideal.start_throughputs, offsets=ideal.offsets)


def vehicle_plan(ideal: PlanResult, limits: VehicleLimits, *,
                 firmware: str = 'ardupilot') -> VehiclePlan:
    """The vehicle's plan of ``ideal``: its schedule stopping at the hovers, else flying
    through them (:func:`schedule_flight`), and the plan as flown. Raises
    :class:`~uav_comm_planner.errors.InfeasibleHorizonError` (the last reason) when neither
    reaches qF on time."""
    error: InfeasibleHorizonError | None = None
    for stop_at_hovers in (True, False):
        try:
            schedule = schedule_flight(ideal, limits, firmware=firmware,
                                       stop_at_hovers=stop_at_hovers)
        except InfeasibleHorizonError as exc:
            error = exc
            continue
        return VehiclePlan(ideal, flown_result(ideal, schedule), schedule, limits)
    raise error


def in_wind(scenario: Scenario, limits: VehicleLimits) -> Scenario:
    """``scenario`` with the vehicle's airspeed when it is planned for a wind and gives none."""
    airspeed = limits.airspeed_for_wind_mps(scenario.wind_speed_mps)
    if airspeed is not None and scenario.max_airspeed_mps is None:
        return scenario.replace(max_airspeed_mps=airspeed)
    return scenario


def straight_line_plan(scenario: Scenario, limits: VehicleLimits,
                       settings: SolverSettings | None, firmware: str,
                       planner: Callable[[Scenario, SolverSettings | None], PlanResult],
                       first_error: Exception | None = None) -> VehiclePlan:
    """The last fallback of a plan for a vehicle: the straight line q0 -> qF, planned by
    ``planner`` at exactly its own ground speed (so that it is the only path, with the power
    optimal for it and any offsets the planner brings) and flown as one leg from rest to rest,
    leaving at once at the slowest speed that reaches qF by the end of the horizon. Raises
    :class:`~uav_comm_planner.errors.InfeasibleHorizonError` (from ``first_error``) when not
    even it fits the horizon, saying the horizon it needs."""
    distance = math.dist(scenario.start_m, scenario.goal_m)
    legs = scenario.num_slots + 1
    end_s = legs * scenario.slot_s
    # Just above the straight line's speed, so that round-off keeps the goal in reach.
    speed = max(distance / end_s * (1 + 1e-9), 2.0 * MIN_STEP_M / scenario.slot_s)
    ideal = planner(scenario.replace(max_speed_mps=min(speed, scenario.max_speed_mps)), settings)
    start = np.asarray(scenario.start_m, dtype=float)
    goal = np.asarray(scenario.goal_m, dtype=float)
    line = np.vstack([start, goal])
    cruise = _leg_cruise(line, scenario, limits.cruise_speed_mps)
    model = leg_model(firmware)
    hold = model.min_hold_s(None, cruise, limits)
    fitted = model.speed_for_time(line, end_s - hold - model.start_delay_s
                                  - model.after_timed_s, cruise, limits)
    # Commanded in hundredths, rounded up so that the leg is not late.
    fitted = min(max(math.ceil(fitted * 100.0) / 100.0, MIN_SPEED_MPS), cruise)
    profile = model.profile(line, fitted, limits)
    leg = Leg(line, fitted, hold + model.start_delay_s, profile)
    arrival = leg.start_s + model.reached_s(profile)
    if arrival > end_s + GOAL_TOLERANCE_SLOTS * scenario.slot_s:
        raise InfeasibleHorizonError(_no_flyable_plan(scenario, limits, firmware)) \
            from first_error
    at_rest = max(arrival, leg.end_s)
    flight = Flight((Dwell(start, 0.0, hold), leg, Dwell(goal, at_rest, at_rest)))
    schedule = Schedule((Stop(start, hold), Stop(goal, 0.0)), (leg,), flight, firmware,
                        arrival)
    return VehiclePlan(ideal, flown_result(ideal, schedule), schedule, limits)


def _no_flyable_plan(scenario: Scenario, limits: VehicleLimits, firmware: str) -> str:
    """Why not even the straight line fits, with the horizon it needs (computed from the
    firmware's leg timing from rest at the fastest speed the vehicle holds along it: the hold
    at q0, the start, and the leg until qF counts as reached)."""
    distance = math.dist(scenario.start_m, scenario.goal_m)
    direction = (np.asarray(scenario.goal_m) - np.asarray(scenario.start_m)) / distance
    line = np.vstack([scenario.start_m, scenario.goal_m])
    speed = _leg_cruise(line, scenario, limits.cruise_speed_mps)
    model = leg_model(firmware)
    flight_s = (model.min_hold_s(None, speed, limits) + model.start_delay_s
                + model.reached_s(model.profile(line, speed, limits)))
    # qF may come GOAL_TOLERANCE_SLOTS after (M + 1) delta = T (M + 1) / M.
    needed = flight_s * scenario.num_slots / (scenario.num_slots + 1 + GOAL_TOLERANCE_SLOTS)
    heading = math.degrees(math.atan2(direction[0], direction[1])) % 360.0
    return (f'the vehicle cannot fly this request on time: even the straight line from q0 to '
            f'qF ({distance:.1f} m, heading {heading:.0f} degrees) takes {flight_s:.1f} s from '
            f'rest to rest at {speed:.3g} m/s (acceleration {limits.max_accel_mpss:g} m/s/s, '
            f'jerk {limits.max_jerk_mpsss:g} m/s/s/s), the horizon ends at '
            f'{scenario.slot_s * (scenario.num_slots + 1):g} s: lengthen horizon_s to '
            f'{math.ceil(needed * 10) / 10:g} s or more')
