"""ArduCopter SITL's default quad measured: power against airspeed, climb and descent.

``make airframe`` (``python -m devtools.measure_airframe``) flies ArduCopter SITL (the ``+``
quad, ArduPilot's copter.parm: BATT_MONITOR 4, the simulated battery's voltage and current) in
still air at 100 m: level legs in GUIDED at several speeds, each long enough for a steady part,
in the four headings; the takeoff to 100 m and the landing from it at the default rates. Every
time is autopilot time (``time_boot_ms``). It writes

- ``uav_comm_planner/vehicle/airframes/arducopter_sitl_quad.csv``: the samples in flight, one
  row per BATTERY_STATUS (power = voltage x current), ``steady`` marking those fitted;
- ``uav_comm_planner/vehicle/airframes/arducopter_sitl_quad.yaml``: the airframe fitted to them
  (:func:`uav_comm_planner.vehicle.airframe_fit.fit_airframe`), its RMS error in ``source``;
- ``test/data/sitl_quad_legs.tlog`` (``--tlog``): a tlog of the flight (one message of each
  kind per second), the fixture of the ``fit-airframe`` command's tests;

and prints the measured table. One flight of about 17 simulated minutes flies it all: the
simulated battery's voltage stays at 12.6 V throughout (it gives about 99 Wh, more than the
41.6 Wh that BATT_CAPACITY states, without sagging), so the power does not depend on the
order of the legs.
"""

from __future__ import annotations

import argparse
import dataclasses
from dataclasses import dataclass, field
import math
from pathlib import Path
import struct
import sys
import tempfile
import time

import numpy as np
from pymavlink import mavutil

from devtools.sitl import (_command, open_link, set_parameter, sitl_binary, start_sitl,
                           take_off)
from uav_comm_planner.errors import VehicleLinkError
from uav_comm_planner.files import write_text_atomic
from uav_comm_planner.vehicle.airframe import airframe_yaml
from uav_comm_planner.vehicle.airframe_fit import (AirframeFit, fit_samples,
                                                    PowerSample, samples_csv, steady_mask)
from uav_comm_planner.vehicle.geodesy import Home

MAV = mavutil.mavlink
HOME = Home(-35.363262, 149.165237, 584.0)
ROOT = Path(__file__).resolve().parents[1]
AIRFRAMES = ROOT / 'uav_comm_planner' / 'vehicle' / 'airframes'
NAME = 'arducopter-sitl-quad'
CSV_PATH = AIRFRAMES / 'arducopter_sitl_quad.csv'
YAML_PATH = AIRFRAMES / 'arducopter_sitl_quad.yaml'
TLOG_PATH = ROOT / 'test' / 'data' / 'sitl_quad_legs.tlog'
#: Where CI keeps its SITL binary (as test/conftest.py): ../shared/sitl/ beside the checkout.
CHECKOUT_SITL = ROOT.parent / 'shared' / 'sitl' / 'arducopter'
ALTITUDE_M = 100.0
#: ArduCopter's LAND flight mode.
LAND_MODE = 9
#: The messages recorded, per second of autopilot time.
RATE_HZ = 2.0
RECORDED = ('BATTERY_STATUS', 'SYS_STATUS', 'VFR_HUD', 'GLOBAL_POSITION_INT')
#: Seconds of steady flight wanted on each leg, and of hover.
STEADY_S = 30.0
#: WPNAV_ACCEL (m/s/s) and WPNAV_JERK (m/s/s/s) at their defaults: a leg of length
#: L reaches at most V with L = V (V / A + A / J) (the SITL README).
ACCEL = 2.5
JERK = 1.0
#: ANGLE_MAX, centidegrees: the default (30 degrees) and the lean the legs above the default
#: top speed need (45 degrees).
DEFAULT_ANGLE_MAX = 3000
WIDE_ANGLE_MAX = 4500
#: Seconds a leg gives its start and its stop beyond the S-curve's ramps (the power settles).
SETTLE_S = 4.0
#: The tlog keeps one message of each kind per this many seconds (a small test fixture), its
#: stamps this epoch (s) plus the autopilot's time.
TLOG_PERIOD_S = 1.0
TLOG_EPOCH_S = 1.7e9


@dataclass
class Row:
    """One BATTERY_STATUS with the latest position and speeds: SI units."""

    time_s: float
    voltage_v: float
    current_a: float
    energy_j: float
    east_m: float
    north_m: float
    altitude_m: float
    velocity_mps: tuple[float, float, float]   # east, north, up
    heading_deg: float
    airspeed_mps: float
    phase: str = ''

    @property
    def power_w(self) -> float:
        return self.voltage_v * self.current_a

    @property
    def ground_speed_mps(self) -> float:
        return math.hypot(self.velocity_mps[0], self.velocity_mps[1])


@dataclass
class Recorder:
    """Reads the link, keeps a :class:`Row` per BATTERY_STATUS, and writes the recorded
    messages (:data:`RECORDED`, HEARTBEAT) to a tlog when one is open."""

    link: object
    rows: list[Row] = field(default_factory=list)
    phase: str = ''
    tlog: object = None
    armed: bool = True
    _position: tuple = (0.0, 0.0, 0.0, (0.0, 0.0, 0.0), 0.0)
    _airspeed: float = 0.0
    _clock_s: float = 0.0
    _logged: dict = field(default_factory=dict)

    def pump(self, timeout_s: float = 5.0) -> Row | None:
        """Read until the next BATTERY_STATUS; return its row."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            message = self.link.recv_match(type=[*RECORDED, 'HEARTBEAT'], blocking=True,
                                           timeout=1.0)
            if message is None:
                continue
            kind = message.get_type()
            if kind == 'HEARTBEAT':
                if message.get_srcComponent() != MAV.MAV_COMP_ID_AUTOPILOT1:
                    continue
                self.armed = bool(message.base_mode & MAV.MAV_MODE_FLAG_SAFETY_ARMED)
            if hasattr(message, 'time_boot_ms'):
                self._clock_s = message.time_boot_ms / 1000.0
            self._log(message)
            if kind == 'GLOBAL_POSITION_INT':
                east, north = _east_north(message.lat, message.lon)
                self._position = (east, north, message.relative_alt / 1000.0,
                                  (message.vy / 100.0, message.vx / 100.0,
                                   -message.vz / 100.0), message.hdg / 100.0)
            elif kind == 'VFR_HUD':
                self._airspeed = float(message.airspeed)
            elif kind == 'BATTERY_STATUS' and message.id == 0:
                east, north, altitude, velocity, heading = self._position
                row = Row(message.time_boot_ms / 1000.0 if hasattr(message, 'time_boot_ms')
                          else self.clock_s(), message.voltages[0] / 1000.0,
                          message.current_battery / 100.0, message.energy_consumed * 100.0,
                          east, north, altitude, velocity, heading, self._airspeed, self.phase)
                self.rows.append(row)
                return row
        raise VehicleLinkError('the vehicle went silent')

    def _log(self, message) -> None:
        """Into the tlog, at most one message of a kind per TLOG_PERIOD_S of autopilot time,
        stamped TLOG_EPOCH_S + autopilot time."""
        kind = message.get_type()
        if self.tlog is None or self._clock_s - self._logged.get(kind, -1e9) < TLOG_PERIOD_S:
            return
        self._logged[kind] = self._clock_s
        stamp = int((TLOG_EPOCH_S + self._clock_s) * 1e6)
        self.tlog.write(struct.pack('>Q', stamp) + message.get_msgbuf())

    def clock_s(self) -> float:
        return self._clock_s

    def wait(self, seconds: float) -> None:
        """Record for ``seconds`` of autopilot time."""
        start = self.pump().time_s
        while self.pump().time_s - start < seconds:
            pass


def _east_north(latitude_e7: int, longitude_e7: int) -> tuple[float, float]:
    """Metres east and north of HOME (flat earth: legs of a few hundred metres)."""
    north = (latitude_e7 / 1e7 - HOME.latitude_deg) * math.pi / 180.0 * 6378137.0
    east = ((longitude_e7 / 1e7 - HOME.longitude_deg) * math.pi / 180.0 * 6378137.0
            * math.cos(math.radians(HOME.latitude_deg)))
    return east, north


def request_streams(link) -> None:
    """The recorded messages at :data:`RATE_HZ` (per second of autopilot time)."""
    for name in RECORDED:
        message_id = getattr(MAV, f'MAVLINK_MSG_ID_{name}')
        link.mav.command_long_send(link.target_system, link.target_component,
                                   MAV.MAV_CMD_SET_MESSAGE_INTERVAL, 0, message_id,
                                   1e6 / RATE_HZ, 0, 0, 0, 0, 0)


def goto(link, east_m: float, north_m: float) -> None:
    """A GUIDED position target, metres from home at ALTITUDE_M."""
    link.mav.set_position_target_local_ned_send(
        0, link.target_system, link.target_component, MAV.MAV_FRAME_LOCAL_NED, 0b110111111000,
        north_m, east_m, -ALTITUDE_M, 0, 0, 0, 0, 0, 0, 0, 0)


def leg_length_m(speed_mps: float) -> float:
    """Long enough for STEADY_S at ``speed_mps`` between the S-curve's start and stop."""
    return speed_mps * (STEADY_S + 2 * SETTLE_S) + 2 * speed_mps * (speed_mps / ACCEL
                                                                     + ACCEL / JERK)


def fly_leg(recorder: Recorder, speed_mps: float, heading_deg: float,
            timeout_s: float = 300.0) -> None:
    """One straight level leg at ``speed_mps`` towards ``heading_deg`` (from north,
    clockwise), from where the vehicle is to a stop; its rows are tagged
    ``leg <speed> <heading>``."""
    link = recorder.link
    set_parameter(link, 'WPNAV_SPEED', speed_mps * 100.0)
    _command(link, MAV.MAV_CMD_DO_CHANGE_SPEED, 1, speed_mps, -1)
    here = recorder.pump()
    length = leg_length_m(speed_mps)
    target = (here.east_m + length * math.sin(math.radians(heading_deg)),
              here.north_m + length * math.cos(math.radians(heading_deg)))
    recorder.phase = f'leg {speed_mps:g} {heading_deg:g}'
    goto(link, *target)
    start = here.time_s
    while True:
        row = recorder.pump()
        if math.hypot(row.east_m - target[0], row.north_m - target[1]) < 1.0 and (
                row.ground_speed_mps < 0.2):
            break
        if row.time_s - start > timeout_s:
            raise VehicleLinkError(f'leg at {speed_mps} m/s not flown in {timeout_s} s')
    recorder.phase = ''


def climb_to(recorder: Recorder, timeout_s: float = 200.0) -> None:
    """Arm, take off to ALTITUDE_M, rows tagged ``takeoff`` until it holds there."""
    recorder.phase = 'takeoff'
    take_off(recorder.link, ALTITUDE_M)
    start = recorder.pump().time_s
    while True:
        row = recorder.pump()
        if row.altitude_m > ALTITUDE_M - 0.3 and abs(row.velocity_mps[2]) < 0.1:
            break
        if row.time_s - start > timeout_s:
            raise VehicleLinkError('the takeoff did not reach 100 m')
    recorder.phase = ''


def land(recorder: Recorder, timeout_s: float = 300.0) -> None:
    """LAND from where it is; rows tagged ``land`` until it disarms."""
    recorder.phase = 'land'
    link = recorder.link
    link.mav.set_mode_send(link.target_system, MAV.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                           LAND_MODE)
    start = recorder.pump().time_s
    while recorder.armed:
        if recorder.pump().time_s - start > timeout_s:
            raise VehicleLinkError('the landing did not end')
    recorder.phase = ''


def session(folder: Path, program, *, parameters: dict[str, float] | None = None,
            tlog: Path | None = None, binary: Path | None = None) -> list[Row]:
    """Start SITL in ``folder``, connect, set ``parameters``, run ``program(recorder)``."""
    vehicle = start_sitl(folder, HOME, binary=binary or sitl_binary() or CHECKOUT_SITL)
    try:
        link = open_link(vehicle)
        for name, value in {'FENCE_ENABLE': 0, **(parameters or {})}.items():
            set_parameter(link, name, value)
        request_streams(link)
        recorder = Recorder(link)
        handle = open(tlog, 'wb') if tlog is not None else None
        recorder.tlog = handle
        try:
            program(recorder)
        finally:
            if handle is not None:
                handle.close()
        link.close()
    finally:
        vehicle.stop()
    return recorder.rows


#: The level legs: (commanded speed m/s, heading degrees, ANGLE_MAX centidegrees), in order.
#: 13 m/s at the default lean is the top-speed leg: the vehicle flies as fast as it can.
LEGS = ((2.0, 90.0, DEFAULT_ANGLE_MAX), (4.0, 270.0, DEFAULT_ANGLE_MAX),
        (6.0, 0.0, DEFAULT_ANGLE_MAX), (6.0, 180.0, DEFAULT_ANGLE_MAX),
        (8.0, 90.0, DEFAULT_ANGLE_MAX), (9.0, 270.0, DEFAULT_ANGLE_MAX),
        (10.0, 0.0, DEFAULT_ANGLE_MAX), (10.0, 90.0, DEFAULT_ANGLE_MAX),
        (10.0, 180.0, DEFAULT_ANGLE_MAX), (10.0, 270.0, DEFAULT_ANGLE_MAX),
        (13.0, 45.0, DEFAULT_ANGLE_MAX),
        (11.0, 225.0, WIDE_ANGLE_MAX), (12.0, 45.0, WIDE_ANGLE_MAX),
        (12.0, 225.0, WIDE_ANGLE_MAX))
TOP_SPEED_LEG = 'leg 13 45'
HOVER_S = 40.0


def program(recorder: Recorder) -> None:
    """The whole flight: takeoff, hover, :data:`LEGS`, landing."""
    climb_to(recorder)
    recorder.phase = 'hover'
    recorder.wait(HOVER_S)
    for speed, heading, angle_max in LEGS:
        set_parameter(recorder.link, 'ANGLE_MAX', angle_max)
        fly_leg(recorder, speed, heading)
    land(recorder)


@dataclass(frozen=True)
class Measured:
    """The flight's rows, which of them are steady, and the fit to the steady ones."""

    rows: list[Row]
    samples: list[PowerSample]
    steady: np.ndarray
    fit: AirframeFit
    top_speed_mps: float


def to_samples(rows: list[Row]) -> list[PowerSample]:
    """A sample per in-flight row: airspeed = ground speed (still air)."""
    return [PowerSample(row.time_s, row.ground_speed_mps, row.velocity_mps[2], row.power_w,
                        row.altitude_m) for row in rows]


def measure(rows: list[Row]) -> Measured:
    """Steady samples of the flight's rows and the airframe fitted to them."""
    flying = [row for row in rows if row.phase and row.altitude_m >= 2.0 and row.current_a > 0]
    samples = to_samples(flying)
    steady = steady_mask(samples)
    top = [sample.airspeed_mps for sample, row, keep in zip(samples, flying, steady)
           if keep and row.phase == TOP_SPEED_LEG]
    if not top:
        raise VehicleLinkError('no steady sample on the top-speed leg')
    top_speed = round(float(np.median(top)), 2)
    kept = [sample for sample, keep in zip(samples, steady) if keep]
    fit = fit_samples(NAME, kept, top_airspeed_mps=top_speed)
    return Measured(flying, samples, steady, fit, top_speed)


def _energy_wh(rows: list[Row], phase: str) -> tuple[float, float]:
    """(counter, integral) Wh of a phase: energy_consumed at its end less at its start (0 at
    boot for the takeoff, before any row), and the trapezoid of V I over its rows."""
    tagged = [row for row in rows if row.phase == phase]
    first = 0.0 if phase == 'takeoff' else tagged[0].energy_j
    times = np.array([row.time_s for row in tagged])
    power = np.array([row.power_w for row in tagged])
    integral = float(np.sum(np.diff(times) * (power[1:] + power[:-1]) / 2.0))
    return (tagged[-1].energy_j - first) / 3600.0, integral / 3600.0


def report(all_rows: list[Row], measured: Measured) -> str:
    """The measured table: level power by leg, heading, vertical, takeoff and landing."""
    lines = ['phase            airspeed m/s  climb m/s  power W  (sd)   steady s  model W']
    airframe = measured.fit.airframe
    groups: dict[str, list[PowerSample]] = {}
    for sample, row, keep in zip(measured.samples, measured.rows, measured.steady):
        if keep:
            # the landing descends at two rates: one line each
            key = (f'{row.phase} {sample.climb_mps:+.1f}' if row.phase in ('takeoff', 'land')
                   else row.phase)
            groups.setdefault(key, []).append(sample)
    for phase, chosen in groups.items():
        if len(chosen) < 3:
            continue
        speed = np.array([s.airspeed_mps for s in chosen])
        climb = np.array([s.climb_mps for s in chosen])
        power = np.array([s.power_w for s in chosen])
        duration = chosen[-1].time_s - chosen[0].time_s
        model = float(np.mean(airframe.power_w(speed, climb)))
        lines.append(f'{phase:16s} {speed.mean():12.2f} {climb.mean():10.2f} '
                     f'{power.mean():8.1f} ({power.std():4.1f}) {duration:8.1f} {model:8.1f}')
    for phase in ('takeoff', 'land'):
        counter, integral = _energy_wh(all_rows, phase)
        lines.append(f'{phase} energy: {counter:.3f} Wh (energy_consumed), {integral:.3f} Wh '
                     f'(integral of V I over the rows)')
    fit = measured.fit
    lines.append(f'top speed at ANGLE_MAX {DEFAULT_ANGLE_MAX}: {measured.top_speed_mps:.2f} m/s')
    lines.append(f'fit: RMS {fit.rms_w:.2f} W, largest {fit.max_error_w:.2f} W over '
                 f'{fit.samples} steady samples')
    return '\n'.join(lines)


def write_outputs(measured: Measured, csv_path: Path, yaml_path: Path) -> None:
    """The samples' CSV (every in-flight row, ``steady`` marking those fitted) and the
    airframe's YAML, each replaced atomically."""
    rows = measured.rows
    extra = {'phase': [row.phase for row in rows],
             'heading_deg': [f'{row.heading_deg:.1f}' for row in rows],
             'voltage_v': [f'{row.voltage_v:.3f}' for row in rows],
             'current_a': [f'{row.current_a:.2f}' for row in rows],
             'energy_consumed_j': [f'{row.energy_j:.0f}' for row in rows],
             'steady': [int(keep) for keep in measured.steady]}
    write_text_atomic(csv_path, samples_csv(measured.samples, extra))
    fit = measured.fit
    # the file's numbers to 6 significant digits, its RMS that of the numbers written
    airframe = dataclasses.replace(fit.airframe, **{
        name: float(f'{value:.6g}') for name, value in dataclasses.asdict(fit.airframe).items()
        if name != 'name'})
    kept = [sample for sample, keep in zip(measured.samples, measured.steady) if keep]
    error = airframe.power_w([s.airspeed_mps for s in kept], [s.climb_mps for s in kept]) - [
        s.power_w for s in kept]
    rms_w = float(np.sqrt(np.mean(error ** 2)))
    source = (f'ArduCopter SITL (V4.7.0-dev, + quad, copter.parm defaults, BATT_MONITOR 4) '
              f'in still air at 100 m, measured by devtools/measure_airframe.py (make '
              f'airframe): power = BATTERY_STATUS voltage x current against ground speed in '
              f'GUIDED level legs from hover to 12 m/s (ANGLE_MAX 45 deg above the default '
              f"30 deg's top speed), the takeoff's climb and the landing's descents; "
              f'{len(kept)} steady samples ({csv_path.name}), least-squares fit RMS '
              f'{rms_w:.2f} W (largest {np.abs(error).max():.2f} W); rho, s and A fixed (only '
              f'd0 rho s A counts); the tip speed is a fitted shape parameter, not the rotor\'s '
              f'(the simulator has no blade aerodynamics: its power grows with the thrust that '
              f'the lean needs); top airspeed = the top speed at the default ANGLE_MAX 30 deg')
    write_text_atomic(yaml_path, airframe_yaml(airframe, source))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--csv', type=Path, default=CSV_PATH, help='samples written here')
    parser.add_argument('--yaml', type=Path, default=YAML_PATH, help='airframe written here')
    parser.add_argument('--tlog', type=Path, default=TLOG_PATH,
                        help='a 1 Hz tlog of the flight written here')
    parser.add_argument('--sitl', type=Path, default=None,
                        help='the arducopter binary (default: $UAV_COMM_PLANNER_SITL, the PATH, '
                             'else ../shared/sitl/arducopter beside the checkout)')
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        rows = session(Path(folder), program, tlog=args.tlog, binary=args.sitl)
    measured = measure(rows)
    print(report(rows, measured))
    write_outputs(measured, args.csv, args.yaml)
    print(f'wrote {args.csv}, {args.yaml} and {args.tlog}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
