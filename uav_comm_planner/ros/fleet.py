"""The node's fleet: K UAVs planned by one planner, each vehicle's outputs under its own
namespace, one vehicle link per ``mavlink_urls`` entry.

With ``uavs`` >= 2 (:mod:`uav_comm_planner.ros.fleet_params`) every plan request of the node
(start-up, a ``ground_nodes`` message, an accepted parameter change, ``~/replan``) plans the
whole fleet jointly (:func:`~uav_comm_planner.core.fleet.plan_fleet`) on a worker thread of its
own, the newest request first. UAV k's part (:func:`~uav_comm_planner.mission.fleet.uav_result`:
its trajectory, its power schedule, the rates it alone gives) is published on the
single-vehicle topics, with the same message types, under ``<node namespace>/uav<k>/``
(``uav1/planned_path``, ``uav1/power_schedule``, ``uav1/power_plan``, ``uav1/min_throughput``,
``uav1/plan_markers``, ``uav1/zone_markers``, ``uav1/planner_status``); the node's own
``min_throughput`` carries the fleet's min_n R_n (node n's throughput summed over the UAVs) and
its ``planner_status`` one entry per request (the fleet planned, or refused with the reason).

With missions (``mission_file`` or ``mavlink_urls``) the fleet is planned as the command line
plans its missions (:func:`~uav_comm_planner.mission.fleet.plan_for_missions`): the missions,
as the autopilot times them, keep d_min. ``mission_file`` m.waypoints is written as
m_uav1.waypoints, ... in ``mission_dir``; vehicle k's mission is uploaded on link k
(:mod:`.fleet_links`). A plan that fails leaves the last good plan published and in force.

A fleet plan is not replanned in flight (no mission clock, no pose replans) and runs to its
end: a request made meanwhile waits, the newest only.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import PurePath
from typing import Sequence

from diagnostic_msgs.msg import DiagnosticArray
from std_msgs.msg import Float64

from uav_comm_planner.core.fleet import FleetScenario, FleetSettings, plan_fleet
from uav_comm_planner.core.fleet.model import closest_approach_m
from uav_comm_planner.core.fleet.planner import FleetPlan
from uav_comm_planner.errors import PlannerError
from uav_comm_planner.files import OutputFolder
from uav_comm_planner.mission.fleet import fleet_mission_paths, plan_for_missions, uav_result
from uav_comm_planner.mission.pipeline import MissionPlan
from uav_comm_planner.mission.request import MissionRequest
from uav_comm_planner.ros.fleet_links import FleetLinks
from uav_comm_planner.ros.handoff import ExecutorHandoff, LatestOnlyWorker
from uav_comm_planner.ros.messages import nodes_text, status_message
from uav_comm_planner.ros.params import NodeSettings, PlannerConfig
from uav_comm_planner.ros.planning import PlanOutcome, PlanRequest, write_mission
from uav_comm_planner.ros.publishing import (OUTPUT_QOS, PlanPublisher, STATUS_QOS,
                                             TOPIC_MIN_THROUGHPUT, TOPIC_STATUS)
from uav_comm_planner.vehicle.limits import VehicleLimits


def vehicle_namespace(k: int) -> str:
    """The namespace of vehicle k's outputs (k 0-based): ``uav1``, ``uav2``, ..."""
    return f'uav{k + 1}'


@dataclass(frozen=True)
class FleetRequest:
    """A fleet to plan, the settings to publish it with, and its plan stamp (node clock, ns);
    ``missions``: build each vehicle's mission items (and keep d_min as the missions fly)."""

    fleet: FleetScenario
    settings: FleetSettings
    output: NodeSettings
    vehicle: VehicleLimits
    start_ns: int
    reason: str
    missions: bool


@dataclass(frozen=True)
class FleetOutcome:
    """A finished fleet request: the fleet's plan and each vehicle's part as a single
    vehicle's outcome (its mission items and file), or the reason it failed; ``note`` says how
    the missions keep d_min."""

    request: FleetRequest
    plan: FleetPlan | None = None
    vehicles: tuple[PlanOutcome, ...] = ()
    note: str = ''
    error: str = ''


def fleet_request(config: PlannerConfig, start_ns: int, reason: str) -> FleetRequest:
    """The request the node's settings ``config`` make (a fleet's, ``config.fleet`` set)."""
    output = config.node
    return FleetRequest(config.fleet, FleetSettings(single=config.settings), output,
                        config.vehicle, start_ns, reason,
                        missions=bool(output.mission_file or config.fleet_urls))


def _vehicle_outcome(request: FleetRequest, plan: FleetPlan, k: int,
                     folder: OutputFolder | None) -> PlanOutcome:
    """Vehicle k's part of ``plan`` as a single vehicle's outcome: its plan, its mission items
    (when asked) and its mission file (``mission_file`` with ``_uav<k>`` before the suffix)."""
    output = request.output
    if output.mission_file:
        name = fleet_mission_paths(PurePath(output.mission_file), plan.fleet.num_uavs)[k].name
        output = replace(output, mission_file=name)
    mission = MissionRequest(plan.fleet.vehicle(k), request.settings.single, request.vehicle,
                             vehicle_aware=False, firmware=output.mission_firmware,
                             end=output.mission_end, home=output.home, items=False)
    planned = MissionPlan(mission, uav_result(plan, k))
    if request.missions:
        planned = planned.for_output(home=output.home, end=output.mission_end,
                                     firmware=output.mission_firmware)
    outcome = PlanOutcome(PlanRequest(planned.request, output, request.start_ns,
                                      request.reason), planned)
    if not output.mission_file:
        return outcome
    try:
        return replace(outcome, mission_path=write_mission(outcome, output, folder))
    except PlannerError as exc:
        return replace(outcome, mission_error=str(exc))


def plan_fleet_request(request: FleetRequest, folder: OutputFolder | None = None
                       ) -> FleetOutcome:
    """Plan ``request`` (module docstring) and write its missions into ``folder`` if asked;
    every failure becomes the outcome."""
    try:
        if request.missions:
            plan, note = plan_for_missions(request.fleet, request.settings, request.vehicle,
                                           request.output.mission_firmware)
        else:
            plan, note = plan_fleet(request.fleet, request.settings), ''
        vehicles = tuple(_vehicle_outcome(request, plan, k, folder)
                         for k in range(plan.fleet.num_uavs))
    except PlannerError as exc:
        return FleetOutcome(request, error=str(exc))
    except Exception as exc:  # noqa: B902 - a failed plan must not end the worker thread
        return FleetOutcome(request, error=f'unexpected {type(exc).__name__}: {exc}')
    return FleetOutcome(request, plan, vehicles, note)


def fleet_summary(outcome: FleetOutcome) -> str:
    """The one log line per fleet plan: its min throughput against each UAV alone, the
    closest approach, size and plan time."""
    plan = outcome.plan
    fleet, scenario = plan.fleet, plan.fleet.scenario
    alone = ', '.join(f'UAV {name.split()[1]} alone {value:.4g}'
                      for name, value in plan.single_throughputs.items())
    line = (f'fleet plan: min throughput {plan.min_throughput:.4g} bit/s'
            + (f' ({alone})' if alone else '') + f'; {fleet.num_uavs} UAVs, closest approach '
            f'{closest_approach_m(plan.trajectories):.1f} m (d_min '
            f'{fleet.min_separation_m:g} m), {scenario.num_nodes} nodes, '
            f'{scenario.num_slots} slots of {scenario.slot_s:g} s, {plan.status}, planned in '
            f'{plan.solve_time_s:.2f} s')
    if outcome.note:
        line += f'; {outcome.note}'
    written = [str(v.mission_path) for v in outcome.vehicles if v.mission_path is not None]
    if written:
        line += '; missions written to ' + ', '.join(written)
    return line


class NodeFleet:
    """The fleet part of ``node`` (module docstring); inactive (nothing made) when the node
    plans one UAV. ``current`` is the fleet outcome in force (the node's ``stats`` count its
    requests and plans); ``links`` are the vehicle links."""

    def __init__(self, node, folder: OutputFolder | None) -> None:
        self._node = node
        self.current: FleetOutcome | None = None
        fleet = node.config.fleet
        self.active = fleet is not None
        if not self.active:
            return
        self._publishers = [PlanPublisher(node, vehicle_namespace(k))
                            for k in range(fleet.num_uavs)]
        self._status = node.create_publisher(DiagnosticArray, TOPIC_STATUS, STATUS_QOS)
        self._throughput = node.create_publisher(Float64, TOPIC_MIN_THROUGHPUT, OUTPUT_QOS)
        self.links = FleetLinks(node, self._on_link_report)
        self._handoff: ExecutorHandoff[FleetOutcome] = ExecutorHandoff(node, self._deliver)
        self._worker: LatestOnlyWorker[FleetRequest] = LatestOnlyWorker(
            lambda request: self._handoff.put(plan_fleet_request(request, folder)),
            name=f'{node.get_name()}.fleet')
        # rclpy calls the post-set callbacks added last first, before the node's settings
        # change: the links are remade on the executor, once the change is applied.
        reconnect = node.create_guard_condition(self.connect)
        node.add_post_set_parameters_callback(lambda _changes: reconnect.trigger())
        self.connect()

    def connect(self) -> None:
        """The links ``mavlink_urls`` names, remade when they or the frame's home change; on
        links made, the plan in force is uploaded, its missions built for the home, end and
        firmware set now."""
        output = self._node.config.node
        current = self.current
        if not self.links.connect(self._node.config.fleet_urls, output.home,
                                  output.home_distance_limit_m) \
                or current is None or not current.request.missions:
            return
        vehicles = [replace(vehicle, plan=vehicle.plan.for_output(
            home=output.home, end=output.mission_end, firmware=output.mission_firmware))
            for vehicle in current.vehicles]
        self.links.upload(vehicles, current.request.start_ns)

    def submit(self, request: PlanRequest) -> bool:
        """Plan the fleet the parameters describe now, for the node's ``request`` (its stamp
        and reason; the node's worker when it plans a fleet); True when it replaced a request
        still waiting."""
        return self._worker.submit(fleet_request(self._node.config, request.start_ns,
                                                 request.reason))

    def _deliver(self, outcomes: Sequence[FleetOutcome]) -> None:
        """Executor thread: publish each plan, or say why it failed (the last good plan
        stays)."""
        for outcome in outcomes:
            request = outcome.request
            self._node.stats.plans_run += 1
            if outcome.plan is None:
                self._node.refuse(request.reason, f'fleet planning failed ({request.reason}); '
                                                  f'the last good plan stays published: '
                                                  f'{outcome.error}',
                                  nodes=nodes_text(request.fleet.scenario.ground_nodes_m),
                                  stamp_ns=request.start_ns)
            else:
                self._publish(outcome)

    def _publish(self, outcome: FleetOutcome) -> None:
        self.current = outcome
        request, plan = outcome.request, outcome.plan
        line = fleet_summary(outcome)
        self._node.get_logger().info(line)
        for publisher, vehicle in zip(self._publishers, outcome.vehicles):
            publisher.publish(vehicle)
        self._throughput.publish(Float64(data=plan.min_throughput))
        values = {'nodes': nodes_text(plan.fleet.scenario.ground_nodes_m),
                  'min_throughput_bps': repr(plan.min_throughput), 'uavs': plan.fleet.num_uavs,
                  'slots': plan.fleet.scenario.num_slots,
                  'closest_approach_m': repr(closest_approach_m(plan.trajectories))}
        self._status.publish(status_message(
            request.start_ns, request=request.reason, planned=True, message=line,
            values=values, hardware_id=self._node.get_fully_qualified_name()))
        self._node.diagnostics.fleet_planned(line, {'request': request.reason,
                                                    'plan_stamp_ns': request.start_ns, **values})
        self._node.stats.plans_published += 1
        self.links.upload(outcome.vehicles, request.start_ns)
        for k, vehicle in enumerate(outcome.vehicles):
            if vehicle.mission_error:
                self._node.report_error(f'{vehicle_namespace(k)}: mission export failed, the '
                                        f'plan is kept: {vehicle.mission_error}')

    def _on_link_report(self, k: int, message: str, is_error: bool) -> None:
        """Vehicle k's link said ``message``: on the log, and an error on its status."""
        line = f'{vehicle_namespace(k)}: {message}'
        if not is_error:
            self._node.get_logger().info(line)
            return
        self._node.report_error(line)
        self._publishers[k].refused(self._node.now_ns(), 'vehicle link', message)

    def stop(self) -> None:
        """Stop planning and the links; deliver nothing more."""
        if self.active:
            self._handoff.close()
            self._worker.stop()
            self.links.close()


__all__ = ['FleetOutcome', 'FleetRequest', 'fleet_request', 'fleet_summary', 'NodeFleet',
           'plan_fleet_request', 'vehicle_namespace']
