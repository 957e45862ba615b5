"""ArduCopter software-in-the-loop: start it, fly a mission, record the flight.

For the flight tests and the benchmark, and for an integrator who wants to see a plan flown
before a real vehicle flies it. The binary is ArduPilot's ``arducopter`` built for the SITL
board (``./waf configure --board sitl && ./waf copter``): the path given, else
``$UAV_COMM_PLANNER_SITL``, else ``arducopter`` on the PATH; ArduPilot's ``copter.parm``
beside it is loaded as defaults when present. Each vehicle runs in its own folder on its own
``-I`` instance (TCP port 5760 + 10 I), at a speedup, and is ended by its PID. Every time here
is autopilot time (``time_boot_ms``), never the wall clock.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import json
import os
from pathlib import Path
import shutil
import socket
import subprocess
import time

import numpy as np
from pymavlink import mavutil

from uav_comm_planner.errors import VehicleLinkError
from uav_comm_planner.vehicle.evaluation import evaluate_flight, FlightReport
from uav_comm_planner.vehicle.fence import fence_from_zones
from uav_comm_planner.vehicle.flyable import VehiclePlan
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.mavlink.fence import fence_items, MISSION_TYPE_FENCE
from uav_comm_planner.vehicle.mavlink.guided import set_mode
from uav_comm_planner.vehicle.mavlink.items import (build_mission_items, NAV_WAYPOINT, Q0_SEQ,
                                                    TAKEOFF_SEQ)
from uav_comm_planner.vehicle.mavlink.link import (connect, download_mission,
                                                   upload_and_verify)
from uav_comm_planner.vehicle.mavlink.telemetry import global_position_enu, request_telemetry

MAV = mavutil.mavlink
ENVIRONMENT_VARIABLE = 'UAV_COMM_PLANNER_SITL'
SPEEDUP = 20
BASE_PORT = 5760
#: Commands ArduCopter refuses while its EKF and GPS settle are retried for this long.
READY_TIMEOUT_S = 180.0
#: ArduCopter's fence parameters for a plan with zones: the uploaded inclusion and exclusion
#: zones only (FENCE_TYPE 4), not the altitude (1) or home-circle (2) fences, which the
#: plans' 100 m over kilometres would breach.
FENCE_PARAMETERS = {'FENCE_ENABLE': 1, 'FENCE_TYPE': 4}


def sitl_binary(path: str | os.PathLike | None = None) -> Path | None:
    """The ArduCopter SITL executable, or None when there is none to run."""
    candidates = [path, os.environ.get(ENVIRONMENT_VARIABLE), shutil.which('arducopter')]
    for candidate in candidates:
        if candidate and Path(candidate).is_file() and os.access(candidate, os.X_OK):
            return Path(candidate).resolve()   # the SITL runs in a folder of its own
    return None


def why_not_runnable(path: str | os.PathLike | None = None) -> str:
    """Empty when SITL can run here, else the reason."""
    binary = sitl_binary(path)
    if binary is None:
        return (f'no ArduCopter SITL binary: set {ENVIRONMENT_VARIABLE} or put arducopter on '
                f'the PATH')
    try:
        subprocess.run([str(binary), '--help'], capture_output=True, timeout=20)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f'{binary} cannot run on this machine: {exc}'
    return ''


def _port_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind(('127.0.0.1', port))
        except OSError:
            return False
    return True


#: Instances this process has handed out, oldest first: a port just closed may linger, so an
#: instance is handed out again only once every other one in its range has been.
_USED_INSTANCES: list[int] = []


def free_instance(first: int = 10, last: int = 59) -> int:
    """An instance number whose MAVLink port and its neighbours are free; processes start
    their search at different places, so that test runs side by side rarely meet. Instances
    this process has not used yet come first, then those it used longest ago."""
    span = last - first + 1
    start = first + os.getpid() % span
    ring = [first + (start - first + offset) % span for offset in range(span)]
    fresh = [instance for instance in ring if instance not in _USED_INSTANCES]
    again = [instance for instance in _USED_INSTANCES if first <= instance <= last]
    for instance in fresh + again:
        base = BASE_PORT + 10 * instance
        if all(_port_free(base + k) for k in range(3)):
            if instance in _USED_INSTANCES:
                _USED_INSTANCES.remove(instance)
            _USED_INSTANCES.append(instance)
            return instance
    raise VehicleLinkError(f'no free SITL instance between {first} and {last}')


@dataclass
class Sitl:
    """A running ArduCopter SITL; ``url`` is its MAVLink TCP address."""

    process: subprocess.Popen
    instance: int
    home: Home
    folder: Path

    @property
    def url(self) -> str:
        return f'tcp:127.0.0.1:{BASE_PORT + 10 * self.instance}'

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(10)


#: The frame model file of a SITL started with its own frame keys.
FRAME_FILE = 'frame.json'
#: What ArduCopter SITL prints once its MAVLink port listens.
LISTENING = b'Waiting for connection'
START_ATTEMPTS = 3


def start_sitl(folder: Path, home: Home, *, speedup: int = SPEEDUP,
               binary: str | os.PathLike | None = None, timeout_s: float = 60.0,
               instances: tuple[int, int] = (10, 59), frame: dict | None = None) -> Sitl:
    """Start ArduCopter in ``folder`` (wiped parameters, ArduPilot's copter defaults) on an
    instance number within ``instances`` (first, last) and return once its MAVLink port
    listens; a start that fails (a port taken meanwhile) is tried again on another
    instance. ``frame``: keys of ArduPilot's frame model (libraries/SITL/SIM_Frame.cpp, e.g.
    ``battCapacityAh``) that replace the ``+`` quad's, written to ``frame.json`` in ``folder``
    (the SITL reads the file by a path relative to its working folder)."""
    binary = sitl_binary(binary)
    if binary is None:
        raise VehicleLinkError(why_not_runnable())
    defaults = binary.parent / 'copter.parm'
    log_path = folder / 'sitl.log'
    model = '+'
    if frame:
        (folder / FRAME_FILE).write_text(json.dumps(frame))
        model = f'+:{FRAME_FILE}'
    for attempt in range(START_ATTEMPTS):
        instance = free_instance(*instances)
        command = [str(binary), '--model', model, '--speedup', str(speedup), '-w',
                   f'-I{instance}',
                   '--home', f'{home.latitude_deg},{home.longitude_deg},{home.altitude_m},0']
        if defaults.is_file():
            command += ['--defaults', str(defaults)]
        with open(log_path, 'wb') as log:
            process = subprocess.Popen(command, cwd=folder, stdout=log,
                                       stderr=subprocess.STDOUT)
        sitl = Sitl(process, instance, home, folder)
        deadline = time.monotonic() + timeout_s
        while process.poll() is None and time.monotonic() < deadline:
            if LISTENING in log_path.read_bytes():
                return sitl
            time.sleep(0.1)
        sitl.stop()
    raise VehicleLinkError(f'ArduCopter SITL did not start in {START_ATTEMPTS} attempts; see '
                           f'{log_path}')


def open_link(sitl: Sitl, timeout_s: float = 60.0):
    """Connect to the SITL's MAVLink port; returns a pymavlink connection."""
    if sitl.process.poll() is not None:
        raise VehicleLinkError(f'SITL exited with {sitl.process.returncode}; see '
                               f'{sitl.folder / "sitl.log"}')
    return connect(sitl.url, timeout_s=timeout_s)


def set_parameter(link, name: str, value: float, timeout_s: float = 10.0) -> None:
    """PARAM_SET until PARAM_VALUE confirms ``value``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        link.mav.param_set_send(link.target_system, link.target_component, name.encode(),
                                float(value), MAV.MAV_PARAM_TYPE_REAL32)
        reply = link.recv_match(type='PARAM_VALUE', blocking=True, timeout=1.0)
        if reply is not None and reply.param_id == name and abs(reply.param_value - value) < 1e-3:
            return
    raise VehicleLinkError(f'{name} was not set to {value}')


def _command(link, command: int, *params: float, timeout_s: float = 3.0) -> int:
    padded = list(params) + [0.0] * (7 - len(params))
    link.mav.command_long_send(link.target_system, link.target_component, command, 0, *padded)
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        ack = link.recv_match(type='COMMAND_ACK', blocking=True, timeout=0.5)
        if ack is not None and ack.command == command:
            return ack.result
    return -1


def take_off(link, altitude_m: float) -> None:
    """GUIDED, arm as soon as the autopilot allows, take off at once (idle disarms fast)."""
    deadline = time.monotonic() + READY_TIMEOUT_S
    while time.monotonic() < deadline:
        set_mode(link, 'GUIDED')
        if _command(link, MAV.MAV_CMD_COMPONENT_ARM_DISARM, 1) == MAV.MAV_RESULT_ACCEPTED:
            if _command(link, MAV.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0,
                        altitude_m) == MAV.MAV_RESULT_ACCEPTED:
                return
        time.sleep(1.0)
    raise VehicleLinkError(f'ArduCopter did not arm and take off within {READY_TIMEOUT_S:g} s')


@dataclass
class FlightRecord:
    """What the vehicle did: positions east, north (K, 2) metres from home at times (K,) s.

    ``reached`` maps a mission item's sequence number to the autopilot time (s) at which
    ArduCopter announced it reached it ("Reached command #N"); ``modes`` are the flight modes
    its heartbeats reported after the switch to AUTO (an RTL or LAND there is a fence
    breach's action), and ``fence_breaches`` the largest FENCE_STATUS breach count seen
    (None: no FENCE_STATUS came, the fence being off). ``battery_times_s`` and
    ``battery_energy_j``: BATTERY_STATUS's energy_consumed (J; BATT_MONITOR 4 reads the
    simulated battery, copter.parm's setting), each at the autopilot time of the last position
    before it.
    """

    times_s: np.ndarray
    positions_m: np.ndarray
    altitudes_m: np.ndarray
    reached: dict[int, float] = field(default_factory=dict)
    modes: frozenset[int] = frozenset()
    fence_breaches: int | None = None
    battery_times_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    battery_energy_j: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def energy_between_j(self, start_s: float, end_s: float) -> float:
        """The battery's energy used from ``start_s`` to ``end_s`` (autopilot s), J, from the
        readings nearest those times."""
        if not len(self.battery_times_s):
            raise ValueError('no BATTERY_STATUS was recorded')
        at = [int(np.argmin(np.abs(self.battery_times_s - t))) for t in (start_s, end_s)]
        return float(self.battery_energy_j[at[1]] - self.battery_energy_j[at[0]])


def fly_auto(link, home: Home, *, last_item: int, timeout_s: float) -> FlightRecord:
    """Switch to AUTO and record GLOBAL_POSITION_INT until item ``last_item`` is reached.

    ``timeout_s`` is autopilot time after the switch.
    """
    request_telemetry(link)
    link.mav.command_long_send(link.target_system, link.target_component,
                               MAV.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                               MAV.MAVLINK_MSG_ID_FENCE_STATUS, 1e6, 0, 0, 0, 0, 0)
    link.mav.command_long_send(link.target_system, link.target_component,
                               MAV.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                               MAV.MAVLINK_MSG_ID_BATTERY_STATUS, 1e5, 0, 0, 0, 0, 0)
    set_mode(link, 'AUTO')
    times, latitudes_e7, longitudes_e7, altitudes_mm = [], [], [], []
    reached: dict[int, float] = {}
    modes: set[int] = set()
    breaches: int | None = None
    battery_times, battery_energy = [], []
    clock_s = None
    started_s = None
    while True:
        message = link.recv_match(type=['GLOBAL_POSITION_INT', 'STATUSTEXT', 'HEARTBEAT',
                                        'FENCE_STATUS', 'BATTERY_STATUS'], blocking=True,
                                  timeout=10.0)
        if message is None:
            raise VehicleLinkError('the vehicle went silent during the flight')
        if message.get_type() == 'HEARTBEAT':
            if (message.get_srcSystem(), message.get_srcComponent()) == (
                    link.target_system, MAV.MAV_COMP_ID_AUTOPILOT1) and clock_s is not None:
                modes.add(message.custom_mode)
            continue
        if message.get_type() == 'FENCE_STATUS':
            breaches = max(breaches or 0, message.breach_count)
            continue
        if message.get_type() == 'BATTERY_STATUS':
            if clock_s is not None and message.id == 0 and message.energy_consumed >= 0:
                battery_times.append(clock_s)
                battery_energy.append(message.energy_consumed * 100.0)   # hJ
            continue
        if message.get_type() == 'STATUSTEXT':
            text = message.text
            if text.startswith('Reached command #') and clock_s is not None:
                reached[int(text.split('#')[1].split()[0])] = clock_s
            if last_item in reached:
                break
            continue
        clock_s = message.time_boot_ms / 1000.0
        started_s = clock_s if started_s is None else started_s
        if clock_s - started_s > timeout_s:
            raise VehicleLinkError(f'item {last_item} not reached {timeout_s:g} s after AUTO')
        times.append(clock_s)
        latitudes_e7.append(message.lat)
        longitudes_e7.append(message.lon)
        altitudes_mm.append(message.relative_alt)
    east, north, up = global_position_enu(latitudes_e7, longitudes_e7, altitudes_mm, home)
    return FlightRecord(np.array(times), np.column_stack([east, north]), up, reached,
                        frozenset(modes), breaches, np.array(battery_times),
                        np.array(battery_energy))


#: ArduCopter refuses a mission right after connecting: the upload is tried this many times.
UPLOAD_ATTEMPTS = 10


def upload(link, items, *, mission_type: int = MAV.MAV_MISSION_TYPE_MISSION) -> None:
    """Upload and verify (the mission, or the fence by ``mission_type``), retrying while the
    autopilot is still busy starting up."""
    for attempt in range(UPLOAD_ATTEMPTS):
        try:
            upload_and_verify(link, items, mission_type=mission_type)
            return
        except VehicleLinkError:
            if attempt == UPLOAD_ATTEMPTS - 1:
                raise
            time.sleep(1.0)


@dataclass(frozen=True)
class SitlFlight:
    """A vehicle plan flown in SITL: the report against the plan, and qF's arrival time (s
    after the plan's clock started); ``fence`` the fence items the vehicle held, read back
    after their upload (empty for a plan without zones)."""

    report: FlightReport
    arrival_s: float
    record: FlightRecord
    fence: tuple = ()


def fly_plan(vehicle_plan: VehiclePlan, folder: Path, *, home: Home,
             parameters: dict[str, float] | None = None,
             binary: str | os.PathLike | None = None,
             instances: tuple[int, int] = (10, 59)) -> SitlFlight:
    """Fly ``vehicle_plan``'s mission on a fresh ArduCopter SITL in ``folder``.

    ``parameters`` are set before the upload. Without zones FENCE_ENABLE is 0 (copter.parm's
    fence would end a mission that goes further than 150 m); with zones, they are uploaded as
    the vehicle's fence (read back) and enforced (:data:`FENCE_PARAMETERS`). The plan's clock
    starts when the vehicle starts holding at q0: ArduCopter announces the q0 waypoint when
    its hold ends.
    """
    scenario = vehicle_plan.ideal.scenario
    items = build_mission_items(vehicle_plan, home, firmware=vehicle_plan.schedule.firmware)
    last_waypoint = max(i for i, item in enumerate(items) if item.command == NAV_WAYPOINT)
    zones = scenario.zones
    fence = (fence_items(fence_from_zones(zones, home))
             if zones is not None and not zones.empty else [])
    vehicle = start_sitl(folder, home, binary=binary, instances=instances)
    try:
        link = open_link(vehicle)
        fence_off = {} if fence else {'FENCE_ENABLE': 0}
        for name, value in {**fence_off, **(parameters or {})}.items():
            set_parameter(link, name, value)
        held: tuple = ()
        if fence:
            upload(link, fence, mission_type=MISSION_TYPE_FENCE)
            held = tuple(download_mission(link, mission_type=MISSION_TYPE_FENCE))
            for name, value in FENCE_PARAMETERS.items():
                set_parameter(link, name, value)
        upload(link, items)
        take_off(link, items[TAKEOFF_SEQ].z)     # the altitude of q0
        horizon_s = scenario.slot_s * (scenario.num_slots + 1)
        record = fly_auto(link, home, last_item=last_waypoint, timeout_s=2 * horizon_s + 300)
        link.close()
    finally:
        vehicle.stop()
    start_s = record.reached[Q0_SEQ] - items[Q0_SEQ].params[0]
    report = evaluate_flight(vehicle_plan.flown, vehicle_plan.schedule.flight.track(),
                             record.times_s, record.positions_m, start_s)
    return SitlFlight(report, record.reached[last_waypoint] - start_s, record, held)
