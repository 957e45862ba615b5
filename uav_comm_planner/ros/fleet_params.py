"""The node's fleet parameters: how many UAVs it plans, each one's ends and link, d_min.

:class:`FleetNodeSettings` is one more owner of the node's parameters
(:mod:`uav_comm_planner.ros.params`): ``uavs`` (K, read-only: fixed at start-up),
``uav_starts_m`` and ``uav_goals_m`` (K points each, a flat list ``x1, y1, x2, y2, ...``),
``mavlink_urls`` (one link per vehicle, or none) and ``min_separation_m`` (d_min).
With ``uavs`` 1 (the default) the node plans one UAV from ``start_m`` to ``goal_m`` over
``mavlink_url`` and the fleet parameters must stay empty; with K >= 2, :func:`fleet_of`
makes the :class:`~uav_comm_planner.core.fleet.FleetScenario` that the other parameters and
these describe, and refuses (InvalidScenarioError) whatever disagrees: a count of ends or links
other than K, ``mavlink_url`` set beside them, the streamed flight mode.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from uav_comm_planner.core.fleet import FleetScenario
from uav_comm_planner.core.fleet.planner import check_budget
from uav_comm_planner.core.fleet.scenario import DEFAULT_SEPARATION_M, MAX_UAVS
from uav_comm_planner.core.scenario import Point, Scenario, SolverSettings
from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.mission.request import check_goal_in_time
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink.urls import parse_link_url

FLEET_DESCRIPTIONS = {
    'uavs': f'number of UAVs K planned jointly (1 to {MAX_UAVS}; read-only: fixed at '
            f'start-up); 1: one UAV from start_m to goal_m over mavlink_url; K >= 2: each '
            f'vehicle\'s outputs under uav1/ ... uavK/',
    'uav_starts_m': 'with uavs >= 2: each UAV\'s launch point q0_k as a flat list x1, y1, x2, '
                    'y2, ... in frame_id (m), K points; start_m and goal_m are not used',
    'uav_goals_m': 'with uavs >= 2: each UAV\'s landing point qF_k, K points as uav_starts_m',
    'mavlink_urls': 'with uavs >= 2: one vehicle link per UAV, in order, as mavlink_url takes '
                    'it (each vehicle gets its own mission); empty: no links',
    'min_separation_m': f'with uavs >= 2: d_min, the least distance between any two UAVs at '
                        f'every slot (m; default {DEFAULT_SEPARATION_M:g}, Wu 2018\'s); the '
                        f'missions keep it as the autopilot times them; 0: they may meet',
}


@dataclass(frozen=True)
class FleetNodeSettings:
    """The fleet parameters (module docstring), each checked on its own."""

    uavs: int = 1
    uav_starts_m: tuple[Point, ...] = ()
    uav_goals_m: tuple[Point, ...] = ()
    mavlink_urls: tuple[str, ...] = ()
    min_separation_m: float = DEFAULT_SEPARATION_M

    def __post_init__(self) -> None:
        if isinstance(self.uavs, bool) or not isinstance(self.uavs, int) \
                or not 1 <= self.uavs <= MAX_UAVS:
            raise InvalidScenarioError(
                f'uavs must be a whole number of UAVs from 1 to {MAX_UAVS}, got {self.uavs!r}')
        separation = self.min_separation_m
        if (isinstance(separation, bool) or not isinstance(separation, (int, float))
                or not math.isfinite(separation) or separation < 0):
            raise InvalidScenarioError(
                f'min_separation_m must be a finite number >= 0, got {separation!r}')
        for url in self.mavlink_urls:
            if not isinstance(url, str) or not url:
                raise InvalidScenarioError(f'mavlink_urls must hold one non-empty link per '
                                           f'vehicle, got {list(self.mavlink_urls)!r}')
            parse_link_url(url)
        if len(set(self.mavlink_urls)) != len(self.mavlink_urls):
            raise InvalidScenarioError(f'mavlink_urls names a link twice: '
                                       f'{list(self.mavlink_urls)!r}; one vehicle per link')

    @property
    def is_fleet(self) -> bool:
        return self.uavs > 1


def first_vehicle_ends(fleet: FleetNodeSettings) -> dict[str, Point]:
    """With ``uavs`` >= 2 and the ends given, UAV 1's start and goal as the scenario's
    ``start_m`` and ``goal_m`` (which a fleet does not use otherwise), so that the scenario's
    own checks hold for a UAV that flies; else nothing."""
    if fleet.is_fleet and fleet.uav_starts_m and fleet.uav_goals_m:
        return {'start_m': fleet.uav_starts_m[0], 'goal_m': fleet.uav_goals_m[0]}
    return {}


def fleet_of(fleet: FleetNodeSettings, scenario: Scenario, settings: SolverSettings, node,
             vehicle: VehicleLimits) -> FleetScenario | None:
    """The fleet the parameters describe (None with one UAV), over ``scenario`` (every UAV's
    nodes, radio, speed, horizon and slots), within the compute budget of ``settings`` (K x N
    x M), with ``node``'s settings (a :class:`~uav_comm_planner.ros.params.NodeSettings`) and
    the vehicle's limits ``vehicle``: a vehicle-aware fleet must reach each goal in time.
    Raises InvalidScenarioError with what to change."""
    if not fleet.is_fleet:
        given = [name for name in ('uav_starts_m', 'uav_goals_m', 'mavlink_urls')
                 if getattr(fleet, name)] + (
            ['min_separation_m'] if fleet.min_separation_m != DEFAULT_SEPARATION_M else [])
        if given:
            raise InvalidScenarioError(
                f'{", ".join(given)} set but uavs is 1: one UAV flies from start_m to goal_m '
                f'over mavlink_url; start the node with uavs >= 2 to plan a fleet')
        return None
    count = fleet.uavs
    for name in ('uav_starts_m', 'uav_goals_m'):
        got = len(getattr(fleet, name))
        if got != count:
            raise InvalidScenarioError(
                f'{name} must hold one point per UAV, x1, y1, x2, y2, ...: uavs is {count}, '
                f'got {got} point' + ('' if got == 1 else 's'))
    if fleet.mavlink_urls and len(fleet.mavlink_urls) != count:
        raise InvalidScenarioError(
            f'mavlink_urls must hold one link per UAV (or none): uavs is {count}, got '
            f'{len(fleet.mavlink_urls)}')
    if node.mavlink_url:
        raise InvalidScenarioError('mavlink_url is for one UAV: with uavs >= 2 each vehicle\'s '
                                   'link goes in mavlink_urls, in order')
    if node.flight_mode != 'mission':
        raise InvalidScenarioError(f'flight_mode {node.flight_mode!r} is for one UAV: a fleet '
                                   f'flies its missions (flight_mode mission)')
    planned = FleetScenario(scenario, fleet.uav_starts_m, fleet.uav_goals_m,
                            fleet.min_separation_m)
    check_budget(planned, settings)
    if node.vehicle_aware:
        for own in planned.vehicles:
            check_goal_in_time(own, vehicle, node.mission_firmware)
    return planned


__all__ = ['FLEET_DESCRIPTIONS', 'first_vehicle_ends', 'FleetNodeSettings', 'fleet_of']
