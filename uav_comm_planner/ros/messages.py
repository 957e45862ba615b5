"""ROS messages <-> the planner's arrays: what the node receives and publishes.

No rclpy here, only message types, so each conversion is testable without a ROS context.
Times are integer nanoseconds on the node's clock; the plan's first pose (the launch point
q0) is stamped with the plan's start time and every later pose with its planned time.
"""

from __future__ import annotations

import math
from typing import Sequence

from builtin_interfaces.msg import Duration, Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point as PointMsg
from geometry_msgs.msg import Pose, PoseArray, PoseStamped, Quaternion
from nav_msgs.msg import Path
import numpy as np
from std_msgs.msg import ColorRGBA, Float64MultiArray, Header, MultiArrayDimension
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
from visualization_msgs.msg import Marker, MarkerArray

from uav_comm_planner.core.model import flown_path, leg_lengths
from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.core.zones import Zones
from uav_comm_planner.vehicle.fence import zone_outlines

#: A leg shorter than this fraction of V delta counts as hovering: the heading is kept and
#: the waypoint is drawn as a hover point.
HOVER_FRACTION = 0.01

NANOSECONDS = 1_000_000_000


def time_msg(nanoseconds: int) -> Time:
    """A builtin_interfaces/Time for a time in integer nanoseconds."""
    seconds, rest = divmod(int(nanoseconds), NANOSECONDS)
    return Time(sec=seconds, nanosec=rest)


def nanoseconds_of(stamp: Time) -> int:
    """The time of a builtin_interfaces/Time in integer nanoseconds."""
    return stamp.sec * NANOSECONDS + stamp.nanosec


def ground_nodes_of(message: PoseArray) -> list[tuple[float, float]]:
    """The node positions (x, y) of a PoseArray, metres; z and orientation are ignored."""
    return [(float(pose.position.x), float(pose.position.y)) for pose in message.poses]


def pose_array(points: Sequence[Sequence[float]], frame_id: str) -> PoseArray:
    """A PoseArray with one pose per (x, y) point at z = 0: how ground nodes are sent."""
    message = PoseArray(header=Header(frame_id=frame_id))
    message.poses = [Pose(position=PointMsg(x=float(x), y=float(y), z=0.0)) for x, y in points]
    return message


def yaw_quaternion(yaw_rad: float) -> Quaternion:
    """The rotation by ``yaw_rad`` about z."""
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw_rad / 2.0), w=math.cos(yaw_rad / 2.0))


def _flight(result: PlanResult) -> tuple[np.ndarray, np.ndarray]:
    """q0, q[1..M], qF as (M + 2, 2) metres and their planned times (M + 2,) seconds."""
    return flown_path(result.trajectory, result.scenario), result.scenario.path_times_s


def _hovering(result: PlanResult) -> np.ndarray:
    """(M + 1,) booleans: whether each leg is short enough to count as hovering."""
    scenario = result.scenario
    return leg_lengths(result.trajectory, scenario) < HOVER_FRACTION * scenario.max_step_m


def headings(result: PlanResult) -> np.ndarray:
    """Yaw of each of the M + 2 poses along its outgoing leg (the last: its incoming leg).

    While hovering the previous heading is kept; hovering before any motion takes the
    heading of the first leg that moves (0 if none does).
    """
    points, _ = _flight(result)
    steps = np.diff(points, axis=0)
    moving = ~_hovering(result)
    yaw = np.arctan2(steps[:, 1], steps[:, 0])
    current = yaw[moving][0] if moving.any() else 0.0
    out = np.empty(len(points))
    for i, step_yaw in enumerate(yaw):
        if moving[i]:
            current = step_yaw
        out[i] = current
    out[-1] = current
    return out


def path_message(result: PlanResult, frame_id: str, start_ns: int) -> Path:
    """nav_msgs/Path: q0, one pose per slot, qF (M + 2 poses) at z = H, stamped in time."""
    points, times = _flight(result)
    altitude = result.scenario.altitude_m
    message = Path(header=Header(frame_id=frame_id, stamp=time_msg(start_ns)))
    for (x, y), t, yaw in zip(points, times, headings(result)):
        pose = PoseStamped(header=Header(
            frame_id=frame_id, stamp=time_msg(start_ns + round(t * NANOSECONDS))))
        pose.pose.position = PointMsg(x=float(x), y=float(y), z=float(altitude))
        pose.pose.orientation = yaw_quaternion(float(yaw))
        message.poses.append(pose)
    return message


def power_message(result: PlanResult) -> Float64MultiArray:
    """p as std_msgs/Float64MultiArray in watts: dims ``slot`` (M) then ``node`` (N).

    Row-major: the power for node n in slot m is ``data[m * N + n]``.
    """
    nodes, slots = result.power.shape
    message = Float64MultiArray()
    message.layout.dim = [
        MultiArrayDimension(label='slot', size=slots, stride=slots * nodes),
        MultiArrayDimension(label='node', size=nodes, stride=nodes),
    ]
    message.layout.data_offset = 0
    message.data = np.ascontiguousarray(result.power.T, dtype=float).ravel().tolist()
    return message


def node_names(num_nodes: int) -> list[str]:
    """``node_1`` .. ``node_N``: the names of the nodes' power channels."""
    return [f'node_{n + 1}' for n in range(num_nodes)]


def duration_msg(seconds: float) -> Duration:
    """A builtin_interfaces/Duration for ``seconds`` >= 0."""
    whole, rest = divmod(round(seconds * NANOSECONDS), NANOSECONDS)
    return Duration(sec=int(whole), nanosec=int(rest))


def power_plan_message(result: PlanResult, frame_id: str, stamp_ns: int) -> JointTrajectory:
    """The power schedule, stamped: trajectory_msgs/JointTrajectory with one joint per node.

    header.stamp is the plan stamp (the one on ``planned_path``); joint_names are
    ``node_1`` .. ``node_N``; point m (m = 1..M) holds p_n[m] in watts in ``positions`` (in
    joint order) and the slot's end, m delta, in ``time_from_start``: the transmit power of
    slot m, flown while the UAV moves from q[m-1] to q[m].
    """
    message = JointTrajectory(header=Header(frame_id=frame_id, stamp=time_msg(stamp_ns)))
    message.joint_names = node_names(result.power.shape[0])
    for power, t in zip(result.power.T, result.scenario.times_s):
        message.points.append(JointTrajectoryPoint(
            positions=[float(v) for v in power], time_from_start=duration_msg(float(t))))
    return message


def nodes_text(points: Sequence[Sequence[float]]) -> str:
    """Node positions as ``x1,y1;x2,y2;...`` with every float exact (repr), as the status
    names the node set a request was for."""
    return ';'.join(f'{float(x)!r},{float(y)!r}' for x, y in points)


#: Name of the planner's DiagnosticStatus.
STATUS_NAME = 'uav_comm_planner: plan'
PLANNED = 'planned'
REFUSED = 'refused'


def one_line(text: str) -> str:
    """``text`` on one line, whole: line breaks become spaces, nothing is cut."""
    return ' '.join(text.splitlines())


def status_message(stamp_ns: int, *, request: str, planned: bool, message: str,
                   values: dict[str, object] | None = None,
                   hardware_id: str = '') -> DiagnosticArray:
    """diagnostic_msgs/DiagnosticArray saying whether one request was planned or refused.

    header.stamp is the plan stamp for a plan (the same as on every output of that plan), the
    time of the refusal otherwise. One status, named :data:`STATUS_NAME`, of ``hardware_id``
    (the node's fully qualified name): level OK and message ``planned: ...``, or level ERROR
    and ``refused: <reason>``, on one line and whole; its values carry ``request`` (what asked
    for the plan: ``ground_nodes``, ``uav_pose``, ``parameters ...``) and whatever else is
    known (``nodes``, ``min_throughput_bps``, ...), as text.
    """
    status = DiagnosticStatus(
        level=DiagnosticStatus.OK if planned else DiagnosticStatus.ERROR,
        name=STATUS_NAME, hardware_id=hardware_id,
        message=one_line(f'{PLANNED if planned else REFUSED}: {message}'))
    status.values = [KeyValue(key='request', value=request)] + [
        KeyValue(key=key, value=str(value)) for key, value in (values or {}).items()]
    return DiagnosticArray(header=Header(stamp=time_msg(stamp_ns)), status=[status])


def status_values(message: DiagnosticArray) -> dict[str, str]:
    """The key-value pairs of the planner's status in ``message`` ({} if none)."""
    for status in message.status:
        if status.name == STATUS_NAME:
            return {pair.key: pair.value for pair in status.values}
    return {}


def _points(xy: np.ndarray, z: float) -> list[PointMsg]:
    return [PointMsg(x=float(x), y=float(y), z=float(z)) for x, y in xy]


def _marker(header: Header, namespace: str, kind: int, scale: float,
            color: tuple[float, float, float]) -> Marker:
    marker = Marker(header=header, ns=namespace, id=0, type=kind, action=Marker.ADD)
    marker.pose.orientation.w = 1.0
    marker.scale.x = marker.scale.y = marker.scale.z = float(scale)
    marker.color = ColorRGBA(r=color[0], g=color[1], b=color[2], a=1.0)
    return marker


def marker_array(result: PlanResult, frame_id: str, start_ns: int) -> MarkerArray:
    """RViz markers: ground nodes (``ground_nodes``), the path (``path``), hover points.

    Sizes scale with V delta so that they stay visible at any scenario size.
    """
    scenario = result.scenario
    header = Header(frame_id=frame_id, stamp=time_msg(start_ns))
    size = max(scenario.max_step_m, 1e-3)
    nodes = _marker(header, 'ground_nodes', Marker.SPHERE_LIST, 0.5 * size, (0.9, 0.3, 0.1))
    nodes.points = _points(scenario.nodes, 0.0)
    points, _ = _flight(result)
    path = _marker(header, 'path', Marker.LINE_STRIP, 0.1 * size, (0.1, 0.4, 0.9))
    path.points = _points(points, scenario.altitude_m)
    hover = _marker(header, 'hover_points', Marker.SPHERE_LIST, 0.3 * size, (0.1, 0.8, 0.2))
    hover_waypoints = result.trajectory[_hovering(result)[:-1]]
    hover.points = _points(hover_waypoints, scenario.altitude_m)
    return MarkerArray(markers=[nodes, path, hover])


#: Line width of the zones' outlines, metres.
ZONE_LINE_M = 2.0
ZONE_COLORS = {'area': (0.1, 0.7, 0.2), 'keep_out': (0.9, 0.1, 0.1)}


def zone_markers(zones: Zones | None, frame_id: str, stamp_ns: int, *,
                 altitude_m: float = 0.0) -> MarkerArray:
    """RViz markers of the zones: a DELETEALL (clearing zones shown before), then one
    LINE_STRIP per zone at ``altitude_m``, closed, namespace ``operating_area`` (green) or
    ``keep_out`` (red, ids 0, 1, ... in the zones' order)."""
    header = Header(frame_id=frame_id, stamp=time_msg(stamp_ns))
    markers = [Marker(header=header, action=Marker.DELETEALL)]
    counts: dict[str, int] = {}
    for kind, ring in zone_outlines(zones) if zones is not None else ():
        marker = _marker(header, 'operating_area' if kind == 'area' else 'keep_out',
                         Marker.LINE_STRIP, ZONE_LINE_M, ZONE_COLORS[kind])
        marker.id = counts.get(kind, 0)
        counts[kind] = marker.id + 1
        marker.points = _points(ring, altitude_m)
        markers.append(marker)
    return MarkerArray(markers=markers)


__all__ = ['HOVER_FRACTION', 'PLANNED', 'REFUSED', 'STATUS_NAME', 'duration_msg',
           'ground_nodes_of', 'headings', 'marker_array', 'nanoseconds_of', 'node_names',
           'nodes_text', 'one_line', 'path_message', 'pose_array', 'power_message',
           'power_plan_message', 'status_message', 'status_values', 'time_msg', 'yaw_quaternion',
           'zone_markers']
