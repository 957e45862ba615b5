"""The battery in flight: the energy the vehicle has left, what the rest of the mission needs,
and whether the plan in force is kept, replanned within the energy left, or the mission ended.

The energy left is measured, not predicted: the autopilot's energy consumed (BATTERY_STATUS)
against the battery's capacity, which is the smaller of the usable energy stated
(``battery_wh``) and the one the autopilot's own charge remaining implies, consumed over the
share drawn (:func:`battery_capacity_wh`; a battery smaller than stated, or one whose
autopilot knows its capacity better, shows there). Of that capacity the reserve is kept and
the landing after qF paid (:func:`rest_allowance_wh`): what remains is what the rest of the
horizon, from where the vehicle is to qF, may use.

The rest of the plan in force needs the energy of its legs from the vehicle's position to
its next point over the time left to it, then through its remaining points to qF, one slot
each, by the airframe's model (:func:`plan_rest_energy_wh`); the cheapest way to qF is taken
as the straight line flown at uniform speed over the legs of the rest a replan would plan
(:func:`~uav_comm_planner.core.receding.rest_of_mission`: from the vehicle's position, one
slot per leg, more when they cannot reach qF in time; the start that costs least on an
airframe whose power only rises with speed, and a flight that always exists:
:func:`straight_rest_energy_wh`).
Both are scaled by how much faster than the model the battery drained since the mission's
clock started (:func:`drain_ratio`, at least 1: a wind stronger than told shows there, though
not in the plan). :func:`battery_decision` then keeps the plan while the energy left flies it;
replans within
:data:`ENERGY_MARGIN` less than the energy left (less only by what the straight line leaves,
when that is less) while the straight line fits in it; and ends the mission otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Sequence

import numpy as np

from uav_comm_planner.core.energy import Battery, JOULES_PER_WH
from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.vehicle.mavlink.battery import BatteryReport

#: A replan for the battery plans with this share less than the energy left, so that the
#: model's error in flight (within 0.4 % measured on ArduCopter SITL, docs/energy.md) does not
#: make the next check replan again.
ENERGY_MARGIN = 0.03
#: ... but never below the straight line's energy by this share more, which the optimiser's
#: straight-line start then keeps with room.
LEAST_SLACK = 1e-3
#: The charge remaining implies a capacity once at least this share of it is drawn: the
#: autopilot reports it in whole percent, so earlier the implied capacity is too coarse.
MIN_DRAWN_SHARE = 0.05

KEEP, REPLAN, END = 'keep', 'replan', 'end'


def battery_capacity_wh(stated_wh: float, consumed_wh: float, remaining: float) -> float:
    """The battery's usable energy, Wh: ``stated_wh``, or less when the autopilot's charge
    ``remaining`` (a share, NaN: unknown) says that ``consumed_wh`` is a larger share of it:
    ``consumed_wh / (1 - remaining)`` once at least :data:`MIN_DRAWN_SHARE` is drawn."""
    drawn = 1.0 - remaining
    if math.isnan(remaining) or drawn < MIN_DRAWN_SHARE or consumed_wh <= 0.0:
        return stated_wh
    return min(stated_wh, consumed_wh / drawn)


def consumed_wh(report: BatteryReport, battery: Battery) -> float:
    """The energy ``report`` says the vehicle used, Wh: its energy consumed, or, when it does
    not count it (PX4, SYS_STATUS), the share of its charge drawn times the battery stated."""
    if math.isfinite(report.consumed_j):
        return report.consumed_j / JOULES_PER_WH
    return battery.usable_wh * (1.0 - report.remaining)


def rest_allowance_wh(battery: Battery, consumed_wh: float, remaining: float,
                      landing_wh: float) -> tuple[float, float]:
    """(allowance, capacity), Wh: what the rest of the horizon may use, the capacity
    (:func:`battery_capacity_wh`) less its reserve, less ``consumed_wh``, less the landing;
    and that capacity. The allowance may be negative (nothing left for the rest)."""
    capacity = battery_capacity_wh(battery.usable_wh, consumed_wh, remaining)
    return capacity * (1.0 - battery.reserve) - consumed_wh - landing_wh, capacity


def path_energy_wh(path_m: np.ndarray, scenario: Scenario) -> float:
    """The propulsion energy of the legs between consecutive points of ``path_m`` (K, 2)
    metres, each flown at constant velocity over one slot at its airspeed in the scenario's
    wind, by its airframe, Wh (as :func:`~uav_comm_planner.core.energy.horizon_energy_j`
    counts a plan's legs)."""
    path = np.asarray(path_m, dtype=float).reshape(-1, 2)
    airspeed = np.linalg.norm(np.diff(path, axis=0) / scenario.slot_s - scenario.wind_mps,
                              axis=1)
    return float(scenario.airframe.level_power_w(airspeed).sum() * scenario.slot_s
                 / JOULES_PER_WH)


def rest_path(position_m: Sequence[float], rest_q: np.ndarray,
              goal_m: Sequence[float]) -> np.ndarray:
    """The vehicle's position, the plan's remaining points (M', 2), qF: (M' + 2, 2)."""
    return np.vstack([np.reshape(position_m, (1, 2)),
                      np.reshape(np.asarray(rest_q, dtype=float), (-1, 2)),
                      np.reshape(goal_m, (1, 2))])


#: The leg to the next planned point is flown over the time left to it unless that is less
#: than this share of a slot: then the vehicle is taken to fly on to the point after it.
SHORTEST_LEG_SHARE = 0.5


def plan_rest_energy_wh(result: PlanResult, elapsed_s: float,
                        position_m: Sequence[float]) -> float:
    """The energy the plan ``result`` still needs ``elapsed_s`` after its clock started with
    the vehicle at ``position_m``: to its next point (reached at the end of the current slot)
    over the time left to it, then its legs as planned to qF, Wh (0 once qF is due)."""
    scenario = result.scenario
    points = np.vstack([np.reshape(np.asarray(result.trajectory, float), (-1, 2)),
                        np.reshape(scenario.goal_m, (1, 2))])
    delta = scenario.slot_s
    j = int(math.floor(elapsed_s / delta))
    left_s = (j + 1) * delta - elapsed_s
    if left_s < SHORTEST_LEG_SHARE * delta:
        j, left_s = j + 1, left_s + delta
    if j >= len(points):
        return 0.0
    velocity = (points[j] - np.asarray(position_m, float)) / left_s - scenario.wind_mps
    first = float(scenario.airframe.level_power_w(np.linalg.norm(velocity))) * left_s
    return first / JOULES_PER_WH + path_energy_wh(points[j:], scenario)


def rest_legs(scenario: Scenario, position_m: Sequence[float], rest_slots: int) -> int:
    """The legs of the rest a replan plans from ``position_m``: its ``rest_slots`` + 1, or,
    when those cannot reach qF at the fastest ground speed towards it, the fewest that can
    (the rest is lengthened: :func:`~uav_comm_planner.core.receding.lengthened`)."""
    gap = np.asarray(scenario.goal_m, dtype=float) - np.asarray(position_m, dtype=float)
    distance = float(np.linalg.norm(gap))
    if distance == 0.0:
        return rest_slots + 1
    step = scenario.fastest_ground_speed_mps(gap / distance) * scenario.slot_s
    fewest = math.ceil(distance / step * (1 - 1e-12)) if step > 0.0 else rest_slots + 1
    return max(rest_slots + 1, fewest)


def straight_rest_energy_wh(scenario: Scenario, position_m: Sequence[float],
                            rest_slots: int) -> float:
    """The energy of the straight line from ``position_m`` to qF at uniform speed over the
    legs of the rest (:func:`rest_legs`), Wh."""
    start = np.asarray(position_m, dtype=float)
    shares = np.linspace(0.0, 1.0, rest_legs(scenario, position_m, rest_slots) + 1)[:, None]
    return path_energy_wh(start + shares * (np.asarray(scenario.goal_m, float) - start),
                          scenario)


#: The flight must have lasted this long (s) before its drain is compared with the model's.
MIN_DRAIN_S = 20.0


def drain_ratio(used_wh: float, track: np.ndarray, scenario: Scenario) -> float:
    """How much faster than the airframe's model the battery drains: ``used_wh``, what the
    battery gave along ``track`` (K, 3: t s, x, y m), over the model's energy of the same
    flight (each step between samples at its airspeed in the scenario's wind); never below 1
    (the rest is never taken to cost less than the model says), and 1 before the track spans
    MIN_DRAIN_S. A wind stronger than told, or an airframe heavier than modelled, shows
    here."""
    samples = np.asarray(track, dtype=float).reshape(-1, 3)
    if len(samples) < 2 or samples[-1, 0] - samples[0, 0] < MIN_DRAIN_S:
        return 1.0
    seconds = np.diff(samples[:, 0])
    moving = seconds > 0.0
    velocity = np.diff(samples[:, 1:], axis=0)[moving] / seconds[moving, None]
    power = scenario.airframe.level_power_w(np.linalg.norm(velocity - scenario.wind_mps, axis=1))
    modelled_wh = float(np.sum(power * seconds[moving])) / JOULES_PER_WH
    return max(1.0, used_wh / modelled_wh) if modelled_wh > 0.0 else 1.0


@dataclass(frozen=True)
class BatteryDecision:
    """What the battery says of the plan in force: ``action`` :data:`KEEP`, :data:`REPLAN`
    (within ``budget_wh``, :func:`battery_decision`) or :data:`END`; the figures it was
    decided on, Wh; ``reason`` in words."""

    action: str
    allowance_wh: float
    needed_wh: float
    least_wh: float
    budget_wh: float
    reason: str


def battery_decision(allowance_wh: float, needed_wh: float, least_wh: float,
                     margin: float = ENERGY_MARGIN) -> BatteryDecision:
    """Keep the plan in force when the energy left flies its rest (``needed_wh`` <=
    ``allowance_wh``); else replan within a budget of ``allowance_wh`` (1 - ``margin``), or
    of the straight line's ``least_wh`` (1 + :data:`LEAST_SLACK`) when that is more, as long
    as the budget is within ``allowance_wh``; else end the mission."""
    budget = max(allowance_wh * (1.0 - margin), least_wh * (1.0 + LEAST_SLACK))
    figures = (f'{allowance_wh:.2f} Wh left for the rest after the reserve and the landing, '
               f'the plan in force needs {needed_wh:.2f} Wh')
    if needed_wh <= allowance_wh:
        return BatteryDecision(KEEP, allowance_wh, needed_wh, least_wh, budget,
                               f'{figures}: kept')
    if budget <= allowance_wh:
        return BatteryDecision(REPLAN, allowance_wh, needed_wh, least_wh, budget,
                               f'{figures}: replanning the rest within {budget:.2f} Wh')
    return BatteryDecision(END, allowance_wh, needed_wh, least_wh, budget,
                           f'{figures} and even the straight line to qF needs '
                           f'{least_wh:.2f} Wh: the battery cannot reach qF with its reserve')


__all__ = ['BatteryDecision', 'END', 'ENERGY_MARGIN', 'KEEP', 'LEAST_SLACK', 'MIN_DRAWN_SHARE',
           'REPLAN',
           'SHORTEST_LEG_SHARE', 'MIN_DRAIN_S', 'battery_capacity_wh', 'battery_decision',
           'consumed_wh', 'drain_ratio', 'path_energy_wh',
           'plan_rest_energy_wh', 'rest_allowance_wh', 'rest_legs', 'rest_path',
           'straight_rest_energy_wh']
