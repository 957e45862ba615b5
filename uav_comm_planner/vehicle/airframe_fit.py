"""An airframe fitted to a flight: power samples from a MAVLink log, steady ones kept.

A user calibrates the propulsion model to their own vehicle by flying it (level legs at a few
steady airspeeds, a climb and a descent) with a telemetry log recorded, then
``uav-comm-planner fit-airframe LOG.tlog --name NAME --output FILE.yaml``. From the tlog:

- power: BATTERY_STATUS of battery 0 (the sum of its known cell voltages, ``voltages`` and
  ``voltages_ext``, times ``current_battery``), else SYS_STATUS (``voltage_battery`` times
  ``current_battery``); messages that say "unknown" (UINT16_MAX volts, -1 current) are skipped;
- speeds: VFR_HUD (``airspeed``, ``climb``), else GLOBAL_POSITION_INT (horizontal speed from
  ``vx``, ``vy``, which is the airspeed only in still air; climb ``-vz``);
- time: the autopilot's (the latest ``time_boot_ms`` of any message), the tlog's own stamps
  only for a log without any;
- in flight only: armed (HEARTBEAT of the autopilot) and, when GLOBAL_POSITION_INT is logged,
  at least :data:`MIN_HEIGHT_M` above home.

Each power message gives a :class:`PowerSample` with the latest speeds (heard within
:data:`MAX_SPEED_AGE_S`). A sample is steady (:func:`steady_mask`) when over
:data:`STEADY_WINDOW_S` either side of it the airspeed and the climb rate each stay within
:data:`STEADY_TOLERANCE_MPS` (max - min): accelerations, turns and the power's transients are
left out. The fit itself is :func:`uav_comm_planner.core.propulsion_fit.fit_airframe`.
"""

from __future__ import annotations

import csv
from dataclasses import astuple, dataclass, fields
import io
import math
import os
from pathlib import Path
import struct

import numpy as np
from pymavlink import mavutil

from uav_comm_planner.core.propulsion_fit import AirframeFit, fit_airframe
from uav_comm_planner.errors import InvalidScenarioError, MissionFileError

MAV = mavutil.mavlink
#: Seconds either side of a sample over which its speeds must hold, and how closely (m/s).
STEADY_WINDOW_S = 5.0
STEADY_TOLERANCE_MPS = 0.25
#: Speeds older than this (autopilot s) at a power message leave it out.
MAX_SPEED_AGE_S = 1.5
#: Samples lower than this above home (m) are on the ground or taking off.
MIN_HEIGHT_M = 2.0
#: Fewest steady samples a log must give.
MIN_STEADY_SAMPLES = 20
_UNKNOWN_MV = 65535
_TYPES = ['BATTERY_STATUS', 'SYS_STATUS', 'VFR_HUD', 'GLOBAL_POSITION_INT', 'HEARTBEAT',
          'SYSTEM_TIME', 'ATTITUDE']     # the last two for the autopilot's clock


@dataclass(frozen=True)
class PowerSample:
    """Power at one moment: autopilot time (s), airspeed and climb rate (m/s, up positive),
    electrical power (W), and the height above home (m; NaN when not logged)."""

    time_s: float
    airspeed_mps: float
    climb_mps: float
    power_w: float
    height_m: float = math.nan


def _battery_power(message) -> float | None:
    """W of a BATTERY_STATUS or SYS_STATUS, None when it does not say."""
    if message.get_type() == 'BATTERY_STATUS':
        if getattr(message, 'id', 0) != 0 or message.current_battery < 0:
            return None
        cells = list(message.voltages) + list(getattr(message, 'voltages_ext', None) or [])
        known = [mv for mv in cells if mv not in (_UNKNOWN_MV, 0)]
        if not known:
            return None
        return sum(known) / 1000.0 * message.current_battery / 100.0
    if message.voltage_battery in (_UNKNOWN_MV, 0) or message.current_battery < 0:
        return None
    return message.voltage_battery / 1000.0 * message.current_battery / 100.0


def read_tlog(path: str | os.PathLike) -> list[PowerSample]:
    """The in-flight power samples of a MAVLink telemetry log (module docstring).

    Raises :class:`~uav_comm_planner.errors.MissionFileError` for a missing or unreadable
    file, or a log without battery power or without speeds.
    """
    path = Path(path)
    if not path.is_file():
        raise MissionFileError(f'flight log {path}: no such file')
    try:
        log = mavutil.mavlink_connection(str(path), dialect='ardupilotmega', notimestamps=False)
    except (OSError, ValueError) as exc:
        raise MissionFileError(f'flight log {path}: cannot be read ({exc})') from None
    rows = {'BATTERY_STATUS': [], 'SYS_STATUS': []}
    clock_s = None
    speeds: tuple | None = None    # (autopilot time, log stamp), airspeed, climb
    hud_seen = False
    height_m = math.nan
    armed = False
    try:
        while True:
            try:
                message = log.recv_match(type=_TYPES)
            except (struct.error, ValueError, IndexError):
                continue
            if message is None:
                break
            boot_ms = getattr(message, 'time_boot_ms', None)
            if boot_ms is not None:
                clock_s = boot_ms / 1000.0
            now = (clock_s, getattr(message, '_timestamp', None))
            kind = message.get_type()
            if kind == 'HEARTBEAT':
                if message.get_srcComponent() == MAV.MAV_COMP_ID_AUTOPILOT1:
                    armed = bool(message.base_mode & MAV.MAV_MODE_FLAG_SAFETY_ARMED)
            elif kind == 'VFR_HUD':
                hud_seen = True
                speeds = (now, float(message.airspeed), float(message.climb))
            elif kind == 'GLOBAL_POSITION_INT':
                height_m = message.relative_alt / 1000.0
                if not hud_seen:
                    speeds = (now, math.hypot(message.vx, message.vy) / 100.0,
                              -message.vz / 100.0)
            elif kind in rows:
                power = _battery_power(message)
                if power is not None:
                    rows[kind].append((now, power, speeds, armed, height_m))
    finally:
        log.close()
    power_rows = rows['BATTERY_STATUS'] or rows['SYS_STATUS']
    if not power_rows:
        raise MissionFileError(f'flight log {path}: no battery power (BATTERY_STATUS or '
                               f'SYS_STATUS with voltage and current)')
    if not any(row[2] is not None for row in power_rows):
        raise MissionFileError(f'flight log {path}: no speeds (VFR_HUD or '
                               f'GLOBAL_POSITION_INT)')
    # the autopilot's clock when the log has it (rows before its first message left out),
    # else the log's stamps
    clock = 0 if any(row[0][0] is not None for row in power_rows) else 1
    samples = []
    for now, power, speed, armed, height in power_rows:
        if speed is None or now[clock] is None or speed[0][clock] is None:
            continue
        if (now[clock] - speed[0][clock] > MAX_SPEED_AGE_S or not armed or power <= 0
                or height < MIN_HEIGHT_M):
            continue
        samples.append(PowerSample(now[clock], speed[1], speed[2], power, height))
    return samples


def steady_mask(samples: list[PowerSample], *, window_s: float = STEADY_WINDOW_S,
                tolerance_mps: float = STEADY_TOLERANCE_MPS) -> np.ndarray:
    """True for each sample whose airspeed and climb rate each stay within ``tolerance_mps``
    (max - min) over ``window_s`` either side of it, the window covered by samples no more
    than a window apart: (K,) bool."""
    times = np.array([sample.time_s for sample in samples], dtype=float)
    speed = np.array([sample.airspeed_mps for sample in samples], dtype=float)
    climb = np.array([sample.climb_mps for sample in samples], dtype=float)
    steady = np.zeros(times.size, dtype=bool)
    for k in range(times.size):
        inside = np.flatnonzero(np.abs(times - times[k]) <= window_s)
        span = times[inside]
        if span.size < 3 or span.min() > times[k] - 0.8 * window_s or (
                span.max() < times[k] + 0.8 * window_s) or np.diff(span).max() > window_s:
            continue
        steady[k] = (np.ptp(speed[inside]) <= tolerance_mps
                     and np.ptp(climb[inside]) <= tolerance_mps)
    return steady


def steady_samples(samples: list[PowerSample], **kwargs) -> list[PowerSample]:
    """The samples :func:`steady_mask` keeps."""
    return [sample for sample, keep in zip(samples, steady_mask(samples, **kwargs)) if keep]


def fit_samples(name: str, samples: list[PowerSample], *,
                top_airspeed_mps: float | None = None) -> AirframeFit:
    """The airframe fitted to ``samples`` (all used: select the steady ones first)."""
    if len(samples) < MIN_STEADY_SAMPLES:
        raise InvalidScenarioError(f'{len(samples)} steady samples; a fit needs at least '
                                   f'{MIN_STEADY_SAMPLES} (fly level legs at several steady '
                                   f'speeds, each for {2 * STEADY_WINDOW_S:g} s or more)')
    return fit_airframe(name, [s.airspeed_mps for s in samples],
                        [s.climb_mps for s in samples], [s.power_w for s in samples],
                        top_airspeed_mps=top_airspeed_mps)


def fit_flight_log(path: str | os.PathLike, name: str, *,
                   top_airspeed_mps: float | None = None) -> tuple[AirframeFit, int]:
    """The airframe fitted to a tlog's steady samples, and how many in-flight samples the
    log gave."""
    samples = read_tlog(path)
    steady = steady_samples(samples)
    try:
        return fit_samples(name, steady, top_airspeed_mps=top_airspeed_mps), len(samples)
    except InvalidScenarioError as exc:
        raise InvalidScenarioError(f'flight log {path}: {exc}') from None


def samples_csv(samples: list[PowerSample], extra: dict[str, list] | None = None) -> str:
    """CSV text of samples (a header of the field names, then ``extra`` columns)."""
    extra = extra or {}
    out = io.StringIO()
    writer = csv.writer(out, lineterminator='\n')
    writer.writerow([field.name for field in fields(PowerSample)] + list(extra))
    for k, sample in enumerate(samples):
        writer.writerow([f'{value:.6g}' for value in astuple(sample)]
                        + [column[k] for column in extra.values()])
    return out.getvalue()


def read_samples_csv(path: str | os.PathLike) -> tuple[list[PowerSample], dict[str, list[str]]]:
    """The samples of :func:`samples_csv` text in a file, and its extra columns as text."""
    with open(path, newline='', encoding='utf-8') as handle:
        table = list(csv.DictReader(handle))
    names = [field.name for field in fields(PowerSample)]
    samples = [PowerSample(*(float(row[name]) for name in names)) for row in table]
    extra_names = [key for key in (table[0] if table else {}) if key not in names]
    return samples, {key: [row[key] for row in table] for key in extra_names}


__all__ = ['AirframeFit', 'fit_airframe', 'fit_flight_log', 'fit_samples', 'MIN_STEADY_SAMPLES',
           'PowerSample', 'read_samples_csv', 'read_tlog', 'samples_csv', 'STEADY_TOLERANCE_MPS',
           'STEADY_WINDOW_S', 'steady_mask', 'steady_samples']
