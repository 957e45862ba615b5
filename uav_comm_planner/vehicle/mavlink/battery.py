"""The vehicle's battery as its autopilot reports it, and the commands that end a mission.

BATTERY_STATUS (battery ``id`` 0, the one the autopilot flies on) gives the energy consumed
(hJ; -1: the monitor does not count it) and the charge remaining (%; -1: unknown); SYS_STATUS
gives the remaining charge, the voltage and the current of the same battery, without the
energy. ArduCopter's BATT_MONITOR 4 (voltage and current) counts the energy; a monitor that
reads only the voltage gives the remaining charge alone. A :class:`BatteryReport` holds what
one message told, at the autopilot time of the latest position.

:func:`command_end` asks the vehicle to return to launch, land where it is, or hold where it is
(the node's ``battery_action``), as commands both ArduCopter and PX4 take.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
import threading

from pymavlink import mavutil

from uav_comm_planner.vehicle.mavlink.guided import set_mode, stream_modes

MAV = mavutil.mavlink
#: BATTERY_STATUS asked of the autopilot (per second of autopilot time); SYS_STATUS comes at
#: the autopilot's own rate.
BATTERY_RATE_HZ = 2.0
#: Joules in the hectojoule of BATTERY_STATUS.energy_consumed.
JOULES_PER_HJ = 100.0
#: What ends a mission the battery cannot fly: return to launch, land, hold.
BATTERY_ACTIONS = ('rtl', 'land', 'hold')


@dataclass(frozen=True)
class BatteryReport:
    """One battery message at ``time_s`` (autopilot s): ``consumed_j`` since the autopilot
    started (NaN: not counted), ``remaining`` the charge left as a share in [0, 1] (NaN:
    unknown), ``voltage_v`` and ``current_a`` (NaN: unknown); ``source`` the message."""

    time_s: float
    consumed_j: float
    remaining: float
    voltage_v: float
    current_a: float
    source: str


def _share(percent: int) -> float:
    """A MAVLink battery_remaining (%, -1 unknown) as a share, NaN when unknown."""
    return percent / 100.0 if 0 <= percent <= 100 else math.nan


def battery_of(message, time_s: float) -> BatteryReport | None:
    """The report of a BATTERY_STATUS (of battery 0) or SYS_STATUS message at ``time_s``;
    None for another battery, or a message that tells nothing of the battery."""
    kind = message.get_type()
    if kind == 'BATTERY_STATUS':
        if message.id != 0:
            return None
        consumed = (message.energy_consumed * JOULES_PER_HJ if message.energy_consumed >= 0
                    else math.nan)
        cells = [v for v in message.voltages[:10] if 0 < v < 65535]
        voltage = sum(cells) / 1000.0 if cells else math.nan
        current = message.current_battery / 100.0 if message.current_battery >= 0 else math.nan
        report = BatteryReport(time_s, consumed, _share(message.battery_remaining), voltage,
                               current, kind)
    elif kind == 'SYS_STATUS':
        voltage = (message.voltage_battery / 1000.0
                   if 0 < message.voltage_battery < 65535 else math.nan)
        current = message.current_battery / 100.0 if message.current_battery >= 0 else math.nan
        report = BatteryReport(time_s, math.nan, _share(message.battery_remaining), voltage,
                               current, kind)
    else:
        return None
    if math.isnan(report.consumed_j) and math.isnan(report.remaining):
        return None
    return report


def request_battery(link, rate_hz: float = BATTERY_RATE_HZ) -> None:
    """Ask the autopilot for BATTERY_STATUS at ``rate_hz`` (per second of autopilot time)."""
    link.mav.command_long_send(link.target_system, link.target_component,
                               MAV.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                               MAV.MAVLINK_MSG_ID_BATTERY_STATUS, 1e6 / rate_hz, 0, 0, 0, 0, 0)


def command_end(link, action: str) -> None:
    """Ask ``link``'s vehicle to end its mission by ``action`` (:data:`BATTERY_ACTIONS`):
    MAV_CMD_NAV_RETURN_TO_LAUNCH, MAV_CMD_NAV_LAND where it is, or its hold mode (ArduCopter's
    BRAKE, PX4's AUTO.LOITER). Raises ValueError for another action."""
    if action == 'hold':
        set_mode(link, stream_modes(link).hold)
        return
    commands = {'rtl': MAV.MAV_CMD_NAV_RETURN_TO_LAUNCH, 'land': MAV.MAV_CMD_NAV_LAND}
    if action not in commands:
        raise ValueError(f'battery action must be one of {BATTERY_ACTIONS}, got {action!r}')
    # NAV_LAND: param5-7 NaN or 0 land where the vehicle is.
    link.mav.command_long_send(link.target_system, link.target_component, commands[action], 0,
                               0, 0, 0, math.nan, 0, 0, 0)


class EndRequest:
    """The end of mission another thread asks (:meth:`ask`), sent on the link's thread
    (:meth:`send`) once."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._action: str | None = None

    def ask(self, action: str) -> None:
        with self._lock:
            self._action = action

    def send(self, link) -> None:
        """On the link's thread: the action asked, if any (:func:`command_end`)."""
        with self._lock:
            action, self._action = self._action, None
        if action is not None:
            command_end(link, action)


#: The heartbeat mode each action puts the vehicle in, as pymavlink names it (ArduCopter's,
#: then PX4's: RTL and LAND are both's names, PX4's hold is its AUTO.LOITER).
END_MODES = {'rtl': ('RTL',), 'land': ('LAND',), 'hold': ('BRAKE', 'LOITER')}


def in_end_mode(action: str, mode: str | None) -> bool:
    """Whether the heartbeat mode name ``mode`` is the one ``action`` asks for."""
    return mode is not None and mode in END_MODES.get(action, ())


__all__ = ['BATTERY_ACTIONS', 'BATTERY_RATE_HZ', 'BatteryReport', 'END_MODES', 'EndRequest',
           'battery_of',
           'command_end', 'in_end_mode', 'request_battery']
