"""The vehicle's horizontal motion limits, as the autopilot's own parameters state them.

ArduCopter plans every waypoint leg with a jerk-limited speed profile (an S-curve) bounded by
WPNAV_SPEED (cm/s), WPNAV_ACCEL (cm/s/s) and WPNAV_JERK (m/s/s/s); PX4 by MPC_XY_CRUISE (m/s),
MPC_ACC_HOR (m/s/s) and MPC_JERK_AUTO (m/s/s/s). :class:`VehicleLimits` holds them in SI units
with ArduCopter's defaults; :func:`read_parameter_file` reads them from a file as ground
stations save parameters (``NAME VALUE``, ``NAME,VALUE`` or tab-separated lines; Mission
Planner's ``.param`` and QGroundControl's ``.params`` both work), and
:class:`VehicleParameters` holds them as read from the vehicle itself over its link
(:mod:`.mavlink.parameters`); :func:`limit_of_parameter` turns either into SI units.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
import os
from typing import Mapping

from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.files import read_text_file
from uav_comm_planner.vehicle.firmware import firmware_named

#: A parameter file larger than this is refused before it is read (a full ArduCopter
#: parameter file is about 50 kB).
MAX_PARAMETER_FILE_BYTES = 4 * 1024 * 1024
#: The limits a plan can be made with, [low, high] (the jerk time's high end excluded): far
#: beyond any multirotor's parameters, yet inside what the S-curve's arithmetic holds.
LIMIT_RANGES = {
    'max_speed_mps': (0.01, 1000.0),
    'max_accel_mpss': (0.01, 1000.0),
    'max_jerk_mpsss': (0.01, 10000.0),
    'jerk_time_s': (0.01, 10.0),
}
#: PX4's turn gain and largest tracking error, with the ranges PX4's parameter table gives them.
PX4_SHAPE_RANGES = (('turn_gain', 'MPC_XY_TRAJ_P', (0.1, 1.0)),
                    ('max_position_error_m', 'MPC_XY_ERR_MAX', (0.1, 10.0)))
#: A vehicle slower than this to reach its cruise speed from rest is refused (seconds).
MAX_RAMP_S = 3600.0


@dataclass(frozen=True)
class VehicleLimits:
    """Horizontal motion limits of the vehicle that flies the plan.

    max_speed_mps: the waypoint speed (WPNAV_SPEED, default 10 m/s; MPC_XY_CRUISE);
    max_accel_mpss: the waypoint acceleration (WPNAV_ACCEL, 2.5 m/s/s; MPC_ACC_HOR);
    max_jerk_mpsss: the waypoint jerk (WPNAV_JERK, 1 m/s/s/s; MPC_JERK_AUTO);
    airframe_speed_mps: the fastest the airframe flies level at its lean limit, if known
    (an ArduCopter quad reaches about 10.3 m/s at the default 30 degree ANGLE_MAX); the
    vehicle cruises at the lesser of it and ``max_speed_mps``;
    jerk_time_s: how long ArduCopter takes to build up the jerk, tj = 2 max(ATC_INPUT_TC, 0.1)
    (0.3 s by default): the jerk rises and falls as a raised cosine over tj;
    gust_margin_mps: the airspeed kept in reserve for gusts when the plan is made for a wind
    (:attr:`airspeed_mps`);
    acceptance_radius_m: PX4's waypoint acceptance radius (NAV_ACC_RAD, metres), as the
    vehicle's parameter file gives it; None: PX4's default (2 m). ArduCopter's legs are timed
    to rest and do not use it;
    turn_gain: PX4's MPC_XY_TRAJ_P, the share of the acceleration a fly-through turn is flown
    with; None: PX4's default (0.5);
    max_position_error_m: PX4's MPC_XY_ERR_MAX (metres), the lag behind its trajectory at which
    PX4 stops the trajectory's clock; None: PX4's default (2 m).
    """

    max_speed_mps: float = 10.0
    max_accel_mpss: float = 2.5
    max_jerk_mpsss: float = 1.0
    airframe_speed_mps: float = math.inf
    jerk_time_s: float = 0.3
    gust_margin_mps: float = 1.0
    acceptance_radius_m: float | None = None
    turn_gain: float | None = None
    max_position_error_m: float | None = None

    def __post_init__(self) -> None:
        for name in ('max_speed_mps', 'max_accel_mpss', 'max_jerk_mpsss'):
            value = getattr(self, name)
            if (isinstance(value, bool) or not isinstance(value, (int, float))
                    or not math.isfinite(value) or value <= 0):
                raise InvalidScenarioError(f'vehicle {name} must be a positive finite number, '
                                           f'got {value!r}')
            low, high = LIMIT_RANGES[name]
            if not low <= value <= high:
                raise InvalidScenarioError(
                    f'vehicle {name} must be in [{low:g}, {high:g}] for a plan to be made, got '
                    f'{value!r}')
        low, high = LIMIT_RANGES['jerk_time_s']
        if (isinstance(self.jerk_time_s, bool) or not isinstance(self.jerk_time_s, (int, float))
                or not low <= self.jerk_time_s < high):
            raise InvalidScenarioError(f'vehicle jerk_time_s must be in [{low:g}, {high:g}) s '
                                       f'for a plan to be made, got {self.jerk_time_s!r}')
        speed = self.airframe_speed_mps
        if isinstance(speed, bool) or not isinstance(speed, (int, float)) or not speed > 0:
            raise InvalidScenarioError(f'vehicle airframe_speed_mps must be positive (inf: '
                                       f'unknown), got {speed!r}')
        margin = self.gust_margin_mps
        if (isinstance(margin, bool) or not isinstance(margin, (int, float))
                or not 0 <= margin < min(speed, self.max_speed_mps)):
            raise InvalidScenarioError(
                f'vehicle gust_margin_mps must be >= 0 and below the airframe\'s speed, got '
                f'{margin!r}')
        radius = self.acceptance_radius_m
        if radius is not None and (isinstance(radius, bool) or not isinstance(radius, (int, float))
                                   or not 0.05 <= radius <= 200.0):
            raise InvalidScenarioError(f'vehicle acceptance_radius_m (NAV_ACC_RAD) must be in '
                                       f'[0.05, 200] m, got {radius!r}')
        for name, parameter, (low, high) in PX4_SHAPE_RANGES:
            value = getattr(self, name)
            if value is not None and (isinstance(value, bool)
                                      or not isinstance(value, (int, float))
                                      or not low <= value <= high):
                raise InvalidScenarioError(f'vehicle {name} ({parameter}) must be in '
                                           f'[{low:g}, {high:g}], got {value!r}')
        ramp_s = self.ramp_s
        if ramp_s > MAX_RAMP_S:
            raise InvalidScenarioError(
                f'the vehicle would take {ramp_s:.4g} s to reach its cruise speed from rest '
                f'(acceleration {self.max_accel_mpss:g} m/s/s, jerk {self.max_jerk_mpsss:g} '
                f'm/s/s/s, jerk time {self.jerk_time_s:g} s), more than {MAX_RAMP_S:g} s: no '
                f'leg could be timed; give the vehicle\'s real limits')

    @property
    def ramp_s(self) -> float:
        """Seconds from rest to the cruise speed V along the S-curve: V / A + A / J + tj when
        the acceleration limit A is reached, else tj + sqrt(tj^2 + 4 V / J)
        (:func:`~uav_comm_planner.vehicle.timing.ramp_time`)."""
        speed, accel = self.cruise_speed_mps, self.max_accel_mpss
        jerk, tj = self.max_jerk_mpsss, self.jerk_time_s
        if speed >= accel * (accel / jerk + tj):
            return speed / accel + accel / jerk + tj
        return tj + math.sqrt(tj * tj + 4 * speed / jerk)

    @property
    def airspeed_mps(self) -> float:
        """The airspeed a plan in wind may use: the airframe's top speed (the waypoint speed
        when that is not known) less the gust margin."""
        top = self.airframe_speed_mps if math.isfinite(self.airframe_speed_mps) \
            else self.max_speed_mps
        return top - self.gust_margin_mps

    def airspeed_for_wind_mps(self, wind_speed_mps: float) -> float | None:
        """The airspeed a plan for this vehicle keeps in a wind of ``wind_speed_mps``
        (:attr:`airspeed_mps`), or None in still air, where the ground speed alone limits it."""
        return self.airspeed_mps if wind_speed_mps > 0.0 else None

    @property
    def cruise_speed_mps(self) -> float:
        """The fastest the vehicle flies a waypoint leg: min(max_speed, airframe_speed)."""
        return min(self.max_speed_mps, self.airframe_speed_mps)

    @classmethod
    def for_firmware(cls, firmware: str) -> 'VehicleLimits':
        """The limits ``firmware`` ships with (ArduCopter's are this class's defaults)."""
        return cls(**firmware_named(firmware).default_limits)

    def describe_cruise(self) -> str:
        if self.airframe_speed_mps < self.max_speed_mps:
            return f'{self.airframe_speed_mps:g} m/s (the airframe\'s top speed)'
        return f'{self.max_speed_mps:g} m/s (the waypoint speed, WPNAV_SPEED / MPC_XY_CRUISE)'


def limit_of_parameter(name: str, value: float, firmware: str = 'ardupilot', *,
                       where: str = '', shown: str | None = None) -> float:
    """The SI value of the limit ``firmware``'s parameter ``name`` states with ``value`` (as
    the autopilot holds it: WPNAV_SPEED in cm/s): the firmware's floor, then its factor
    (:attr:`~uav_comm_planner.vehicle.firmware.Firmware.parameters`). Raises
    :class:`~uav_comm_planner.errors.InvalidScenarioError` (its message starts with ``where``
    and shows the value as ``shown``, if given) for a name the firmware's limits do not use,
    or a value that is not finite (or is not once scaled)."""
    known = firmware_named(firmware)
    if name not in known.parameters:
        raise InvalidScenarioError(f'{where}{name} is none of {", ".join(known.parameters)} '
                                   f'({firmware})')
    said = f'{where}{name} is {repr(value) if shown is None else shown}'
    if not math.isfinite(value):
        raise InvalidScenarioError(f'{said}, not a finite number')
    scaled = max(value, known.parameter_floors.get(name, -math.inf)) * known.parameters[name][1]
    if not math.isfinite(scaled):   # 1e308 times ATC_INPUT_TC's factor of 2
        raise InvalidScenarioError(f'{said}, beyond what a plan can be made with')
    return scaled


@dataclass(frozen=True)
class VehicleParameters:
    """The limit parameters an autopilot holds, as read from it over its link.

    firmware: the autopilot's key of :data:`~uav_comm_planner.vehicle.firmware.FIRMWARES`;
    values: name -> value as the autopilot states it (WPNAV_SPEED in cm/s, NAV_ACC_RAD in
    metres), for the names of its
    :attr:`~uav_comm_planner.vehicle.firmware.Firmware.parameters` it answered; missing: the
    names it was asked for and did not answer.
    """

    firmware: str
    values: Mapping[str, float]
    missing: tuple[str, ...] = ()

    def limits(self) -> dict[str, float]:
        """The values as :class:`VehicleLimits` fields in SI units (:func:`limit_of_parameter`);
        raises InvalidScenarioError for a value no plan can be made with."""
        fields = firmware_named(self.firmware).parameters
        return {fields[name][0]: limit_of_parameter(name, value, self.firmware)
                for name, value in self.values.items()}


def parameter_file_values(path: str | os.PathLike, *,
                          firmware: str = 'ardupilot') -> dict[str, float]:
    """The limits a saved parameter file sets, as :class:`VehicleLimits` fields in SI units.

    Lines are ``NAME VALUE``, ``NAME,VALUE`` or QGroundControl's tab-separated
    ``SYSID COMPID NAME VALUE TYPE``; ``#`` starts a comment. Raises
    :class:`~uav_comm_planner.errors.InvalidScenarioError` for a file that is not a regular file
    (a device, a pipe, a folder: refused without blocking), is larger than
    :data:`MAX_PARAMETER_FILE_BYTES`, is not UTF-8, has a malformed value of a parameter it
    uses, or sets none of them.
    """
    wanted = firmware_named(firmware).parameters
    text = read_text_file(path, max_bytes=MAX_PARAMETER_FILE_BYTES, what='parameter file',
                          error=InvalidScenarioError)
    values = {}
    for number, line in enumerate(text.splitlines(), start=1):
        fields = line.split('#', 1)[0].replace(',', ' ').split()
        if len(fields) >= 4 and fields[2] in wanted:   # QGroundControl: sys comp name value type
            fields = fields[2:4]
        if len(fields) < 2 or fields[0] not in wanted:
            continue
        name, raw = fields[0], fields[1]
        try:
            given = float(raw)
        except ValueError:
            raise InvalidScenarioError(f'{path}:{number}: {name} is {raw[:40]!r}, not a '
                                       f'number') from None
        values[wanted[name][0]] = limit_of_parameter(name, given, firmware,
                                                     where=f'{path}:{number}: ',
                                                     shown=repr(raw[:40]))
    if not values:
        raise InvalidScenarioError(f'{path} sets none of {", ".join(wanted)} ({firmware})')
    return values


def read_parameter_file(path: str | os.PathLike, *, firmware: str = 'ardupilot',
                        base: VehicleLimits = VehicleLimits()) -> VehicleLimits:
    """The limits in a saved parameter file (:func:`parameter_file_values`), the others from
    ``base``; raises InvalidScenarioError as that does, or for limits no plan is made with."""
    return VehicleLimits(**{**base.__dict__, **parameter_file_values(path,
                                                                     firmware=firmware)})
