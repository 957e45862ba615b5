"""The node's state as ROS tools read it: diagnostic_msgs/DiagnosticArray on ``/diagnostics``.

As diagnostic_updater does, :class:`NodeDiagnostics` publishes once a second (and at once when
something changes) one status per concern, each named ``<node name>: <concern>`` with the
node's fully qualified name as ``hardware_id`` (the vehicle link's: its ``mavlink_url``), so
that rqt_robot_monitor and diagnostic_aggregator show the planner beside the rest of the
vehicle:

- ``planner``: the latest request planned (OK, or WARN when its slots are too coarse for the
  channel, :mod:`uav_comm_planner.mission.resolution`) or refused (WARN while an earlier plan
  stays in force, ERROR when there is none); the values carry the numbers (min throughput,
  baselines, slots, the coarse-slot figures, the full reason of the last refusal); a fleet's
  plan (``uavs`` >= 2) is OK with its line and numbers;
- ``vehicle link``: off without ``mavlink_url``; else the telemetry's age, the mission item,
  the uploads verified, the last link error (ERROR while the link is down), whether the link
  is up, the vehicle's mode, the telemetry gaps said and the planning frame's origin;
- ``mission clock``: waiting for the UAV at q0, running (slot, time left) or over;
- ``battery``: the vehicle's latest battery report (energy used, charge left, voltage,
  current), and with ``battery_wh`` the energy left for the rest against what the plan in
  force needs (:mod:`uav_comm_planner.ros.battery`): OK, WARN while a replan for the battery
  is asked, ERROR once the battery ended the mission, with the reason;
- ``vehicle parameters``: the limit parameters read from the vehicle (WPNAV_SPEED...,
  NAV_ACC_RAD) and where each limit the plan uses comes from
  (:mod:`uav_comm_planner.ros.vehicle_params`): OK, or WARN when some were not answered, are
  of another firmware than ``mission_firmware``, or were refused.

A message is one line and is never shortened: the reason of a refusal ends with its fix.
"""

from __future__ import annotations

from typing import Protocol

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Header

from uav_comm_planner.mission.resolution import coarse_slots, MAX_LEG_ALTITUDE_SHARE
from uav_comm_planner.ros.fleet import NodeFleet
from uav_comm_planner.ros.flight import MissionFlight
from uav_comm_planner.ros.messages import nodes_text, one_line, time_msg
from uav_comm_planner.ros.params import PlannerConfig
from uav_comm_planner.ros.planning import PlanOutcome
from uav_comm_planner.ros.publishing import plan_values
from uav_comm_planner.ros.vehicle import VehicleAdapter

#: Where every ROS 2 diagnostic source publishes (absolute: a namespace does not move it).
TOPIC_DIAGNOSTICS = '/diagnostics'
#: diagnostic_updater's period; an aggregator marks a status stale after a few missed ones.
PERIOD_S = 1.0
DIAGNOSTICS_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.VOLATILE)
#: The concerns, each one status.
PLANNER = 'planner'
VEHICLE_LINK = 'vehicle link'
MISSION_CLOCK = 'mission clock'
BATTERY = 'battery'
VEHICLE_PARAMETERS = 'vehicle parameters'
#: Telemetry older than this (node clock seconds) makes the link status WARN.
TELEMETRY_TIMEOUT_S = 3.0

OK, WARN, ERROR = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR


class DiagnosticsHost(Protocol):
    """What :class:`NodeDiagnostics` asks of its node (the planner node provides it)."""

    config: PlannerConfig
    flight: MissionFlight
    vehicle: VehicleAdapter
    current_plan: PlanOutcome | None
    fleet: NodeFleet

    def get_name(self) -> str: ...

    def get_fully_qualified_name(self) -> str: ...

    def get_logger(self): ...

    def create_publisher(self, *args, **kwargs): ...

    def create_timer(self, *args, **kwargs): ...

    def now_ns(self) -> int: ...

    def clock_s(self) -> float: ...


def diagnostic_status(name: str, hardware_id: str, level: bytes, message: str,
                      values: dict[str, object]) -> DiagnosticStatus:
    """A DiagnosticStatus whose message is ``message`` on one line, whole, values as text."""
    return DiagnosticStatus(level=level, name=name, hardware_id=hardware_id,
                            message=one_line(message),
                            values=[KeyValue(key=key, value=str(value))
                                    for key, value in values.items()])


class NodeDiagnostics:
    """The diagnostics of ``node`` (module docstring): :meth:`planned` and :meth:`refused`
    record the planner's outcomes, :meth:`update` publishes every status now."""

    def __init__(self, node: DiagnosticsHost) -> None:
        self._node = node
        self._publisher = node.create_publisher(DiagnosticArray, TOPIC_DIAGNOSTICS,
                                                DIAGNOSTICS_QOS)
        self._planner = (OK, f'planning the first plan of {node.get_name()}', {})
        self._refusal: dict[str, object] = {}
        node.create_timer(PERIOD_S, self.update)

    def planned(self, outcome: PlanOutcome) -> None:
        """A plan is in force: OK, or WARN with the numbers (also logged) when its slots are
        too coarse for the channel."""
        values = {'request': outcome.request.reason,
                  'plan_stamp_ns': outcome.request.start_ns, **plan_values(outcome)}
        values.update({f'{name}_bps': repr(value)
                       for name, value in outcome.result.baselines.items()})
        coarse = coarse_slots(outcome.result, outcome.request.scenario)
        if coarse is None:
            self._planner = (OK, f'planned: min throughput {outcome.min_throughput:.4g} bit/s',
                             values)
        else:
            self._node.get_logger().warning(coarse.message())
            values.update({'longest_leg_m': repr(coarse.longest_leg_m),
                           'altitude_m': repr(coarse.altitude_m),
                           'max_leg_altitude_share': repr(MAX_LEG_ALTITUDE_SHARE),
                           'along_legs_min_throughput_bps': repr(coarse.along_legs_bps),
                           'suggested_num_slots': coarse.suggested_slots})
            self._planner = (WARN, coarse.message(), values)
        self.update()

    def fleet_planned(self, message: str, values: dict[str, object]) -> None:
        """A fleet's plan is in force (:mod:`.fleet`): OK, its line and numbers."""
        self._planner = (OK, message, values)
        self.update()

    def refused(self, request: str, reason: str, *, nodes: str | None = None) -> None:
        """A request was refused or failed with ``reason`` (for the node set ``nodes``): WARN
        while an earlier plan stays in force, ERROR when there is none."""
        self._refusal = {'refused_request': request, 'refused_reason': one_line(reason),
                         'refused_stamp_ns': self._node.now_ns()}
        if nodes is not None:
            self._refusal['refused_nodes'] = nodes
        if self._node.current_plan is None and self._node.fleet.current is None:
            self._planner = (ERROR, f'no plan: {reason}', {})
        else:
            # The values of the plan in force stay: it is still published and flown.
            self._planner = (WARN, reason, self._planner[2])
        self.update()

    def update(self) -> None:
        """Publish every status now."""
        node = self._node
        level, message, values = self._planner
        statuses = [
            diagnostic_status(self._name(PLANNER), node.get_fully_qualified_name(), level,
                              message, {**values, **self._refusal}),
            self._link_status(),
            self._clock_status(),
            self._battery_status(),
            self._parameters_status(),
        ]
        self._publisher.publish(DiagnosticArray(header=Header(stamp=time_msg(node.now_ns())),
                                                status=statuses))

    def _name(self, concern: str) -> str:
        return f'{self._node.get_name()}: {concern}'

    def _link_status(self) -> DiagnosticStatus:
        node, vehicle = self._node, self._node.vehicle
        url = node.config.node.mavlink_url
        name = self._name(VEHICLE_LINK)
        if not vehicle.linked:
            return diagnostic_status(name, node.get_fully_qualified_name(), OK,
                                     'off: parameter mavlink_url is empty', {'mavlink_url': ''})
        values = {'mavlink_url': url, 'uploads_verified': vehicle.uploads_verified,
                  'upload_pending': vehicle.upload_pending,
                  'mission_item': '' if vehicle.mission_item is None else vehicle.mission_item,
                  'last_error': vehicle.last_error, 'link_up': vehicle.link_up,
                  'mode': vehicle.mode or '', 'telemetry_gaps': vehicle.telemetry_gaps,
                  'frame_origin': '' if vehicle.home is None else
                  f'{vehicle.home.latitude_deg:.7f}, {vehicle.home.longitude_deg:.7f}'}
        age_s = vehicle.telemetry_age_s(node.now_ns())
        if age_s is not None:
            values['telemetry_age_s'] = f'{age_s:.3f}'
        if vehicle.last_error:
            level, message = ERROR, vehicle.last_error
        elif age_s is None:
            level, message = WARN, f'connecting to {url}: no telemetry yet'
        elif age_s > TELEMETRY_TIMEOUT_S:
            level, message = WARN, f'no telemetry from {url} for {age_s:.1f} s'
        else:
            level, message = OK, (f'telemetry from {url}; {vehicle.uploads_verified} uploads '
                                  f'verified')
        return diagnostic_status(name, url, level, message, values)

    def _battery_status(self) -> DiagnosticStatus:
        node = self._node
        level, message, values = node.vehicle.battery.status()
        if not node.vehicle.linked:
            level, message = OK, 'off: parameter mavlink_url is empty'
        return diagnostic_status(self._name(BATTERY), node.get_fully_qualified_name(), level,
                                 message, values)

    def _parameters_status(self) -> DiagnosticStatus:
        node = self._node
        level, message, values = node.vehicle.parameters.status()
        if not node.vehicle.linked and node.vehicle.parameters.read is None:
            level, message = OK, 'off: parameter mavlink_url is empty'
        return diagnostic_status(self._name(VEHICLE_PARAMETERS), node.get_fully_qualified_name(),
                                 level, message, values)

    def _clock_status(self) -> DiagnosticStatus:
        node = self._node
        progress = node.flight.progress
        segment = progress.current
        now_s = node.clock_s()
        values: dict[str, object] = {'started': progress.started}
        if segment is None:
            message = 'no plan in force'
        elif segment.start_s is None:
            start = segment.result.scenario.start_m
            message = (f'waiting: starts when the UAV reaches q0 ({start[0]:g}, {start[1]:g}) '
                       f'or on ~/start')
        else:
            mission = progress.mission
            slot = segment.first_slot + segment.slots_begun(now_s)
            values.update({'slot': slot, 'mission_slots': mission.num_slots,
                           'plans': len(progress.segments),
                           'nodes': nodes_text(mission.ground_nodes_m)})
            if progress.ended:
                message = f'mission ended: {progress.ended}'
            elif progress.over(now_s):
                message = f'mission over: all {mission.num_slots} slots begun'
            else:
                left_s = (mission.num_slots - slot) * segment.result.scenario.slot_s
                values['left_s'] = f'{left_s:.3f}'
                message = (f'running: slot {slot} of {mission.num_slots}, {left_s:.0f} s left, '
                           f'plan {len(progress.segments)} of the mission')
        return diagnostic_status(self._name(MISSION_CLOCK), node.get_fully_qualified_name(),
                                 OK, message, values)


__all__ = ['BATTERY', 'DIAGNOSTICS_QOS', 'MISSION_CLOCK', 'NodeDiagnostics', 'PERIOD_S', 'PLANNER',
           'TELEMETRY_TIMEOUT_S', 'TOPIC_DIAGNOSTICS', 'VEHICLE_LINK', 'VEHICLE_PARAMETERS',
           'diagnostic_status']
