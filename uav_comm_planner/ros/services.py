"""The node's services: ``~/replan``, ``~/start`` and ``~/export_mission`` (std_srvs/Trigger).

:class:`PlannerServices` takes the node (as tf2_ros's TransformListener does) and answers
each request at once; a plan asked for follows on the plan topics.
"""

from __future__ import annotations

from typing import Protocol

from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_srvs.srv import Trigger

from uav_comm_planner.errors import PlannerError
from uav_comm_planner.files import OutputFolder
from uav_comm_planner.ros.flight import MissionFlight
from uav_comm_planner.ros.params import PlannerConfig
from uav_comm_planner.ros.planning import PlanOutcome, write_mission
from uav_comm_planner.ros.publishing import TOPIC_PATH

SERVICE_REPLAN = '~/replan'
SERVICE_START = '~/start'
SERVICE_EXPORT_MISSION = '~/export_mission'
#: Service requests are queued, not dropped, up to this many in flight (the default is 10).
SERVICE_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)


#: What ``~/start`` and ``~/export_mission`` say on a node that plans a fleet.
FLEET_NOT_YET = ('a fleet (uavs >= 2) has no mission clock yet, and writes every vehicle\'s '
                 'mission file (mission_file with _uav1, _uav2, ...) with every plan')


class ServiceHost(Protocol):
    """What :class:`PlannerServices` asks of its node (the planner node provides it)."""

    config: PlannerConfig
    flight: MissionFlight
    current_plan: PlanOutcome | None
    mission_folder: OutputFolder

    def create_service(self, *args, **kwargs): ...

    def clock_s(self) -> float: ...

    def report_error(self, message: str) -> None: ...


class PlannerServices:
    """The services of ``node`` (module docstring)."""

    def __init__(self, node: ServiceHost) -> None:
        self._node = node
        for name, callback in ((SERVICE_REPLAN, self._on_replan),
                               (SERVICE_START, self._on_start),
                               (SERVICE_EXPORT_MISSION, self._on_export_mission)):
            node.create_service(Trigger, name, callback, qos_profile=SERVICE_QOS)

    def _on_replan(self, _request: Trigger.Request,
                   response: Trigger.Response) -> Trigger.Response:
        self._node.flight.request_plan(SERVICE_REPLAN)
        response.success = True
        response.message = (f'planning the mission from start_m; the plan follows on '
                            f'{TOPIC_PATH}; the mission clock starts at q0 or on '
                            f'{SERVICE_START}')
        return response

    def _on_start(self, _request: Trigger.Request,
                  response: Trigger.Response) -> Trigger.Response:
        node = self._node
        response.success = False
        segment = node.flight.progress.current
        if node.config.fleet is not None:
            response.message = FLEET_NOT_YET
        elif node.config.node.mavlink_url:
            response.message = ('the vehicle link starts the mission clock when the vehicle '
                                'reaches q0 (parameter mavlink_url is set)')
        elif segment is None:
            response.message = 'no plan yet'
        elif segment.start_s is not None:
            response.message = 'the mission clock is already running'
        else:
            node.flight.start_clock(node.clock_s(), SERVICE_START)
            response.success = True
            response.message = 'mission clock started: the plan in force is flown from now'
        return response

    def export_mission(self) -> tuple[bool, str]:
        """Write the plan in force as ``mission_file`` now (``~/export_mission``, and the node
        when the file's name, end, firmware or home changes): (whether written, what
        happened, also on the node's log: a failed write as its error)."""
        node = self._node
        if not node.config.node.mission_file:
            return False, 'parameter mission_file is empty: set a .waypoints or .plan file name'
        if node.config.fleet is not None:
            return False, FLEET_NOT_YET
        if node.current_plan is None:
            return False, 'no plan yet'
        try:
            written = write_mission(node.current_plan, node.config.node, node.mission_folder)
        except PlannerError as exc:
            node.report_error(f'mission export failed: {exc}')
            return False, str(exc)
        node.get_logger().info(f'the plan in force: mission written to {written}')
        return True, f'mission written to {written}'

    def _on_export_mission(self, _request: Trigger.Request,
                           response: Trigger.Response) -> Trigger.Response:
        response.success, response.message = self.export_mission()
        return response


__all__ = ['PlannerServices', 'ServiceHost', 'SERVICE_EXPORT_MISSION', 'SERVICE_QOS',
           'SERVICE_REPLAN', 'SERVICE_START']
