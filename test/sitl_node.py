"""What the SITL tests of the linked node share: an ArduCopter SITL started in its own folder
with the test's parameters, the planner node linked to it on its second port (or through a
relay), a probe of what the node publishes (``planner_status`` and ``/diagnostics``), one
executor thread for both, and the test's own telemetry of the vehicle on the SITL's first
port, in autopilot time (``time_boot_ms``) only.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Callable

from diagnostic_msgs.msg import DiagnosticArray
import numpy as np
from pymavlink import mavutil
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter

from devtools.link_proxy import LinkProxy
from devtools.sitl import MAV, open_link, set_mode, set_parameter, start_sitl, take_off
from uav_comm_planner.ros.diagnostics import DIAGNOSTICS_QOS, TOPIC_DIAGNOSTICS
from uav_comm_planner.ros.node import PlannerNode
from uav_comm_planner.ros.publishing import STATUS_QOS, TOPIC_STATUS
from uav_comm_planner.vehicle.geodesy import geodetic_to_enu, Home
from uav_comm_planner.vehicle.mavlink.battery import JOULES_PER_HJ

HOME = Home(-35.363262, 149.165237, 584.0)
#: The autopilot estimates the wind only with its drag model on: the simulated quad's values.
DRAG = {'EK3_DRAG_BCOEF_X': 17.209, 'EK3_DRAG_BCOEF_Y': 17.209, 'EK3_DRAG_MCOEF': 0.209}
#: A held-out mission: five nodes the airframe and the planner's tests never saw, 54 slots of
#: 4 s from (0, -100) (away from the takeoff, so that the clock starts in AUTO) to (0, 900) at
#: up to 8 m/s; the vehicle's cruise is 10, time lost can be made up.
HELD_OUT = {'ground_nodes': [-223.0, 928.0, 0.0, 70.0, 61.0, 130.0, -283.0, 948.0,
                             -211.0, 622.0],
            'start_m': [0.0, -100.0], 'goal_m': [0.0, 900.0], 'max_speed_mps': 8.0,
            'horizon_s': 216.0, 'num_slots': 54, 'altitude_m': 100.0}
#: The rates (Hz) the test's own link asks its telemetry at.
TELEMETRY_HZ = {MAV.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 10.0,
                MAV.MAVLINK_MSG_ID_GPS_RAW_INT: 10.0, MAV.MAVLINK_MSG_ID_BATTERY_STATUS: 2.0}


class Telemetry:
    """The test's own telemetry, in autopilot seconds: positions ``rows`` (t, east, north, up,
    speed), GPS_RAW_INT north offsets ``raw`` (t, north), the flight ``modes`` (t, name) as the
    heartbeat changed to them, the ``battery`` (t, consumed J, remaining %), the status
    ``texts`` (t, text)."""

    def __init__(self, link, home: Home = HOME) -> None:
        self.link = link
        self.home = home
        self.rows: list[tuple[float, float, float, float, float]] = []
        self.raw: list[tuple[float, float]] = []
        self.modes: list[tuple[float, str]] = []
        self.battery: list[tuple[float, float, int]] = []
        self.texts: list[tuple[float, str]] = []
        for message_id, rate_hz in TELEMETRY_HZ.items():
            link.mav.command_long_send(link.target_system, link.target_component,
                                       MAV.MAV_CMD_SET_MESSAGE_INTERVAL, 0, message_id,
                                       1e6 / rate_hz, 0, 0, 0, 0, 0)

    @property
    def now_s(self) -> float:
        """The autopilot time of the latest position (0 before any)."""
        return self.rows[-1][0] if self.rows else 0.0

    def poll(self) -> float | None:
        """Read one message: the autopilot time when it was a position, else None (also after
        a second without any message)."""
        message = self.link.recv_match(type=['GLOBAL_POSITION_INT', 'GPS_RAW_INT', 'HEARTBEAT',
                                             'BATTERY_STATUS', 'STATUSTEXT'],
                                       blocking=True, timeout=1.0)
        kind = None if message is None else message.get_type()
        if kind == 'GLOBAL_POSITION_INT':
            east, north, _ = geodetic_to_enu(message.lat / 1e7, message.lon / 1e7,
                                             self.home.altitude_m, self.home)
            speed = math.sqrt(message.vx ** 2 + message.vy ** 2 + message.vz ** 2) / 100.0
            self.rows.append((message.time_boot_ms / 1000.0, float(east), float(north),
                              message.relative_alt / 1000.0, speed))
            return self.rows[-1][0]
        if kind == 'GPS_RAW_INT' and message.lat:
            _, north, _ = geodetic_to_enu(message.lat / 1e7, self.home.longitude_deg,
                                          self.home.altitude_m, self.home)
            self.raw.append((message.time_usec / 1e6, float(north)))
        elif kind == 'HEARTBEAT' and message.get_srcComponent() == MAV.MAV_COMP_ID_AUTOPILOT1:
            mode = mavutil.mode_string_v10(message)
            if not self.modes or self.modes[-1][1] != mode:
                self.modes.append((self.now_s, mode))
        elif kind == 'BATTERY_STATUS' and message.id == 0:
            self.battery.append((self.now_s, message.energy_consumed * JOULES_PER_HJ,
                                 message.battery_remaining))
        elif kind == 'STATUSTEXT':
            self.texts.append((self.now_s, message.text))
        return None

    def at(self, times_s: np.ndarray) -> np.ndarray:
        """(K, 5) rows interpolated at ``times_s``."""
        rows = np.array(self.rows)
        assert rows[0, 0] <= times_s.min() and times_s.max() <= rows[-1, 0] + 0.5
        return np.column_stack([times_s] + [np.interp(times_s, rows[:, 0], rows[:, k])
                                            for k in range(1, 5)])

    def mode_at(self, names: tuple[str, ...]) -> float | None:
        """The autopilot time the vehicle first took one of ``names`` (None: never)."""
        return next((t for t, mode in self.modes if mode in names), None)


class LinkedNode:
    """A SITL (``sitl_parameters`` set on it, the fence off), the planner node with
    ``parameters`` linked to it (through a :class:`LinkProxy` when ``proxy``), a probe node
    recording ``statuses`` (planner_status messages) and ``diagnostics`` (name, level,
    message, values) of /diagnostics, the errors the node reported, an executor thread, and
    the test's own link ``link``; ``wait`` and every flight end ``limit_s`` of wall clock
    after the start, a guard only (every measurement is in autopilot time)."""

    def __init__(self, ros_context, folder, parameters: dict, *, instances: tuple[int, int],
                 sitl_parameters: dict | None = None, speedup: int | None = None,
                 frame: dict | None = None, proxy: bool = False, home: Home = HOME,
                 limit_s: float = 240.0) -> None:
        self.sitl = start_sitl(folder, home, instances=instances, frame=frame,
                               **({} if speedup is None else {'speedup': speedup}))
        self.node = self.executor = self.spinner = self.proxy = self.probe = None
        self.limit_s = limit_s
        self.link = open_link(self.sitl)
        for name, value in {'FENCE_ENABLE': 0, **(sitl_parameters or {})}.items():
            set_parameter(self.link, name, value)
        port = 5762 + 10 * self.sitl.instance
        if proxy:
            self.proxy = LinkProxy(port)
        url = self.proxy.url if proxy else f'tcp:127.0.0.1:{port}'
        self.node = PlannerNode(context=ros_context, parameter_overrides=[
            Parameter(name, value=value)
            for name, value in {**parameters, 'mavlink_url': url}.items()])
        self.errors: list[str] = []
        report = self.node.report_error
        self.node.report_error = lambda message: (self.errors.append(message),
                                                  report(message))
        self.statuses: list[str] = []
        self.diagnostics: list[tuple[str, bytes, str, dict[str, str]]] = []
        self.probe = Node('sitl_probe', context=ros_context)
        self.probe.create_subscription(
            DiagnosticArray, TOPIC_STATUS,
            lambda array: self.statuses.extend(s.message for s in array.status), STATUS_QOS)
        self.probe.create_subscription(DiagnosticArray, TOPIC_DIAGNOSTICS, self._on_diagnostics,
                                       DIAGNOSTICS_QOS)
        self.executor = SingleThreadedExecutor(context=ros_context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.probe)
        self.spinner = threading.Thread(target=self.executor.spin, daemon=True)
        self.spinner.start()
        self.deadline = time.monotonic() + limit_s

    def _on_diagnostics(self, array: DiagnosticArray) -> None:
        self.diagnostics.extend((status.name, status.level, status.message,
                                 {kv.key: kv.value for kv in status.values})
                                for status in array.status)

    def states_of(self, suffix: str) -> list[tuple[bytes, str, dict[str, str]]]:
        """The /diagnostics statuses whose name ends with ``suffix``: (level, message,
        values)."""
        return [(level, message, values) for name, level, message, values in self.diagnostics
                if name.endswith(suffix)]

    def wait(self, condition: Callable[[], bool], what: str) -> None:
        while not condition():
            assert time.monotonic() < self.deadline, f'no {what} within {self.limit_s} s'
            time.sleep(0.02)

    def watch(self, telemetry: Telemetry, condition: Callable[[], bool], what: str) -> None:
        """Read ``telemetry`` (without pause: it comes faster than real time) until
        ``condition()`` holds."""
        while not condition():
            assert time.monotonic() < self.deadline, f'no {what} within {self.limit_s} s'
            telemetry.poll()

    def fly(self, during: Callable[[float, Telemetry], None], *,
            ready: Callable[[], bool] | None = None) -> Telemetry:
        """Take off, (once ``ready()``, when given) fly AUTO, call ``during(mission_s,
        telemetry)`` at every position of the test's telemetry once the node's clock runs,
        until the last slot has passed."""
        self.wait(lambda: self.node.vehicle.uploads_verified >= 1, 'mission on the vehicle')
        take_off(self.link, 100.0)
        if ready is not None:
            self.wait(ready, 'the node ready to fly')
        set_mode(self.link, 'AUTO')
        telemetry = Telemetry(self.link)
        while True:
            assert time.monotonic() < self.deadline, 'the mission did not end in time'
            now = telemetry.poll()
            progress = self.node.progress
            if now is None or not progress.started:
                continue
            during(now - progress.segments[0].start_s, telemetry)
            segment = progress.current
            if (segment.start_s is not None
                    and segment.first_slot + segment.num_slots == progress.mission.num_slots
                    and now >= segment.slot_times_s(segment.num_slots)[-1] + 0.5):
                return telemetry

    def close(self) -> None:
        if self.executor is not None:
            self.executor.shutdown()
        if self.spinner is not None:
            self.spinner.join(10)
        for made in (self.node, self.probe):
            if made is not None:
                made.destroy_node()
        if self.proxy is not None:
            self.proxy.close()
        self.sitl.stop()


def flights(ros_context, tmp_path, kind: type):
    """A fixture's body: makes ``kind(ros_context, folder, **options)`` flights, each in a
    folder of its own, and closes them after the test."""
    made = []

    def make(**options):
        folder = tmp_path / f'flight{len(made)}'
        folder.mkdir()
        made.append(kind(ros_context, folder, **options))
        return made[-1]
    yield make
    for each in made:
        each.close()
