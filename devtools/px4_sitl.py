"""PX4 software-in-the-loop: start PX4's SIH quadrotor, fly a mission in AUTO.MISSION, record it.

For the PX4 flight tests and for an integrator who wants to see a PX4 mission flown before a
real vehicle flies it. PX4 SITL is started by its ``run_px4.sh`` (the path given, else
``$UAV_COMM_PLANNER_PX4``): ``run_px4.sh N SPEED WORKDIR``, instance N (0..9) in a fresh
working folder, lockstep at a speed-up, ``PX4_PARAM_<NAME>`` in the environment setting
parameters at boot; it is ended by its PID. The package talks to it on PX4's onboard port
(``udpin:127.0.0.1:14540+N``, which takes reconnections), uploads with
:func:`~uav_comm_planner.vehicle.mavlink.upload.upload_file`, switches to AUTO.MISSION on the
ground and arms: PX4 takes off and flies the mission. Every time here is autopilot time
(``time_boot_ms``), never the wall clock.
"""

from __future__ import annotations

from dataclasses import dataclass
import logging
import os
from pathlib import Path
import shutil
import signal
import socket
import subprocess
import threading
import time

import numpy as np
from pymavlink import mavutil

# MAV_CMD by COMMAND_LONG until its COMMAND_ACK: the same for PX4 as for ArduCopter.
from devtools.sitl import _command, FlightRecord, SitlFlight
from uav_comm_planner.errors import VehicleLinkError
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.vehicle.evaluation import evaluate_flight
from uav_comm_planner.vehicle.firmware import PX4_AUTO, PX4_MISSION
from uav_comm_planner.vehicle.flyable import VehiclePlan
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.mavlink.files import read_mission_file
from uav_comm_planner.vehicle.mavlink.items import NAV_WAYPOINT, Q0_SEQ
from uav_comm_planner.vehicle.mavlink.link import connect
from uav_comm_planner.vehicle.mavlink.telemetry import global_position_enu
from uav_comm_planner.vehicle.mavlink.upload import upload_files

MAV = mavutil.mavlink
logger = logging.getLogger(__name__)
ENVIRONMENT_VARIABLE = 'UAV_COMM_PLANNER_PX4'
#: PX4 SITL's home (its default, Zurich): the missions flown on it are made for this home.
PX4_HOME = Home(47.397742, 8.545594, 489.0)
#: Lockstep speed-up of the flights (PX4_SIM_SPEED_FACTOR).
PX4_SPEEDUP = 20
#: PX4_PARAM_SDLOG_MODE -1: no flight log (about 1 MB per simulated second otherwise).
BOOT_PARAMETERS = {'SDLOG_MODE': -1}
#: Messages the flight needs; every other stream on the onboard port is switched off, since
#: the stream rates are in simulated time and multiply with the speed-up.
KEPT_MESSAGES = ('HEARTBEAT', 'GLOBAL_POSITION_INT', 'MISSION_ITEM_REACHED', 'STATUSTEXT',
                 'COMMAND_ACK', 'MISSION_CURRENT')
#: GLOBAL_POSITION_INT per second of autopilot time during the flight (1 m apart at 10 m/s).
POSITION_RATE_HZ = 10.0
#: A flight whose record has a longer gap (autopilot seconds) is refused: points planned in
#: the gap could not be held against it.
MAX_RECORD_GAP_S = 0.5
#: Autopilot seconds recorded after the last waypoint is reported reached, while it settles.
RECORD_AFTER_S = 8.0
#: The link's receive buffer, bytes: at a speed-up the telemetry comes many times faster.
RECEIVE_BUFFER_BYTES = 8 * 1024 * 1024
#: PX4 arms once its estimator has settled (about 5 s of autopilot time): tried this long.
READY_TIMEOUT_S = 120.0
#: PX4 has taken off once it has climbed this much since the arming (metres)...
TAKEOFF_HEIGHT_M = 1.0
#: ... which it is within this many autopilot seconds of an arming that starts the mission
#: (it climbs at about 1.5 m/s at once); else AUTO.MISSION and the arming are asked again.
TAKEOFF_WAIT_S = 20.0
#: Fresh PX4s a flight is tried on when PX4 does not take off (:class:`TakeoffError`).
FLIGHT_ATTEMPTS = 2
#: MAV_CMD_DO_SET_MODE (base mode custom, main mode AUTO, sub mode MISSION).
AUTO_MISSION = (1.0, float(PX4_AUTO), float(PX4_MISSION))


def px4_run_script(path: str | os.PathLike | None = None) -> Path | None:
    """PX4 SITL's run_px4.sh: ``path``, else ``$UAV_COMM_PLANNER_PX4``; None when neither is a
    file."""
    for candidate in (path, os.environ.get(ENVIRONMENT_VARIABLE)):
        if candidate and Path(candidate).is_file():
            return Path(candidate).resolve()
    return None


def why_px4_not_runnable(path: str | os.PathLike | None = None) -> str:
    """Empty when PX4 SITL can run here, else the reason."""
    script = px4_run_script(path)
    if script is None:
        return f'no PX4 SITL run_px4.sh at {path!r} and none in ${ENVIRONMENT_VARIABLE}'
    if os.uname().machine != 'x86_64':
        return 'the PX4 SITL binary is built for x86_64'
    return ''


def runnable_copy(script: Path, folder: Path) -> Path:
    """PX4 SITL's folder (the one holding ``script``) copied into ``folder`` without the
    ``bin/px4-*`` command links: a copy that lost them keeps each as a small file naming its
    target, which run_px4.sh takes for the links and px4's start-up script cannot run; without
    them, run_px4.sh makes the links in its working folder. Returns the copy's run_px4.sh."""
    source = script.parent
    shutil.copytree(source / 'etc', folder / 'etc')
    (folder / 'bin').mkdir()
    for name in ('px4', '.commands', 'px4-alias.sh'):
        if (source / 'bin' / name).exists():
            shutil.copy2(source / 'bin' / name, folder / 'bin' / name)
    shutil.copy2(script, folder / script.name)
    return folder / script.name


@dataclass
class Px4Sitl:
    """A running PX4 SITL, instance ``instance``."""

    process: subprocess.Popen
    instance: int
    folder: Path

    @property
    def onboard_url(self) -> str:
        return f'udpin:127.0.0.1:{14540 + self.instance}'

    @property
    def ground_station_url(self) -> str:
        return f'udpout:127.0.0.1:{18570 + self.instance}'

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            try:
                self.process.wait(20)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(10)


def start_px4(folder: Path, instance: int, *, script: str | os.PathLike | None = None,
              speedup: float = PX4_SPEEDUP,
              parameters: dict[str, float] | None = None) -> Px4Sitl:
    """Start PX4 SITL instance ``instance`` (0..9, unused by any other px4) in ``folder``
    with ``parameters`` set at boot; returns at once (:func:`open_px4` waits for it)."""
    found = px4_run_script(script)
    if found is None:
        raise VehicleLinkError(why_px4_not_runnable(script))
    copy = runnable_copy(found, folder / 'px4')
    work = folder / 'work'
    work.mkdir()
    environment = {**os.environ, **{f'PX4_PARAM_{name}': f'{value:g}' for name, value in
                                    {**BOOT_PARAMETERS, **(parameters or {})}.items()}}
    with open(folder / 'px4.log', 'wb') as log:
        process = subprocess.Popen(['sh', str(copy), str(instance), f'{speedup:g}', str(work)],
                                   env=environment, stdout=log, stderr=subprocess.STDOUT)
    return Px4Sitl(process, instance, folder)


def quiet_streams(link, keep: tuple[str, ...] = KEPT_MESSAGES, listen_s: float = 1.0) -> None:
    """Switch off every stream but ``keep`` (MAV_CMD_SET_MESSAGE_INTERVAL, interval -1): the
    streams seen within ``listen_s`` seconds (wall clock)."""
    seen = {}
    deadline = time.monotonic() + listen_s
    while time.monotonic() < deadline:
        message = link.recv_match(blocking=True, timeout=0.1)
        if message is not None and message.get_type() not in keep:
            seen[message.get_type()] = message.get_msgId()
    for message_id in seen.values():
        if message_id >= 0:
            link.mav.command_long_send(link.target_system, link.target_component,
                                       MAV.MAV_CMD_SET_MESSAGE_INTERVAL, 0, message_id, -1,
                                       0, 0, 0, 0, 0)


#: Uploads tried before a flight gives up: PX4's mission protocol times out in simulated time,
#: which a loaded machine at a speed-up can miss (PX4 then ends the transfer).
UPLOAD_ATTEMPTS = 5
#: One upload at a time from this process: flights side by side upload in turn.
_UPLOADS = threading.Lock()


def upload_with_retries(mission: Path, url: str, fence: Path | None = None) -> None:
    """:func:`upload_files` (the ``fence`` file's fence first, when given) until PX4 holds
    the mission, at most UPLOAD_ATTEMPTS times."""
    for attempt in range(UPLOAD_ATTEMPTS):
        try:
            with _UPLOADS:
                upload_files(url, mission=mission, fence=fence, connect_timeout_s=60.0)
            return
        except VehicleLinkError:
            if attempt == UPLOAD_ATTEMPTS - 1:
                raise
            time.sleep(0.5)


class TakeoffError(VehicleLinkError):
    """PX4 did not take off in AUTO.MISSION. Seen on a machine that stalled PX4 SITL for
    seconds: its simulated sensors timed out ("No valid data from Baro 0"), it landed blind
    and then refused every arming ("Resolve system health failures first"). Only a fresh PX4
    flies again."""


def ask_positions(link) -> None:
    """Ask PX4 for GLOBAL_POSITION_INT at POSITION_RATE_HZ (autopilot time) on ``link``."""
    link.mav.command_long_send(link.target_system, link.target_component,
                               MAV.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                               MAV.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 1e6 / POSITION_RATE_HZ,
                               0, 0, 0, 0, 0)


def start_mission(link) -> None:
    """AUTO.MISSION on the ground, then arm as soon as PX4 allows, until it takes off: PX4
    may accept the arming and still not start the mission (one just uploaded and not yet
    checked, say), then disarms on the ground after COM_DISARM_PRFLT: AUTO.MISSION and the
    arming are then asked again, as they are when it stays on the ground. It asks for
    GLOBAL_POSITION_INT on ``link`` (:func:`ask_positions`), which it reads for the climb."""
    deadline = time.monotonic() + READY_TIMEOUT_S
    said: list[str] = []
    ask_positions(link)
    while time.monotonic() < deadline:
        if (_command(link, MAV.MAV_CMD_DO_SET_MODE, *AUTO_MISSION) == MAV.MAV_RESULT_ACCEPTED
                and _command(link, MAV.MAV_CMD_COMPONENT_ARM_DISARM, 1)
                == MAV.MAV_RESULT_ACCEPTED and _took_off(link, deadline, said)):
            return
        time.sleep(0.5)
    heard = f'; PX4 said: {" | ".join(said[-5:])}' if said else ''
    raise TakeoffError(f'PX4 did not take off in AUTO.MISSION within '
                       f'{READY_TIMEOUT_S:g} s{heard}')


def _took_off(link, deadline: float, said: list[str]) -> bool:
    """After an accepted arming: True once PX4 has climbed TAKEOFF_HEIGHT_M above the lowest
    altitude it reported since (mean sea level: wherever home is), still armed; False when it
    disarms first or stays on the ground for TAKEOFF_WAIT_S of autopilot time. PX4's status
    texts are added to ``said``."""
    armed_s = lowest_mm = None
    armed = False           # a heartbeat sent before the arming may still come after its ack
    while time.monotonic() < deadline:
        message = link.recv_match(type=['HEARTBEAT', 'GLOBAL_POSITION_INT', 'STATUSTEXT'],
                                  blocking=True, timeout=1.0)
        if message is None or message.get_srcSystem() != link.target_system:
            continue
        kind = message.get_type()
        if kind == 'STATUSTEXT':
            said.append(message.text)
        elif kind == 'HEARTBEAT':
            if message.type != MAV.MAV_TYPE_GCS:
                now_armed = bool(message.base_mode & MAV.MAV_MODE_FLAG_SAFETY_ARMED)
                if armed and not now_armed:
                    return False
                armed = now_armed
        else:
            now_s = message.time_boot_ms / 1000.0
            armed_s = now_s if armed_s is None else armed_s
            lowest_mm = message.alt if lowest_mm is None else min(lowest_mm, message.alt)
            if message.alt - lowest_mm >= TAKEOFF_HEIGHT_M * 1000.0:
                return True
            if now_s - armed_s > TAKEOFF_WAIT_S:
                return False
    return False


def record_mission(link, home: Home, *, last_item: int, timeout_s: float) -> FlightRecord:
    """Record GLOBAL_POSITION_INT and MISSION_ITEM_REACHED until RECORD_AFTER_S after PX4
    reaches item ``last_item`` (its own numbering, from 0; PX4 reports it on entering the
    acceptance radius); ``timeout_s`` is autopilot time."""
    ask_positions(link)
    times, latitudes_e7, longitudes_e7, altitudes_mm = [], [], [], []
    reached: dict[int, float] = {}
    modes: set[int] = set()
    clock_s = started_s = None
    while last_item not in reached or clock_s < reached[last_item] + RECORD_AFTER_S:
        message = link.recv_match(type=['GLOBAL_POSITION_INT', 'MISSION_ITEM_REACHED',
                                        'HEARTBEAT'], blocking=True, timeout=10.0)
        if message is None:
            raise VehicleLinkError('PX4 went silent during the flight')
        if message.get_type() == 'HEARTBEAT':
            if link.probably_vehicle_heartbeat(message):
                modes.add(int(message.custom_mode))
            continue
        if message.get_type() == 'MISSION_ITEM_REACHED':
            if clock_s is not None:
                reached.setdefault(message.seq, clock_s)
            continue
        clock_s = message.time_boot_ms / 1000.0
        started_s = clock_s if started_s is None else started_s
        if clock_s - started_s > timeout_s:
            raise VehicleLinkError(f'item {last_item} not reached {timeout_s:g} s after the '
                                   f'start')
        times.append(clock_s)
        latitudes_e7.append(message.lat)
        longitudes_e7.append(message.lon)
        altitudes_mm.append(message.relative_alt)
    gaps = np.diff(times)
    if len(gaps) and gaps.max() > MAX_RECORD_GAP_S:
        raise VehicleLinkError(f'the telemetry has a gap of {gaps.max():.2f} s at '
                               f'{times[int(gaps.argmax())]:.1f} s (autopilot time): the machine '
                               f'is too loaded for this speed-up')
    east, north, up = global_position_enu(latitudes_e7, longitudes_e7, altitudes_mm, home)
    return FlightRecord(np.array(times), np.column_stack([east, north]), up, reached,
                        modes=frozenset(modes))


def reached_by_row(items, reached: dict[int, float]) -> dict[int, float]:
    """When PX4 reached each waypoint, by file row, from MISSION_ITEM_REACHED: a DO command
    after a waypoint (the DO_CHANGE_SPEED after a stop) runs at once, and PX4 reports only the
    later of two items reached within one of its cycles, so a waypoint missing from
    ``reached`` takes the time of the first DO row after it that was reported."""
    out = dict(reached)
    for row, item in enumerate(items):
        if row in out or item.command >= MAV.MAV_CMD_NAV_LAST:
            continue
        for later in range(row + 1, len(items)):
            if items[later].command < MAV.MAV_CMD_NAV_LAST:
                break
            if later in reached:
                out[row] = reached[later]
                break
    return out


def q0_reached_s(items, reached: dict[int, float]) -> float:
    """When PX4 reached q0 (its hold ended), from MISSION_ITEM_REACHED by file row
    (:func:`reached_by_row`)."""
    rows = reached_by_row(items, reached)
    if Q0_SEQ not in rows:
        raise VehicleLinkError(f'PX4 never reported q0 (mission row {Q0_SEQ}) reached')
    return rows[Q0_SEQ]


def fly_px4_mission(vehicle_plan: VehiclePlan, mission: Path, folder: Path, *, instance: int,
                    home: Home = PX4_HOME, parameters: dict[str, float] | None = None,
                    speedup: float = PX4_SPEEDUP, script: str | os.PathLike | None = None,
                    fence: Path | None = None) -> SitlFlight:
    """Fly the mission file ``mission`` (made from ``vehicle_plan`` for PX4 and ``home``) on a
    fresh PX4 SITL and hold the flight against the plan.

    The file is uploaded and read back with :func:`upload_files` (after the fence of the
    file ``fence``, when given: PX4 enforces it by GF_ACTION); PX4 keeps no home row, so
    the file's row k is PX4's item k - 1. The plan's clock starts when the hold at q0 starts:
    PX4 reports q0 reached when its hold ends (:func:`q0_reached_s`). A PX4 that does not
    take off (:class:`TakeoffError`) is stopped and the flight flown again on a fresh one, at
    most FLIGHT_ATTEMPTS times in all, each in a folder ``attemptK`` of ``folder``.
    """
    items = read_mission_file(mission)
    for attempt in range(FLIGHT_ATTEMPTS):
        try:
            record = _record_flight(items, mission, folder / f'attempt{attempt + 1}', home,
                                    vehicle_plan.ideal.scenario, instance=instance,
                                    parameters=parameters, speedup=speedup, script=script,
                                    fence=fence)
            break
        except TakeoffError as exc:
            if attempt == FLIGHT_ATTEMPTS - 1:
                raise
            logger.warning('%s; flying again on a fresh PX4', exc)
    last_waypoint = max(i for i, item in enumerate(items) if item.command == NAV_WAYPOINT)
    record.reached = reached_by_row(items, {seq + 1: when for seq, when in
                                            record.reached.items()})
    start_s = q0_reached_s(items, record.reached) - items[Q0_SEQ].params[0]
    report = evaluate_flight(vehicle_plan.flown, vehicle_plan.schedule.flight.track(),
                             record.times_s, record.positions_m, start_s)
    return SitlFlight(report, record.reached[last_waypoint] - start_s, record)


def _record_flight(items, mission: Path, folder: Path, home: Home, scenario: Scenario, *,
                   instance: int, parameters: dict[str, float] | None, speedup: float,
                   script: str | os.PathLike | None, fence: Path | None = None) -> FlightRecord:
    """One flight of ``mission`` on a fresh PX4 SITL in ``folder``, recorded (PX4's item
    numbers in ``reached``)."""
    last_waypoint = max(i for i, item in enumerate(items) if item.command == NAV_WAYPOINT)
    folder.mkdir(parents=True, exist_ok=True)
    vehicle = start_px4(folder, instance, script=script, speedup=speedup,
                        parameters=parameters)
    try:
        url = vehicle.onboard_url
        link = connect(url, timeout_s=60.0)
        quiet_streams(link)
        link.close()                 # the upload opens the port itself
        upload_with_retries(mission, url, fence)
        link = connect(url, timeout_s=60.0)
        try:
            link.port.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER_BYTES)
            start_mission(link)
            horizon_s = scenario.slot_s * (scenario.num_slots + 1)
            record = record_mission(link, home, last_item=last_waypoint - 1,
                                    timeout_s=2 * horizon_s + 300)
        finally:
            link.close()
    finally:
        vehicle.stop()
    return record


__all__ = ['FLIGHT_ATTEMPTS', 'PX4_HOME', 'PX4_SPEEDUP', 'Px4Sitl', 'TAKEOFF_HEIGHT_M',
           'TakeoffError', 'ask_positions', 'fly_px4_mission', 'px4_run_script',
           'runnable_copy', 'start_mission', 'start_px4', 'why_px4_not_runnable']
