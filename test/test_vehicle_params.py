"""The vehicle's own limit parameters: each one in SI units, the one precedence rule (explicit
parameters over the user's parameter file over the vehicle's values over the firmware's
defaults), the read over MAVLink (requests by name, retries, a value changed later, PX4's
bytewise integers) against a fake vehicle, and the node planning with them, on real rclpy in
this process."""

from __future__ import annotations

import math
import struct

from diagnostic_msgs.msg import DiagnosticStatus
from fake_vehicle import Events, FakeVehicle
import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as MAV
import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter

from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.mission.request import limit_sources, vehicle_limits
from uav_comm_planner.vehicle.limits import limit_of_parameter, VehicleParameters
from uav_comm_planner.vehicle.mavlink.link import connect
from uav_comm_planner.vehicle.mavlink.parameters import (PARAMETER_TRIES, parameter_value,
                                                         ParameterRead, shortest_float32)
from uav_comm_planner.vehicle.px4_timing import px4_reach_time

#: name, firmware, value as the autopilot holds it, field, the SI value worked out by hand.
CONVERSIONS = [
    ('WPNAV_SPEED', 'ardupilot', 750.0, 'max_speed_mps', 7.5),        # cm/s
    ('WPNAV_ACCEL', 'ardupilot', 180.0, 'max_accel_mpss', 1.8),       # cm/s/s
    ('WPNAV_JERK', 'ardupilot', 2.0, 'max_jerk_mpsss', 2.0),
    ('ATC_INPUT_TC', 'ardupilot', 0.25, 'jerk_time_s', 0.5),          # tj = 2 TC
    ('ATC_INPUT_TC', 'ardupilot', 0.02, 'jerk_time_s', 0.2),          # TC floored at 0.1
    ('MPC_XY_CRUISE', 'px4', 8.0, 'max_speed_mps', 8.0),
    ('MPC_ACC_HOR', 'px4', 2.0, 'max_accel_mpss', 2.0),
    ('MPC_JERK_AUTO', 'px4', 6.0, 'max_jerk_mpsss', 6.0),
    ('NAV_ACC_RAD', 'px4', 6.0, 'acceptance_radius_m', 6.0),
]


@pytest.mark.parametrize('name, firmware, value, field, expected', CONVERSIONS)
def test_each_parameter_read_is_its_limit_in_si_units(name, firmware, value, field, expected):
    assert VehicleParameters(firmware, {name: value}).limits() == {
        field: pytest.approx(expected, rel=1e-12)}


@pytest.mark.parametrize('name, value, match', [
    ('WPNAV_SPEED', math.nan, 'not a finite number'),
    ('WPNAV_SPEED', math.inf, 'not a finite number'),
    ('ATC_INPUT_TC', 1e308, 'beyond what a plan can be made with'),
    ('MPC_XY_CRUISE', 5.0, 'none of WPNAV_SPEED'),
])
def test_a_value_no_plan_can_be_made_with_is_a_typed_error(name, value, match):
    with pytest.raises(InvalidScenarioError, match=match):
        limit_of_parameter(name, value, 'ardupilot')


def test_precedence_explicit_over_file_over_vehicle_over_firmware_default(tmp_path):
    read = VehicleParameters('ardupilot', {'WPNAV_SPEED': 750.0, 'WPNAV_ACCEL': 180.0,
                                           'WPNAV_JERK': 2.0}, missing=('ATC_INPUT_TC',))
    params = tmp_path / 'copter.param'
    params.write_text('WPNAV_ACCEL,300\nWPNAV_JERK,1.5\n')
    layers = {
        'the vehicle alone': ({}, None, (7.5, 1.8, 2.0)),
        'its file over it': ({}, params, (7.5, 3.0, 1.5)),
        'explicit over both': ({'max_speed_mps': 9.0, 'max_jerk_mpsss': 3.0}, params,
                               (9.0, 3.0, 3.0)),
    }
    for what, (explicit, file, (speed, accel, jerk)) in layers.items():
        limits = vehicle_limits(explicit, file, read=read)
        assert (limits.max_speed_mps, limits.max_accel_mpss, limits.max_jerk_mpsss) == \
            pytest.approx((speed, accel, jerk)), what
        assert limits.jerk_time_s == 0.3, 'ATC_INPUT_TC not answered: the default'
    assert limit_sources({'max_speed_mps'}, params, read=read) == {
        'max_speed_mps': 'explicit', 'max_accel_mpss': 'parameter file',
        'max_jerk_mpsss': 'parameter file', 'jerk_time_s': 'firmware default'}
    assert limit_sources((), None, read=read)['max_speed_mps'] == 'vehicle'
    # A read of another firmware than the plan's is not used.
    px4_read = VehicleParameters('px4', {'MPC_XY_CRUISE': 3.0})
    assert vehicle_limits(read=px4_read).max_speed_mps == 10.0
    assert vehicle_limits(firmware='px4', read=px4_read).max_speed_mps == 3.0
    assert limit_sources(read=px4_read)['max_speed_mps'] == 'firmware default'


def test_a_px4_acceptance_radius_read_from_the_vehicle_times_its_legs():
    read = VehicleParameters('px4', {'NAV_ACC_RAD': 6.0, 'MPC_ACC_HOR': 3.0})
    limits = vehicle_limits(firmware='px4', read=read)
    default = vehicle_limits(firmware='px4')
    assert limits.acceptance_radius_m == 6.0 and default.acceptance_radius_m is None
    line = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 80.0]])
    # The hold starts on entering the wider radius: sooner than within PX4's default 2 m.
    for speed in (1.0, 5.0):
        assert px4_reach_time(line, speed, limits) < px4_reach_time(line, speed, default)


class FakeLink:
    """What :class:`ParameterRead` uses of a pymavlink connection: the requests it sends."""

    target_system, target_component = 1, 1

    def __init__(self) -> None:
        self.requests: list[str] = []
        self.mav = self
        self.message_hooks = []

    def param_request_read_send(self, system, component, name: bytes, index: int) -> None:
        assert (system, component, index) == (1, 1, -1)
        self.requests.append(name.decode())


def param_value(name: str, value: float, kind: int = MAV.MAV_PARAM_TYPE_REAL32):
    mav = MAV.MAVLink(None, srcSystem=1, srcComponent=1)
    return mav.param_value_encode(name.encode(), value, kind, 10, 0)


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_a_read_asks_each_name_again_until_answered_or_given_up():
    link, clock = FakeLink(), Clock()
    reader = ParameterRead(MAV.MAV_AUTOPILOT_ARDUPILOTMEGA, timeout_s=1.0, tries=3, clock=clock)
    assert reader.poll(link) is None
    assert link.requests == ['WPNAV_SPEED', 'WPNAV_ACCEL', 'WPNAV_JERK', 'ATC_INPUT_TC']
    for name, value in (('WPNAV_SPEED', 750.0), ('WPNAV_ACCEL', 250.0), ('WPNAV_JERK', 1.0)):
        assert reader.heard(param_value(name, value)) is None
    assert reader.heard(param_value('SOMETHING_ELSE', 3.0)) is None
    clock.now = 0.5
    reader.poll(link)
    assert len(link.requests) == 4, 'asked again before its timeout'
    for now in (1.0, 2.0):
        clock.now = now
        assert reader.poll(link) is None
    assert link.requests[4:] == ['ATC_INPUT_TC', 'ATC_INPUT_TC']
    clock.now = 2.9
    assert reader.poll(link) is None, 'the last request still has time'
    clock.now = 3.0
    read = reader.poll(link)
    assert read == VehicleParameters('ardupilot', {'WPNAV_SPEED': 750.0, 'WPNAV_ACCEL': 250.0,
                                                   'WPNAV_JERK': 1.0}, ('ATC_INPUT_TC',))
    clock.now = 10.0
    assert reader.poll(link) is None and len(link.requests) == 6, 'handed on once'
    # A value a ground station changes later hands the read on again; the same value does not.
    assert reader.heard(param_value('WPNAV_SPEED', 750.0)) is None
    again = reader.heard(param_value('WPNAV_SPEED', 500.0))
    assert again.values['WPNAV_SPEED'] == 500.0


def test_px4_integer_parameters_are_decoded_bytewise():
    as_float = struct.unpack('<f', struct.pack('<i', 7))[0]
    message = param_value('SOME_INT', as_float, MAV.MAV_PARAM_TYPE_INT32)
    assert parameter_value(message, bytewise=True) == 7.0
    plain = parameter_value(message, bytewise=False)      # ArduPilot's: the float as it is
    assert plain != 7.0 and struct.pack('<f', plain) == struct.pack('<f', as_float)
    real = param_value('NAV_ACC_RAD', 6.0)
    assert parameter_value(real, bytewise=True) == 6.0
    # A float32 is read as the decimal a ground station shows, the same float32.
    for value in (0.15, 0.1, 1e-7, 3.4e38, 123456.7, 750.0):
        single = struct.unpack('<f', struct.pack('<f', value))[0]
        shown = parameter_value(param_value('ATC_INPUT_TC', single), bytewise=False)
        assert shown == value and repr(shown) == repr(value)
        assert struct.pack('<f', shown) == struct.pack('<f', single)
    assert shortest_float32(math.inf) == math.inf and math.isnan(shortest_float32(math.nan))
    reader = ParameterRead(MAV.MAV_AUTOPILOT_PX4)
    assert reader.names == ('MPC_XY_CRUISE', 'MPC_ACC_HOR', 'MPC_JERK_AUTO', 'NAV_ACC_RAD',
                            'MPC_XY_TRAJ_P', 'MPC_XY_ERR_MAX')


def test_a_connection_reads_the_vehicles_parameters_over_tcp_with_retries():
    events = Events()
    with FakeVehicle('good') as vehicle:
        vehicle.parameters = {'WPNAV_SPEED': 650.0, 'WPNAV_ACCEL': 250.0, 'WPNAV_JERK': 1.0,
                              'ATC_INPUT_TC': 0.15}
        vehicle.parameter_drops = 2         # the first two requests are lost
        link = connect(vehicle.url, timeout_s=5.0, parameters=events)
        try:
            def reads():
                return [e for _, e in events.seen if isinstance(e, VehicleParameters)]

            def pump() -> bool:
                link.recv_match(blocking=True, timeout=0.1)
                return bool(reads())
            events.wait(pump, 'the read', timeout_s=10.0)
            assert reads()[0] == VehicleParameters('ardupilot', vehicle.parameters)
            asked = [entry for entry in vehicle.log if entry == ('PARAM_REQUEST_READ',)]
            assert 6 <= len(asked) <= 4 * PARAMETER_TRIES
            vehicle.parameters['WPNAV_SPEED'] = 900.0
            vehicle.announce.append('WPNAV_SPEED')
            events.wait(lambda: pump() and len(reads()) == 2, 'the change', timeout_s=10.0)
            assert reads()[1].values['WPNAV_SPEED'] == 900.0
        finally:
            link.close()


#: A small mission the node plans at once, for a vehicle (its limits matter).
MISSION = {'ground_nodes': [0.0, 300.0, 300.0, 300.0], 'start_m': [0.0, 0.0],
           'goal_m': [300.0, 0.0], 'horizon_s': 120.0, 'num_slots': 30, 'max_speed_mps': 6.0,
           'vehicle_aware': True, 'compute_baselines': False}
COPTER = {'WPNAV_SPEED': 750.0, 'WPNAV_ACCEL': 180.0, 'WPNAV_JERK': 1.0, 'ATC_INPUT_TC': 0.15}


def _planned_with(h, speed_mps: float) -> None:
    h.spin_until(lambda: h.node.current_plan is not None
                 and h.node.current_plan.plan.vehicle_plan.limits.max_speed_mps == speed_mps,
                 f'a plan for {speed_mps} m/s')
    legs = h.node.current_plan.plan.vehicle_plan.schedule.legs
    assert max(leg.speed_mps for leg in legs) <= speed_mps


@pytest.mark.slow
def test_the_node_plans_with_the_vehicles_parameters_unless_set_explicitly(harness):
    with FakeVehicle('good', positions=True) as vehicle:
        vehicle.parameters = dict(COPTER)
        h = harness(mavlink_url=vehicle.url, **MISSION)
        watch = h.node.vehicle.parameters
        _planned_with(h, 7.5)
        limits = h.node.config.vehicle
        assert (limits.max_speed_mps, limits.max_accel_mpss, limits.jerk_time_s) == \
            pytest.approx((7.5, 1.8, 0.3))
        assert watch.used and watch.reads == 1
        assert watch.describe() == ('vehicle parameters (ardupilot): WPNAV_SPEED 750 (used), '
                                    'WPNAV_ACCEL 180 (used), WPNAV_JERK 1 (used), ATC_INPUT_TC '
                                    '0.15 (used)')
        level, message, values = watch.status()
        assert level == DiagnosticStatus.OK and values['max_speed_mps_from'] == 'vehicle'
        # An explicit speed wins over the vehicle's; the vehicle's acceleration stays.
        answer = h.call('set_parameters', SetParameters.Request(parameters=[
            Parameter('vehicle_max_speed_mps', value=7.0).to_parameter_msg()]))
        assert answer.results[0].successful
        _planned_with(h, 7.0)
        assert h.node.config.vehicle.max_accel_mpss == pytest.approx(1.8)
        assert watch.status()[2]['max_speed_mps_from'] == 'explicit'
        assert 'vehicle_max_speed_mps set explicitly wins' in watch.describe()


@pytest.mark.slow
def test_vehicle_values_that_fit_no_plan_are_refused_then_used_once_they_fit(harness):
    with FakeVehicle('good', positions=True) as vehicle:
        vehicle.parameters = {**COPTER, 'WPNAV_SPEED': 500.0}       # 5 m/s < max_speed 6
        h = harness(mavlink_url=vehicle.url, **MISSION)
        watch = h.node.vehicle.parameters
        h.spin_until(lambda: watch.refusal != '', 'the refusal')
        assert 'faster than the vehicle flies' in watch.refusal and not watch.used
        assert h.node.config.vehicle.max_speed_mps == 10.0
        assert watch.status()[0] == DiagnosticStatus.WARN
        error = h.node.stats.last_error
        assert error.startswith('vehicle parameters (ardupilot): WPNAV_SPEED 500 (not used)')
        assert 'plan with max_speed_mps <= 5' in error
        answer = h.call('set_parameters', SetParameters.Request(parameters=[
            Parameter('max_speed_mps', value=5.0).to_parameter_msg()]))
        assert answer.results[0].successful
        _planned_with(h, 5.0)
        assert watch.used and h.node.config.vehicle.max_speed_mps == 5.0


@pytest.mark.slow
def test_a_vehicle_of_another_firmware_than_the_plans_is_read_and_not_used(harness):
    with FakeVehicle('good', positions=True) as vehicle:        # an ArduPilot heartbeat
        vehicle.parameters = dict(COPTER)
        h = harness(mavlink_url=vehicle.url, mission_firmware='px4',
                    **{**MISSION, 'max_speed_mps': 5.0, 'vehicle_max_speed_mps': 5.0})
        watch = h.node.vehicle.parameters
        h.spin_until(lambda: watch.read is not None, 'the read')
        assert h.node.config.vehicle.max_speed_mps == 5.0
        assert h.node.config.vehicle.max_accel_mpss == 3.0         # PX4's default, not 1.8
        line = watch.describe()
        assert 'WPNAV_SPEED 750 (not used)' in line and 'WPNAV_ACCEL 180 (not used)' in line
        assert line.endswith('not used: the plan is made for mission_firmware px4')
        assert watch.status()[0] == DiagnosticStatus.WARN


def test_the_command_lines_vehicle_params_help_names_every_key_it_reads(capsys):
    from uav_comm_planner.tools.cli import build_parser
    from uav_comm_planner.vehicle.firmware import FIRMWARES

    with pytest.raises(SystemExit) as stopped:
        build_parser().parse_args(['plan', '--help'])
    assert stopped.value.code == 0
    text = ' '.join(capsys.readouterr().out.split())
    help_text = text[text.index('--vehicle-params FILE parameter file'):]
    help_text = help_text[:help_text.index('--wp-speed VEHICLE')]
    for name, firmware in FIRMWARES.items():
        assert f'{", ".join(firmware.parameters)} ({name})' in help_text
    assert 'NAV_ACC_RAD' in help_text
