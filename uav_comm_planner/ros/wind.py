"""The wind measured in flight, as the node uses it: published, planned for, replanned on.

A :class:`WindTracker` takes the node (as tf2_ros's TransformListener does). It smooths the
autopilot's wind estimates (:class:`~uav_comm_planner.mission.wind.WindEstimate`, time constant
``wind_time_constant_s`` of autopilot time), publishes the smoothed wind on ``wind_estimate``
(geometry_msgs/Vector3Stamped in ``frame_id``: x east, y north, z 0, m/s, the velocity of the
air, i.e. the direction it blows *towards*), and gives every plan the measured wind in place of
the ``wind_speed_mps`` / ``wind_from_deg`` parameters, which hold only until the autopilot
reports one. When the estimate moves farther than ``wind_replan_mps`` from the wind of the plan
in force, it asks the node for a replan of the rest of the mission in flight; before the
mission's clock runs (nothing flies the plan yet, a replan costs nothing) already when it moves
farther than :data:`PREFLIGHT_RESOLUTION_MPS`, so that the plan the mission starts with is made
for the wind as measured; at most once every ``replan_interval_s`` of autopilot time. A wind is
answered once: one the plan cannot fly (at or above the airspeed, or a goal it puts out of
reach) is refused on ``planner_status`` and ``/diagnostics``, the plan in force kept, and not
said again while the estimate stays one that no plan can take (a rising gale is one refusal,
not one per threshold it crosses); it is answered again once a plan can take it. A wind
replanned for is not asked for again until the estimate moves by the same threshold. While a
refusal stands (:attr:`WindTracker.refused`), the node makes no replan from the UAV's position
either: any such plan would be made for a wind known to be wrong, and the UAV, slower than
planned in the gale, would fall behind it again at once (an endless replan loop).
"""

from __future__ import annotations

from dataclasses import replace
import math
from typing import Protocol

from geometry_msgs.msg import Vector3Stamped
import numpy as np
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.mission.wind import WindEstimate
from uav_comm_planner.ros.params import PlannerConfig

TOPIC_WIND = 'wind_estimate'
#: Reliable and kept for late subscribers: the latest estimate is what matters.
WIND_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Why a wind replan is asked (the request's name on planner_status).
REASON = 'wind estimate'
#: Before the mission clock runs, the plan follows the estimate to within this (m/s).
PREFLIGHT_RESOLUTION_MPS = 0.5


class WindHost(Protocol):
    """What :class:`WindTracker` asks of its node (the planner node provides it)."""

    config: PlannerConfig
    current_plan: object
    flight: object
    progress: object

    def get_logger(self): ...

    def get_clock(self): ...

    def create_publisher(self, *args, **kwargs): ...

    def refuse(self, request: str, message: str, *, nodes: str | None = None) -> None: ...


class WindTracker:
    """The node's wind estimate (module docstring)."""

    def __init__(self, node: WindHost) -> None:
        self._node = node
        self.estimate = WindEstimate(node.config.node.wind_time_constant_s)
        self._publisher = node.create_publisher(Vector3Stamped, TOPIC_WIND, WIND_QOS)
        self._last_replan_s = -math.inf
        #: The smoothed wind (m/s, east and north) last answered: replanned for or refused.
        self._answered: np.ndarray | None = None
        #: Replans the wind asked for.
        self.replans = 0

    @property
    def refused(self) -> bool:
        """Whether the wind last answered was refused and no plan can take the estimate since
        (kept on the node's flight, which makes no replan from the UAV's position then)."""
        return self._node.flight.wind_refused

    @refused.setter
    def refused(self, value: bool) -> None:
        self._node.flight.wind_refused = value

    def _windy(self, config: PlannerConfig) -> PlannerConfig:
        """``config`` with the measured wind in its scenario; raises InvalidScenarioError
        when the scenario cannot take it (a wind at or above the airspeed)."""
        scenario = self.estimate.for_scenario(config.scenario)
        if self.estimate.known and config.node.vehicle_aware:
            # A plan for the vehicle in wind keeps the vehicle's airspeed.
            scenario = scenario.replace(max_airspeed_mps=config.vehicle.airspeed_for_wind_mps(
                scenario.wind_speed_mps))
        return replace(config, scenario=scenario)

    def config(self, config: PlannerConfig) -> PlannerConfig:
        """``config`` with the measured wind in its scenario (as it is before any
        measurement, and when the scenario cannot take the wind measured: said on the log)."""
        try:
            return self._windy(config)
        except InvalidScenarioError as exc:
            self._node.get_logger().error(f'{REASON}: not planned for, the plan keeps '
                                          f'wind_speed_mps and wind_from_deg: {exc}')
            return config

    def add(self, time_s: float, east_mps: float, north_mps: float) -> None:
        """An estimate from the autopilot at ``time_s``: smooth, publish, replan if due."""
        output = self._node.config.node
        if self.estimate.time_constant_s != output.wind_time_constant_s:
            self.estimate.time_constant_s = output.wind_time_constant_s
        self.estimate.add(time_s, east_mps, north_mps)
        velocity = self.estimate.velocity_mps
        if velocity is None:
            return
        message = Vector3Stamped()
        message.header.frame_id = output.frame_id
        message.header.stamp = self._node.get_clock().now().to_msg()
        message.vector.x, message.vector.y = float(velocity[0]), float(velocity[1])
        self._publisher.publish(message)
        plan = self._node.current_plan
        if plan is None or time_s - self._last_replan_s < output.replan_interval_s:
            return
        threshold = (output.wind_replan_mps if self._node.progress.started
                     else min(output.wind_replan_mps, PREFLIGHT_RESOLUTION_MPS))
        if not self.estimate.differs_from(plan.request.scenario, threshold):
            self.refused = False
            return
        # A wind answered already (planned for, or its plan failed) is not asked again until
        # the estimate moves on by the threshold; a refused one not until a plan can take it:
        # a gale the plan cannot fly would otherwise be asked for at every
        # replan_interval_s, for ever.
        if (not self.refused and self._answered is not None
                and float(math.hypot(*(velocity - self._answered))) <= threshold):
            return
        self._last_replan_s = time_s
        try:
            self._windy(self._node.config)
        except InvalidScenarioError as exc:
            if not self.refused:
                self._refuse(exc, plan)
            return
        self.refused = False
        self._answered = velocity.copy()
        self.replans += 1
        self._node.get_logger().info(
            f'{REASON}: {self.estimate.speed_mps:.1f} m/s from '
            f'{self.estimate.from_deg:.0f} degrees, the plan in force was made for '
            f'{plan.request.scenario.wind_speed_mps:g} m/s from '
            f'{plan.request.scenario.wind_from_deg:g} degrees; replanning')
        self._node.flight.request_update(REASON)

    def _refuse(self, exc: InvalidScenarioError, plan) -> None:
        """Say once that the measured wind cannot be planned for, and what happens now."""
        self.refused = True
        self._answered = self.estimate.velocity_mps.copy()
        self._node.refuse(REASON, f'{REASON} refused: {exc}; the plan in force stays (made '
                                  f'for {plan.request.scenario.wind_speed_mps:g} m/s) and is '
                                  f'not replanned until the wind drops to one a plan can take '
                                  f'or the request changes')


__all__ = ['PREFLIGHT_RESOLUTION_MPS', 'TOPIC_WIND', 'WIND_QOS', 'WindTracker']
