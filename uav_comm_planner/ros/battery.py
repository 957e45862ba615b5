"""The vehicle's battery in flight, as the node uses it: reported, planned with, acted on.

A :class:`BatteryWatch` takes the node (as tf2_ros's TransformListener does) and keeps the
latest battery report of the vehicle link
(:class:`~uav_comm_planner.vehicle.mavlink.battery.BatteryReport`; BATTERY_STATUS, which
counts the energy, over SYS_STATUS, which does not), shown on ``/diagnostics``
(:meth:`BatteryWatch.status`).

With a battery stated (``battery_wh``), an airframe and a mission whose clock runs, every
replan of the rest plans with the energy the battery has left for it, measured
(:meth:`BatteryWatch.budget`, :mod:`uav_comm_planner.mission.battery`), and at most
once every ``replan_interval_s`` of autopilot time the watch checks the plan in force against
it, its needs scaled by how much faster than the airframe's model the battery drained since
the clock started (:func:`~uav_comm_planner.mission.battery.drain_ratio`,
:func:`~uav_comm_planner.mission.battery.battery_decision`): kept while the energy left
flies its rest; replanned within the energy left when the straight line to qF still fits in
it; otherwise, or when that replan fails, the mission ends: the vehicle is told
``battery_action`` (rtl, land or hold, asked again at each mode report that is not it, up to
:data:`END_TRIES` times), the reason is one line on the log, ``planner_status`` and
``/diagnostics``, and the node replans nothing more of that mission (``~/replan`` plans a new
one).
"""

from __future__ import annotations

from dataclasses import replace
import math
from typing import Protocol

from diagnostic_msgs.msg import DiagnosticStatus

from uav_comm_planner.core.energy import JOULES_PER_WH, takeoff_landing_j
from uav_comm_planner.errors import PlannerError
from uav_comm_planner.mission.battery import (battery_decision, BatteryDecision,
                                              consumed_wh, drain_ratio, END, ENERGY_MARGIN,
                                              plan_rest_energy_wh, REPLAN, rest_allowance_wh,
                                              straight_rest_energy_wh)
from uav_comm_planner.ros.params import node_battery, PlannerConfig
from uav_comm_planner.vehicle.mavlink.battery import BatteryReport, in_end_mode

#: Why a battery replan is asked, and the name of the battery's refusals.
REASON = 'battery'
#: The end of the mission is asked again at most this many times while the vehicle's mode is
#: not the one asked.
END_TRIES = 5
#: A battery replan asked waits this many replan intervals for its plan before the plan in
#: force is checked again.
WAIT_INTERVALS = 3
#: Battery reports kept for the drain ratio (at 2 Hz, over an hour and a half).
USED_KEPT = 12_000
#: What the vehicle is told, in words.
ACTION_WORDS = {'rtl': 'return to launch', 'land': 'land where it is', 'hold': 'hold'}

OK, WARN, ERROR = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR


class BatteryHost(Protocol):
    """What :class:`BatteryWatch` asks of its node (the planner node provides it)."""

    config: PlannerConfig
    current_plan: object
    flight: object
    vehicle: object

    def get_logger(self): ...

    def refuse(self, request: str, message: str, *, nodes: str | None = None) -> None: ...

    def submit(self, reason: str, in_flight: object = None) -> None: ...


class BatteryWatch:
    """The node's battery (module docstring). ``latest`` is the latest report (None before
    any), ``decision`` the latest check's, ``replans`` the replans the battery asked for; the
    reason the battery ended a mission is its progress's ``ended``."""

    def __init__(self, node: BatteryHost) -> None:
        self._node = node
        self.latest: BatteryReport | None = None
        self.decision: BatteryDecision | None = None
        self.replans = 0
        self._counted = False
        self._last_check_s = -math.inf
        self._asked: tuple[object, float] | None = None
        self._end_tries = 0
        #: How much faster than the model the battery drains (:func:`drain_ratio`), and the
        #: energy used (autopilot s, Wh) at the reports that counted it.
        self.ratio = 1.0
        self._used: list[tuple[float, float]] = []

    def add(self, report: BatteryReport) -> None:
        """A report from the vehicle: kept (SYS_STATUS only while no BATTERY_STATUS counted the
        energy), then the plan in force checked when due."""
        if math.isnan(report.consumed_j) and self._counted:
            return
        self._counted = self._counted or not math.isnan(report.consumed_j)
        self.latest = report
        battery = node_battery(self._node.config.node)
        if battery is not None:
            self._used.append((report.time_s, consumed_wh(report, battery)))
            del self._used[:-USED_KEPT]
        self._check(report.time_s)

    def allowance_wh(self) -> tuple[float, float] | None:
        """(allowance, capacity), Wh, for the rest of the mission in force
        (:func:`~uav_comm_planner.mission.battery.rest_allowance_wh`); None without a battery
        stated, an airframe, a plan or a report. A report without the energy (PX4's
        BATTERY_STATUS, SYS_STATUS) counts the charge drawn as that share of the battery
        stated (:func:`~uav_comm_planner.mission.battery.consumed_wh`)."""
        battery = node_battery(self._node.config.node)
        report = self.latest
        if battery is None or report is None:
            return None
        plan = self._node.current_plan
        if plan is None:
            return None
        scenario = plan.result.scenario
        if scenario.airframe is None:
            return None
        landing_wh = takeoff_landing_j(scenario.airframe, scenario.altitude_m)[1] / JOULES_PER_WH
        return rest_allowance_wh(battery, consumed_wh(report, battery), report.remaining,
                                 landing_wh)

    def budget(self) -> float | None:
        """The energy budget of a replan of the rest now, as the airframe's model counts it:
        the allowance less ENERGY_MARGIN, over the drain ratio (None: no measured figure, the
        mission's own budget holds)."""
        allowance = self.allowance_wh()
        return None if allowance is None else allowance[0] * (1.0 - ENERGY_MARGIN) / self.ratio

    def _drain_ratio(self, time_s: float, start_s: float, scenario) -> float:
        """:func:`~uav_comm_planner.mission.battery.drain_ratio` since ``start_s`` (the
        mission clock's start): the energy used since then along the UAV's track."""
        since = [used for used in self._used if used[0] >= start_s]
        track = self._node.flight.track.samples
        track = track[(track[:, 0] >= start_s) & (track[:, 0] <= time_s)]
        if not since or not len(track):
            return 1.0
        return drain_ratio(self._used[-1][1] - since[0][1], track[track[:, 0] >= since[0][0]],
                           scenario)

    def _check(self, time_s: float) -> None:
        node = self._node
        progress = node.flight.progress
        segment = progress.current
        if (segment is None or segment.start_s is None or progress.over(time_s)
                or time_s - self._last_check_s < node.config.node.replan_interval_s):
            return
        interval = node.config.node.replan_interval_s
        if (self._asked is not None and self._asked[0] is node.current_plan
                and time_s - self._asked[1] < WAIT_INTERVALS * interval):
            return              # the battery's replan is not in force yet
        allowance = self.allowance_wh()
        latest = node.flight.track.latest
        begun = segment.slots_begun(time_s)
        rest_slots = progress.mission.num_slots - segment.first_slot - begun
        if allowance is None or latest is None or rest_slots < 1:
            return
        self._last_check_s = time_s
        scenario = segment.result.scenario
        position = (latest[1], latest[2])
        self.ratio = self._drain_ratio(time_s, progress.segments[0].start_s, scenario)
        needed = plan_rest_energy_wh(segment.result, time_s - segment.start_s, position)
        least = straight_rest_energy_wh(scenario, position, rest_slots)
        self.decision = battery_decision(allowance[0], needed * self.ratio, least * self.ratio)
        if self.ratio > 1.0:
            self.decision = replace(self.decision, reason=(
                f'{self.decision.reason} (the needs at the drain measured, {self.ratio:.3f} '
                f'times the airframe model\'s)'))
        if self.decision.action == REPLAN:
            self.replans += 1
            self._asked = (node.current_plan, time_s)
            node.get_logger().warning(f'{REASON}: {self.decision.reason}')
            self._replan(time_s, position, self.decision.budget_wh / self.ratio)
        elif self.decision.action == END:
            self.end(self.decision.reason)

    def _replan(self, time_s: float, position: tuple[float, float], budget_wh: float) -> None:
        """Ask for the rest from ``position`` within ``budget_wh`` (the model's Wh); the
        mission ends when even that request cannot be made
        (:meth:`~uav_comm_planner.mission.progress.MissionProgress.in_flight` refuses it)."""
        node = self._node
        try:
            in_flight = node.flight.progress.in_flight(node.config.scenario, time_s, position,
                                                       node.flight.track,
                                                       energy_left_wh=budget_wh)
        except PlannerError as exc:
            self.replan_failed(str(exc))
            return
        node.submit(REASON, in_flight)

    def replan_failed(self, reason: str) -> None:
        """The replan the battery asked for was refused or failed: the mission ends."""
        if not self._node.flight.progress.ended:
            self.end(f'the rest cannot be planned within the energy left ({reason}): the '
                     f'battery cannot reach qF with its reserve')

    def end(self, reason: str) -> None:
        """End the mission: the vehicle told ``battery_action``, the reason said once."""
        node = self._node
        action = node.config.node.battery_action
        ended = (f'{REASON}: mission ended, the vehicle told to {ACTION_WORDS[action]} '
                 f'({action}): {reason}')
        node.flight.progress.ended = ended
        self._end_tries = 1
        node.vehicle.end_mission(action)
        node.refuse(REASON, ended)

    def on_mode(self, mode: str) -> None:
        """The vehicle's mode: after the end, ask again while it is not the one asked."""
        action = self._node.config.node.battery_action
        ended = self._node.flight.progress.ended
        if ended and not in_end_mode(action, mode) and self._end_tries < END_TRIES:
            self._end_tries += 1
            self._node.vehicle.end_mission(action)

    def status(self) -> tuple[bytes, str, dict[str, object]]:
        """(level, message, values) of the battery on /diagnostics."""
        report = self.latest
        if report is None:
            return OK, 'no battery report from the vehicle', {}
        values: dict[str, object] = {
            'source': report.source, 'time_s': f'{report.time_s:.3f}',
            'consumed_wh': f'{report.consumed_j / JOULES_PER_WH:.4f}',
            'remaining_percent': f'{100 * report.remaining:.0f}',
            'voltage_v': f'{report.voltage_v:.3f}', 'current_a': f'{report.current_a:.3f}',
            'battery_action': self._node.config.node.battery_action,
            'battery_replans': self.replans, 'drain_ratio': f'{self.ratio:.4f}'}
        allowance = self.allowance_wh()
        if allowance is not None:
            values.update(capacity_wh=f'{allowance[1]:.4f}',
                          rest_allowance_wh=f'{allowance[0]:.4f}')
        if self.decision is not None:       # the figures of the latest check, when it was made
            values.update(checked_allowance_wh=f'{self.decision.allowance_wh:.4f}',
                          checked_needed_wh=f'{self.decision.needed_wh:.4f}',
                          checked_least_wh=f'{self.decision.least_wh:.4f}',
                          battery_decision=self.decision.action)
        message = (f'{report.consumed_j / JOULES_PER_WH:.2f} Wh used, '
                   f'{100 * report.remaining:.0f} % left')
        ended = self._node.flight.progress.ended
        if ended:
            values['ended_reason'] = ended
            return ERROR, ended, values
        if self.decision is not None and self.decision.action == REPLAN:
            return WARN, f'{message}; {self.decision.reason}', values
        if self.decision is not None:
            return OK, f'{message}; {self.decision.reason}', values
        return OK, message, values


__all__ = ['ACTION_WORDS', 'BatteryWatch', 'END_TRIES', 'REASON']
