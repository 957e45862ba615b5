"""The vehicle's own limit parameters, read over its link without holding the link up.

The limits a plan is timed with (WPNAV_SPEED, WPNAV_ACCEL, WPNAV_JERK and ATC_INPUT_TC on
ArduPilot; MPC_XY_CRUISE, MPC_ACC_HOR, MPC_JERK_AUTO and NAV_ACC_RAD on PX4: the firmware's
:attr:`~uav_comm_planner.vehicle.firmware.Firmware.parameters`) are asked by name with
PARAM_REQUEST_READ (``param_index`` -1) and taken from the PARAM_VALUE answers. A
:class:`ParameterRead` rides on the reads the connection makes anyway (the telemetry's, an
upload's): :meth:`ParameterRead.attach` puts it among the connection's message hooks, where
each message from the vehicle sends the requests that are due (:meth:`ParameterRead.poll`)
and an answer is taken (:meth:`ParameterRead.heard`), so that reading the parameters never
holds the link up (:func:`~.link.connect` with ``parameters``). A name unanswered for
:data:`PARAMETER_TIMEOUT_S` is asked again, up to :data:`PARAMETER_TRIES` times in all; one
still unanswered then is missing (an autopilot that has no such parameter does not answer).
The read is handed on once, when every name is answered or given up, as a
:class:`~uav_comm_planner.vehicle.limits.VehicleParameters`; after that a PARAM_VALUE that
changes one of the values (a ground station set it: autopilots send PARAM_VALUE to every
link after a PARAM_SET) hands the read on again.

PX4 sends integer parameters bytewise in PARAM_VALUE's float (its
MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE); ArduPilot sends their value as a float. The
limits read here are floats on both, but an integer one is decoded as its autopilot sends it.
"""

from __future__ import annotations

import math
import struct
import time
from typing import Callable

from pymavlink import mavutil

from uav_comm_planner.vehicle.firmware import firmware_name_of_autopilot, FIRMWARES
from uav_comm_planner.vehicle.limits import VehicleParameters

MAV = mavutil.mavlink
#: A request unanswered for this long (wall clock seconds, as the link's other timeouts) is
#: sent again...
PARAMETER_TIMEOUT_S = 1.0
#: ... until it has been sent this many times; a name still unanswered then is missing.
PARAMETER_TRIES = 5
#: How an integer parameter's bytes sit in PARAM_VALUE's float when it is sent bytewise.
BYTEWISE_FORMATS = {MAV.MAV_PARAM_TYPE_UINT8: '<B', MAV.MAV_PARAM_TYPE_INT8: '<b',
                    MAV.MAV_PARAM_TYPE_UINT16: '<H', MAV.MAV_PARAM_TYPE_INT16: '<h',
                    MAV.MAV_PARAM_TYPE_UINT32: '<I', MAV.MAV_PARAM_TYPE_INT32: '<i'}


def parameter_value(message, *, bytewise: bool) -> float:
    """A PARAM_VALUE's value: its float as the shortest decimal that is the same float32
    (0.15, as a ground station shows ATC_INPUT_TC, not 0.15000000596...), or with ``bytewise``
    (PX4) an integer type's value decoded from the float's bytes."""
    layout = BYTEWISE_FORMATS.get(message.param_type) if bytewise else None
    if layout is None:
        return shortest_float32(float(message.param_value))
    return float(struct.unpack_from(layout, struct.pack('<f', message.param_value))[0])


def shortest_float32(value: float) -> float:
    """The number of fewest significant digits that rounds to the same float32 as ``value``
    (``value`` itself when it is not finite or not a float32's)."""
    if not math.isfinite(value):
        return value
    try:
        single = struct.unpack('<f', struct.pack('<f', value))[0]
    except OverflowError:
        return value
    for digits in range(1, 10):     # 9 significant digits tell every float32 apart
        shown = float(f'{single:.{digits}g}')
        if struct.unpack('<f', struct.pack('<f', shown))[0] == single:
            return shown
    return single


def _same(a: float | None, b: float) -> bool:
    return a is not None and (a == b or (math.isnan(a) and math.isnan(b)))


class ParameterRead:
    """The limit parameters of the vehicle whose heartbeat named ``autopilot``, read on one
    connection (module docstring); ``clock`` is the monotonic clock the timeouts run on."""

    def __init__(self, autopilot: int | None, *, timeout_s: float = PARAMETER_TIMEOUT_S,
                 tries: int = PARAMETER_TRIES,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.firmware = firmware_name_of_autopilot(autopilot)
        self.names = tuple(FIRMWARES[self.firmware].parameters)
        self._bytewise = autopilot == MAV.MAV_AUTOPILOT_PX4
        self._timeout_s, self._tries, self._clock = timeout_s, tries, clock
        #: The values answered so far, by name.
        self.values: dict[str, float] = {}
        #: Per name asked: how many requests were sent, and when the last was.
        self.sent: dict[str, tuple[int, float]] = {}
        #: Whether the read was handed on (every name answered or given up).
        self.done = False

    def attach(self, link, on_read: Callable[[VehicleParameters], None]) -> None:
        """Read on ``link``: the first requests now, the rest from ``link``'s message hook
        (pymavlink calls it on the reading thread for every message parsed), which hands each
        read :meth:`poll` and :meth:`heard` return to ``on_read``."""
        def hook(_, message) -> None:
            if message.get_srcSystem() != link.target_system:
                return
            if message.get_type() == 'PARAM_VALUE' and (read := self.heard(message)):
                on_read(read)
            if (read := self.poll(link)) is not None:
                on_read(read)
        self.poll(link)
        link.message_hooks.append(hook)

    def poll(self, link) -> VehicleParameters | None:
        """Send the requests that are due on ``link``; the read when it has just ended."""
        if self.done:
            return None
        now = self._clock()
        for name in self.names:
            count, last = self.sent.get(name, (0, -math.inf))
            if name in self.values or count >= self._tries or now - last < self._timeout_s:
                continue
            link.mav.param_request_read_send(link.target_system, link.target_component,
                                             name.encode(), -1)
            self.sent[name] = (count + 1, now)
        return self._ended(now)

    def heard(self, message) -> VehicleParameters | None:
        """A PARAM_VALUE from the vehicle: kept when it is one of :attr:`names`; the read when
        this answer ends it, or changes a value of a read already handed on."""
        name = message.param_id
        if name not in self.names:
            return None
        value = parameter_value(message, bytewise=self._bytewise)
        if _same(self.values.get(name), value):
            return None
        self.values[name] = value
        return self.read() if self.done else self._ended(self._clock())

    def _ended(self, now: float) -> VehicleParameters | None:
        waiting = [name for name in self.names if name not in self.values
                   and (self.sent.get(name, (0, now))[0] < self._tries
                        or now - self.sent[name][1] < self._timeout_s)]
        if waiting:
            return None
        self.done = True
        return self.read()

    def read(self) -> VehicleParameters:
        """What was read so far: the values answered, and the names not (yet) answered."""
        return VehicleParameters(self.firmware, dict(self.values),
                                 tuple(name for name in self.names if name not in self.values))


__all__ = ['BYTEWISE_FORMATS', 'PARAMETER_TIMEOUT_S', 'PARAMETER_TRIES', 'ParameterRead',
           'parameter_value', 'shortest_float32']
