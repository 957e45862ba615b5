"""A geofence as MAVLink fence items (mission type MAV_MISSION_TYPE_FENCE), and back.

A polygon of K vertices is K items MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION (or _EXCLUSION),
each with param1 = K and its vertex in x, y (latitude, longitude); a circle is one
MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION (or _EXCLUSION) with param1 = its radius in metres and its
centre in x, y. ArduPilot and PX4 take the same items; neither has a home row in its fence.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from pymavlink import mavutil

from uav_comm_planner.core.zones import Zones
from uav_comm_planner.errors import VehicleLinkError
from uav_comm_planner.vehicle.fence import FenceCircle, FencePolygon, GeoFence
from uav_comm_planner.vehicle.geodesy import geodetic_to_plane, Home
from uav_comm_planner.vehicle.mavlink.items import (FRAME_GLOBAL, MissionItem, NAV_LAND,
                                                    NAV_WAYPOINT, Q0_SEQ)

MAV = mavutil.mavlink
MISSION_TYPE_FENCE = MAV.MAV_MISSION_TYPE_FENCE
VERTEX = {True: MAV.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
          False: MAV.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION}
CIRCLE = {True: MAV.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION,
          False: MAV.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION}


def fence_items(fence: GeoFence) -> list[MissionItem]:
    """The fence items of ``fence``: its polygons' vertices, then its circles."""
    items = []
    for polygon in fence.polygons:
        count = float(len(polygon.vertices_deg))
        items += [MissionItem(VERTEX[polygon.inclusion], FRAME_GLOBAL, (count, 0.0, 0.0, 0.0),
                              latitude, longitude, 0.0)
                  for latitude, longitude in polygon.vertices_deg]
    items += [MissionItem(CIRCLE[circle.inclusion], FRAME_GLOBAL,
                          (circle.radius_m, 0.0, 0.0, 0.0), *circle.center_deg, 0.0)
              for circle in fence.circles]
    return items


def fence_from_items(items: Sequence[MissionItem]) -> GeoFence:
    """The geofence a vehicle's fence items hold (a read-back); VehicleLinkError for items
    that are not a fence (another command, a polygon cut short)."""
    polygons, circles = [], []
    inclusion_of = {**{c: k for k, c in VERTEX.items()}, **{c: k for k, c in CIRCLE.items()}}
    seq = 0
    while seq < len(items):
        item = items[seq]
        if item.command in CIRCLE.values():
            circles.append(FenceCircle(inclusion_of[item.command], (item.x, item.y),
                                       float(item.params[0])))
            seq += 1
            continue
        if item.command not in VERTEX.values():
            raise VehicleLinkError(f'fence item {seq} has command {item.command}, not a fence '
                                   f'vertex or circle')
        count = int(item.params[0])
        vertices = items[seq:seq + count]
        if count < 3 or len(vertices) < count or any(
                v.command != item.command or int(v.params[0]) != count for v in vertices):
            raise VehicleLinkError(f'fence item {seq} starts a polygon of {count} vertices '
                                   f'that the items after it do not complete')
        polygons.append(FencePolygon(inclusion_of[item.command],
                                     tuple((v.x, v.y) for v in vertices)))
        seq += count
    return GeoFence(tuple(polygons), tuple(circles))


def mission_clearance(items: Sequence[MissionItem], home: Home, zones: Zones) -> float:
    """The least clearance from ``zones`` of the path a mission's rows fly, from q0 (row
    :data:`~.items.Q0_SEQ`) through every waypoint to the landing point, legs included
    (:meth:`~uav_comm_planner.core.zones.Zones.path_clearance`): negative where a leg enters a
    keep-out zone or leaves the operating area. The climb from home to q0 is not planned and
    not counted."""
    points = [(item.x, item.y) for item in items[Q0_SEQ:]
              if item.command in (NAV_WAYPOINT, NAV_LAND)]
    if not points:
        return float('inf')
    latitude, longitude = np.array(points).T
    east, north, _ = geodetic_to_plane(latitude, longitude, home)
    return zones.path_clearance(np.column_stack([east, north]))


__all__ = ['MISSION_TYPE_FENCE', 'fence_from_items', 'fence_items', 'mission_clearance']
