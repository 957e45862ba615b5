"""The autopilots a plan is made for, and everything that differs between them: one table.

Every firmware name the package takes (``plan --firmware``, the node's ``mission_firmware``,
:func:`~uav_comm_planner.vehicle.flyable.plan_for_vehicle`, a parameter file, a mission) is a
key of :data:`FIRMWARES`. It is a leaf of the vehicle side, so that the limits, the timing
(:mod:`.flyable`) and the mission (:mod:`.mavlink.items`, which imports the timing) all read
the same table.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Mapping

from pymavlink import mavutil

from uav_comm_planner.errors import InvalidScenarioError

MAV = mavutil.mavlink


@dataclass(frozen=True)
class StreamModes:
    """The flight modes of a streamed trajectory on one autopilot.

    modes: name -> HEARTBEAT custom_mode (what SET_MODE asks for, with
    MAV_MODE_FLAG_CUSTOM_MODE_ENABLED); follow: the mode that flies the targets; resume: the
    mode that flies the mission; hold: the mode that holds the position;
    lead_s: autopilot seconds of targets sent before ``follow`` is asked (PX4 takes OFFBOARD
    only while targets are coming);
    amsl_targets: whether the targets' altitude is sent above mean sea level
    (MAV_FRAME_GLOBAL_INT, the vehicle's home altitude added) rather than above home. PX4
    v1.16 turns a MAV_FRAME_GLOBAL_RELATIVE_ALT_INT altitude h into the local down
    coordinate home - h - origin instead of origin - home - h, which is off by twice the
    height of its home over its local origin; its GLOBAL_INT altitude is exact.
    """

    modes: Mapping[str, int]
    follow: str
    resume: str
    hold: str
    lead_s: float
    amsl_targets: bool


def px4_mode(main: int, sub: int = 0) -> int:
    """PX4's custom_mode of main mode ``main``, sub mode ``sub`` (px4_custom_mode: the main
    mode in the third byte, the sub mode in the fourth)."""
    return main << 16 | sub << 24


#: PX4's main modes AUTO (4) and OFFBOARD (6); AUTO's sub modes LOITER (3) and MISSION (4).
PX4_AUTO, PX4_OFFBOARD, PX4_LOITER, PX4_MISSION = 4, 6, 3, 4


@dataclass(frozen=True)
class Firmware:
    """What a plan, its mission and a parameter file depend on in one autopilot.

    autopilot: its MAV_AUTOPILOT (a .plan file's ``firmwareType``);
    hold_resolution_s: the step a waypoint's hold is commanded in (ArduPilot keeps whole
    seconds, a uint16; PX4 a float);
    max_hold_s: the longest hold one waypoint stores; a longer hold repeats the waypoint;
    waypoint_yaw: param4 of the takeoff, waypoints and landing. PX4 reads a yaw of 0 as "face
    north", NaN keeps its own heading mode; ArduCopter ignores the waypoint yaw, and Mission
    Planner shows NaN as an error, so it gets 0;
    parameters: the parameters that state the vehicle's limits, name -> (VehicleLimits field,
    factor to SI units);
    timing: how its legs are timed, a key of
    :data:`~uav_comm_planner.vehicle.leg_models.LEG_MODELS` (ArduPilot's S-curve planned
    ahead, or PX4's trajectory generator);
    default_limits: the limits (VehicleLimits field -> SI value) the firmware ships with,
    where they differ from :class:`~uav_comm_planner.vehicle.limits.VehicleLimits`' own
    (which are ArduCopter's): a plan for this firmware without a parameter file or explicit
    limits uses them;
    stream_modes: the flight modes the streamed trajectory uses
    (:mod:`.mavlink.guided`);
    sitl_home: where its software-in-the-loop simulator starts (latitude deg, longitude deg,
    altitude m above mean sea level): the home a plan for it is anchored at when no home is
    given (:func:`~uav_comm_planner.vehicle.geodesy.default_home`).
    parameter_floors: name -> the least value the firmware flies with, whatever the parameter
    says (ArduCopter's S-curve takes max(ATC_INPUT_TC, 0.1): AC_WPNav's snap is
    J pi / (2 max(ATC_INPUT_TC, 0.1)), halved, and SCurve's jerk time J pi / (2 snap), so
    tj = 2 max(ATC_INPUT_TC, 0.1)); applied before the factor.
    """

    autopilot: int
    hold_resolution_s: float
    max_hold_s: float
    waypoint_yaw: float
    parameters: Mapping[str, tuple[str, float]]
    timing: str
    default_limits: Mapping[str, float]
    stream_modes: StreamModes
    sitl_home: tuple[float, float, float]
    parameter_floors: Mapping[str, float] = field(default_factory=dict)


FIRMWARES = {
    'ardupilot': Firmware(
        autopilot=MAV.MAV_AUTOPILOT_ARDUPILOTMEGA, hold_resolution_s=1.0, max_hold_s=65535.0,
        waypoint_yaw=0.0,
        parameters={'WPNAV_SPEED': ('max_speed_mps', 0.01),
                    'WPNAV_ACCEL': ('max_accel_mpss', 0.01),
                    'WPNAV_JERK': ('max_jerk_mpsss', 1.0),
                    'ATC_INPUT_TC': ('jerk_time_s', 2.0)},
        timing='scurve', default_limits={},
        stream_modes=StreamModes(modes={'AUTO': 3, 'GUIDED': 4, 'BRAKE': 17}, follow='GUIDED',
                                 resume='AUTO', hold='BRAKE', lead_s=0.0,
                                 amsl_targets=False),
        # ArduPilot SITL's default location, CMAC (Canberra Model Aircraft Club).
        sitl_home=(-35.363262, 149.165237, 584.0),
        parameter_floors={'ATC_INPUT_TC': 0.1}),
    'px4': Firmware(
        autopilot=MAV.MAV_AUTOPILOT_PX4, hold_resolution_s=0.01, max_hold_s=1e9,
        waypoint_yaw=math.nan,
        parameters={'MPC_XY_CRUISE': ('max_speed_mps', 1.0),
                    'MPC_ACC_HOR': ('max_accel_mpss', 1.0),
                    'MPC_JERK_AUTO': ('max_jerk_mpsss', 1.0),
                    'NAV_ACC_RAD': ('acceptance_radius_m', 1.0),
                    'MPC_XY_TRAJ_P': ('turn_gain', 1.0),
                    'MPC_XY_ERR_MAX': ('max_position_error_m', 1.0)},
        # PX4 v1.16's MPC_XY_CRUISE, MPC_ACC_HOR and MPC_JERK_AUTO defaults.
        timing='px4', default_limits={'max_speed_mps': 5.0, 'max_accel_mpss': 3.0,
                                      'max_jerk_mpsss': 4.0},
        # PX4 leaves OFFBOARD when no target came for COM_OF_LOSS_T (1 s by default); half a
        # second of targets at 20 Hz (PX4 asks for more than 2 Hz) comes before the switch.
        stream_modes=StreamModes(modes={'AUTO.MISSION': px4_mode(PX4_AUTO, PX4_MISSION),
                                        'OFFBOARD': px4_mode(PX4_OFFBOARD),
                                        'AUTO.LOITER': px4_mode(PX4_AUTO, PX4_LOITER)},
                                 follow='OFFBOARD', resume='AUTO.MISSION', hold='AUTO.LOITER',
                                 lead_s=0.5, amsl_targets=True),
        # PX4 SITL's default home, Zurich (SIH's SIH_LOC_LAT0, SIH_LOC_LON0, SIH_LOC_H0).
        sitl_home=(47.397742, 8.545594, 489.0)),
}


def firmware_named(name: str) -> Firmware:
    """The firmware called ``name``; an InvalidScenarioError that lists the names otherwise."""
    if name not in FIRMWARES:
        raise InvalidScenarioError(f'unknown firmware {name!r}: choose one of '
                                   f'{", ".join(FIRMWARES)}')
    return FIRMWARES[name]


def firmware_name_of_autopilot(autopilot: int | None) -> str:
    """The name of a heartbeat's MAV_AUTOPILOT's firmware: 'px4' for PX4, 'ardupilot'
    otherwise (and when the autopilot is not known)."""
    return 'px4' if autopilot == MAV.MAV_AUTOPILOT_PX4 else 'ardupilot'


def firmware_of_autopilot(autopilot: int | None) -> Firmware:
    """The firmware of a heartbeat's MAV_AUTOPILOT (:func:`firmware_name_of_autopilot`)."""
    return FIRMWARES[firmware_name_of_autopilot(autopilot)]


__all__ = ['FIRMWARES', 'Firmware', 'StreamModes', 'firmware_name_of_autopilot', 'firmware_named',
           'firmware_of_autopilot', 'px4_mode']
