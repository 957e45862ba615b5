"""The measured airframe of ArduCopter SITL's quad, and airframes fitted to flight logs.

- ``arducopter-sitl-quad`` (``make airframe``: devtools/measure_airframe.py flew SITL and
  fitted it) loads by name, and its curve matches the shipped samples within the RMS its
  ``source`` line states;
- the fit recovers a known airframe's power curve within 1 % from synthetic samples and from a
  synthetic tlog (SYS_STATUS power, GLOBAL_POSITION_INT speeds);
- ``uav-comm-planner fit-airframe`` fits the tlog recorded on SITL (test/data/, BATTERY_STATUS
  and VFR_HUD) to the shipped airframe's curve, end to end; bad input is one line and exit 2,
  and leaves an existing output file alone.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
import re
import struct

import numpy as np
from pymavlink import mavutil
import pytest
import yaml

from devtools import measure_airframe
from devtools.measure_airframe import CHECKOUT_SITL
from devtools.sitl import sitl_binary, why_not_runnable
from uav_comm_planner.core.propulsion import Airframe, ZENG2019
from uav_comm_planner.core.propulsion_fit import fit_airframe
from uav_comm_planner.errors import InvalidScenarioError, MissionFileError
from uav_comm_planner.tools.cli import main
from uav_comm_planner.vehicle.airframe import airframe_named, airframe_names, load_airframe
from uav_comm_planner.vehicle.airframe_fit import (fit_flight_log, read_samples_csv, read_tlog,
                                                    steady_mask, steady_samples)

MAV = mavutil.mavlink
AIRFRAMES = Path(__file__).resolve().parents[1] / 'uav_comm_planner' / 'vehicle' / 'airframes'
SAMPLES_CSV = AIRFRAMES / 'arducopter_sitl_quad.csv'
SITL_TLOG = Path(__file__).resolve().parent / 'data' / 'sitl_quad_legs.tlog'
GRID = np.linspace(0.0, 12.0, 49)


def stated_rms_w() -> float:
    text = yaml.safe_load((AIRFRAMES / 'arducopter_sitl_quad.yaml').read_text())['source']
    return float(re.search(r'RMS ([0-9.]+) W', text).group(1))


def test_the_measured_quad_loads_by_name_with_its_measured_figures():
    quad = airframe_named('arducopter-sitl-quad')
    assert 'arducopter-sitl-quad' in airframe_names()
    assert quad.name == 'arducopter-sitl-quad'
    # measured: about 354 W hovering, 382 W at 10 m/s, 412 W at 12 m/s; top speed 10.3 m/s
    assert quad.hover_power_w == pytest.approx(354.2, abs=2.0)
    assert float(quad.level_power_w(10.0)) == pytest.approx(382.0, abs=2.0)
    assert float(quad.level_power_w(12.0)) == pytest.approx(412.0, abs=2.0)
    assert quad.top_airspeed_mps == pytest.approx(10.3, abs=0.1)
    # climbing costs power, descending saves a little
    assert quad.climb_w_per_mps > 5.0 and quad.descent_w_per_mps < 0.0


def test_the_measured_curve_matches_the_shipped_samples_within_the_stated_rms():
    samples, extra = read_samples_csv(SAMPLES_CSV)
    steady = [s for s, keep in zip(samples, extra['steady']) if keep == '1']
    assert len(steady) >= 500
    quad = airframe_named('arducopter-sitl-quad')
    error = quad.power_w([s.airspeed_mps for s in steady], [s.climb_mps for s in steady]) - [
        s.power_w for s in steady]
    rms = float(np.sqrt(np.mean(error ** 2)))
    assert rms <= stated_rms_w() + 0.005
    assert stated_rms_w() < 2.0
    # the samples span hover to 12 m/s, a climb and a descent
    speeds = np.array([s.airspeed_mps for s in steady])
    climbs = np.array([s.climb_mps for s in steady])
    assert speeds.min() < 0.5 and speeds.max() > 11.5
    assert climbs.max() > 2.0 and climbs.min() < -1.0


def test_the_power_does_not_depend_on_the_heading_in_still_air():
    samples, extra = read_samples_csv(SAMPLES_CSV)
    means = {}
    for sample, phase, keep in zip(samples, extra['phase'], extra['steady']):
        if keep == '1' and phase.startswith('leg 10 '):
            means.setdefault(phase, []).append(sample.power_w)
    assert len(means) == 4
    powers = [float(np.mean(values)) for values in means.values()]
    assert max(powers) - min(powers) < 1.0


def noisy_samples(airframe: Airframe, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    speed = np.repeat(np.arange(0.0, airframe.top_airspeed_mps + 0.1, 2.0), 20)
    climb = np.zeros_like(speed)
    speed = np.concatenate([speed, np.zeros(40)])
    climb = np.concatenate([climb, np.full(20, 2.5), np.full(20, -1.5)])
    power = airframe.power_w(speed, climb) + rng.normal(0.0, 0.5, speed.size)
    return speed, climb, power


@pytest.mark.parametrize('airframe', [
    dataclasses.replace(ZENG2019, climb_w_per_mps=15.0, descent_w_per_mps=-8.0),
    Airframe(name='heavy', blade_profile_power_w=150.0, induced_power_w=420.0,
             tip_speed_mps=150.0, induced_velocity_mps=7.0, fuselage_drag_ratio=0.3,
             air_density_kg_per_m3=1.225, rotor_solidity=0.08, rotor_disc_area_m2=0.9,
             top_airspeed_mps=18.0, climb_w_per_mps=30.0, descent_w_per_mps=-12.0),
], ids=['zeng2019', 'heavy'])
def test_the_fit_recovers_a_known_power_curve_within_one_percent(airframe):
    speed, climb, power = noisy_samples(airframe, seed=7)
    fit = fit_airframe('fitted', speed, climb, power)
    grid = np.linspace(0.0, airframe.top_airspeed_mps, 61)
    relative = fit.airframe.level_power_w(grid) / airframe.level_power_w(grid) - 1.0
    assert np.abs(relative).max() < 0.01
    assert fit.airframe.climb_w_per_mps == pytest.approx(airframe.climb_w_per_mps, rel=0.05)
    assert fit.airframe.descent_w_per_mps == pytest.approx(airframe.descent_w_per_mps,
                                                           rel=0.05)
    assert fit.rms_w < 1.0 and fit.fitted_climb and fit.fitted_descent
    assert fit.airframe.top_airspeed_mps == pytest.approx(speed.max())


def test_the_fit_refuses_samples_that_cannot_identify_the_curve():
    with pytest.raises(InvalidScenarioError, match='distinct airspeeds'):
        fit_airframe('x', np.full(30, 5.0), np.zeros(30), np.full(30, 360.0))
    with pytest.raises(InvalidScenarioError, match='finite'):
        fit_airframe('x', [0.0, np.nan], [0.0, 0.0], [1.0, 1.0])
    with pytest.raises(InvalidScenarioError, match='as many'):
        fit_airframe('x', [0.0, 1.0], [0.0], [1.0, 1.0])


# A synthetic tlog: a flight of level legs, a climb and a descent of a known airframe, logged as
# ArduPilot does (HEARTBEAT, GLOBAL_POSITION_INT, SYS_STATUS / BATTERY_STATUS, VFR_HUD) at 2 Hz.

def flight_profile(top_mps: float) -> list[tuple[float, float]]:
    """(airspeed, climb) every 0.5 s: 30 s per leg, ramps of a few seconds between."""
    legs = [(v, 0.0) for v in np.arange(0.0, top_mps + 0.1, 2.0)] + [(0.0, 2.5), (0.0, -1.5)]
    profile, current = [], (0.0, 0.0)
    for target in legs:
        for step in np.linspace(0.0, 1.0, 8)[1:]:      # a 3.5 s ramp
            profile.append(tuple(c + step * (t - c) for c, t in zip(current, target)))
        profile += [target] * 60
        current = target
    return profile


def write_tlog(path: Path, airframe: Airframe, *, power_message: str = 'SYS_STATUS',
               speed_message: str = 'GLOBAL_POSITION_INT', armed: bool = True,
               speedup: float = 1.0) -> None:
    """The log's stamps are wall-clock time of a simulator at ``speedup``."""
    mav = MAV.MAVLink(None, srcSystem=1, srcComponent=1)
    with open(path, 'wb') as handle:
        def put(message, time_s: float) -> None:
            handle.write(struct.pack('>Q', int((1.7e9 + time_s / speedup) * 1e6))
                         + message.pack(mav))

        for k, (speed, climb) in enumerate(flight_profile(airframe.top_airspeed_mps)):
            time_s = 100.0 + 0.5 * k
            boot_ms = int(time_s * 1000)
            if k % 2 == 0:
                put(mav.heartbeat_encode(MAV.MAV_TYPE_QUADROTOR, MAV.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                         MAV.MAV_MODE_FLAG_SAFETY_ARMED if armed else 0, 4,
                                         MAV.MAV_STATE_ACTIVE), time_s)
            if speed_message == 'GLOBAL_POSITION_INT':
                put(mav.global_position_int_encode(boot_ms, 0, 0, 150000, 50000,
                                                   int(round(speed * 100)), 0,
                                                   int(round(-climb * 100)), 9000), time_s)
            elif speed_message == 'VFR_HUD':
                put(mav.system_time_encode(0, boot_ms), time_s)
                put(mav.vfr_hud_encode(speed, speed, 90, 50, 150.0, climb), time_s)
            current_ca = int(round(float(airframe.power_w(speed, climb)) / 12.6 * 100))
            if power_message == 'SYS_STATUS':
                put(mav.sys_status_encode(0, 0, 0, 500, 12600, current_ca, 90, 0, 0, 0, 0, 0,
                                          0), time_s)
            elif power_message == 'BATTERY_STATUS':
                put(mav.battery_status_encode(0, 0, 0, 2500, [12600] + [65535] * 9,
                                              current_ca, -1, -1, 90), time_s)


@pytest.mark.parametrize('power_message, speed_message', [
    ('SYS_STATUS', 'GLOBAL_POSITION_INT'), ('BATTERY_STATUS', 'VFR_HUD')])
def test_a_synthetic_tlog_recovers_its_airframe(power_message, speed_message, tmp_path):
    """Both sources of power and of speed, timed by the autopilot's clock (the log's stamps
    are those of a simulator at 20x: the steady windows would find nothing by them)."""
    airframe = dataclasses.replace(ZENG2019, top_airspeed_mps=20.0, climb_w_per_mps=15.0,
                                   descent_w_per_mps=-8.0)
    log = tmp_path / 'flight.tlog'
    write_tlog(log, airframe, power_message=power_message, speed_message=speed_message,
               speedup=20.0)
    samples = read_tlog(log)
    steady = steady_samples(samples)
    assert 0 < len(steady) < len(samples)      # the ramps are left out
    fit, in_flight = fit_flight_log(log, 'synthetic')
    assert in_flight == len(samples)
    grid = np.linspace(0.0, 20.0, 41)
    relative = fit.airframe.level_power_w(grid) / airframe.level_power_w(grid) - 1.0
    assert np.abs(relative).max() < 0.01
    assert fit.airframe.climb_w_per_mps == pytest.approx(15.0, rel=0.05)
    assert fit.airframe.top_airspeed_mps == pytest.approx(20.0)


def test_a_disarmed_log_gives_no_samples(tmp_path):
    log = tmp_path / 'ground.tlog'
    write_tlog(log, ZENG2019, armed=False)
    assert read_tlog(log) == []


def test_the_sitl_tlog_fits_the_measured_quad(tmp_path):
    """The recorded SITL flight (1 Hz) read and fitted: the same curve as the shipped fit of the
    2 Hz samples, within 1 %."""
    quad = airframe_named('arducopter-sitl-quad')
    fit, in_flight = fit_flight_log(SITL_TLOG, 'from-log')
    assert in_flight > 500 and fit.samples > 200
    relative = fit.airframe.level_power_w(GRID) / quad.level_power_w(GRID) - 1.0
    assert np.abs(relative).max() < 0.01
    assert fit.airframe.climb_w_per_mps == pytest.approx(quad.climb_w_per_mps, rel=0.1)
    assert fit.airframe.descent_w_per_mps == pytest.approx(quad.descent_w_per_mps, rel=0.1)


def test_fit_airframe_command_end_to_end(tmp_path, capsys):
    output = tmp_path / 'my_quad.yaml'
    assert main(['fit-airframe', str(SITL_TLOG), '--name', 'my-quad', '--output',
                 str(output)]) == 0
    printed = capsys.readouterr().out
    assert 'my-quad' in printed and 'RMS' in printed
    fitted = load_airframe(output)
    assert fitted.name == 'my-quad'
    quad = airframe_named('arducopter-sitl-quad')
    assert np.abs(fitted.level_power_w(GRID) / quad.level_power_w(GRID) - 1.0).max() < 0.01
    assert 'sitl_quad_legs.tlog' in yaml.safe_load(output.read_text())['source']
    # a top airspeed given wins over the log's fastest
    assert main(['fit-airframe', str(SITL_TLOG), '--name', 'my-quad', '--output', str(output),
                 '--top-airspeed', '9.5']) == 0
    assert load_airframe(output).top_airspeed_mps == 9.5


def bad_logs(tmp_path: Path) -> dict[str, tuple[Path, str]]:
    no_battery = tmp_path / 'no_battery.tlog'
    write_tlog(no_battery, ZENG2019, power_message='none', speed_message='VFR_HUD')
    no_speed = tmp_path / 'no_speed.tlog'
    write_tlog(no_speed, ZENG2019, power_message='BATTERY_STATUS', speed_message='none')
    hover_only = tmp_path / 'hover_only.tlog'
    hover_only.write_bytes(b''.join(
        chunk for chunk in _records(SITL_TLOG) if _is_hover_or_heartbeat(chunk)))
    garbage = tmp_path / 'garbage.tlog'
    garbage.write_bytes(bytes(range(256)) * 40)
    return {'missing file': (tmp_path / 'absent.tlog', 'no such file'),
            'no battery': (no_battery, 'no battery power'),
            'no speeds': (no_speed, 'no speeds'),
            'too few steady samples': (hover_only, 'steady'),
            'not a tlog': (garbage, 'no battery power')}


def _records(path: Path) -> list[bytes]:
    """A tlog's records (stamp + MAVLink frame), split by parsing it."""
    log = mavutil.mavlink_connection(str(path))
    records = []
    while (message := log.recv_match()) is not None:
        records.append(struct.pack('>Q', int(message._timestamp * 1e6)) + message.get_msgbuf())
    log.close()
    return records


def _is_hover_or_heartbeat(record: bytes) -> bool:
    """The first 60 s of the SITL flight's records only (takeoff and hover)."""
    return struct.unpack('>Q', record[:8])[0] / 1e6 - 1.7e9 < 150.0


@pytest.mark.parametrize('case', ['missing file', 'no battery', 'no speeds',
                                  'too few steady samples', 'not a tlog'])
def test_bad_logs_exit_2_with_one_line_and_keep_the_output(case, tmp_path, capsys):
    log, reason = bad_logs(tmp_path)[case]
    output = tmp_path / 'kept.yaml'
    output.write_text('earlier\n')
    assert main(['fit-airframe', str(log), '--name', 'x', '--output', str(output)]) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and err.startswith('uav-comm-planner: error: ')
    assert reason in err
    assert output.read_text() == 'earlier\n'


@pytest.mark.parametrize('arguments, reason', [
    (['--name', 'x', '--top-airspeed', '-1'], 'top-airspeed'),
    (['--name', ' '], '--name must not be empty'),
    (['--name', 'x', '--output', 'absent/x.yaml'], 'does not exist'),
])
def test_bad_arguments_exit_2_before_the_log_is_read(arguments, reason, tmp_path, capsys,
                                                     monkeypatch):
    monkeypatch.chdir(tmp_path)
    if '--output' not in arguments:
        arguments = arguments + ['--output', 'x.yaml']
    monkeypatch.setattr('uav_comm_planner.tools.fit_airframe.fit_flight_log', None)
    assert main(['fit-airframe', str(SITL_TLOG), *arguments]) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and reason in err
    assert list(tmp_path.iterdir()) == []


def test_read_tlog_errors_are_typed(tmp_path):
    with pytest.raises(MissionFileError, match='no such file'):
        read_tlog(tmp_path / 'absent.tlog')


@pytest.mark.sitl
@pytest.mark.skipif(bool(why_not_runnable(sitl_binary() or CHECKOUT_SITL)),
                    reason=why_not_runnable(sitl_binary() or CHECKOUT_SITL))
def test_a_fresh_sitl_flight_draws_the_shipped_airframes_power(tmp_path, capsys):
    """A short flight on SITL now (takeoff to 100 m, hover, legs at 5 and 10 m/s): each steady
    stretch's mean power is the shipped airframe's within 2 W, and fit-airframe fits its tlog."""
    def short_flight(recorder):
        measure_airframe.climb_to(recorder)
        recorder.phase = 'hover'
        recorder.wait(20.0)
        measure_airframe.fly_leg(recorder, 5.0, 90.0)
        measure_airframe.fly_leg(recorder, 10.0, 270.0)

    tlog = tmp_path / 'short.tlog'
    rows = measure_airframe.session(tmp_path, short_flight, tlog=tlog,
                                    binary=sitl_binary() or CHECKOUT_SITL)
    flying = [row for row in rows if row.phase and row.altitude_m >= 2.0]
    samples = measure_airframe.to_samples(flying)
    steady = steady_mask(samples)
    quad = airframe_named('arducopter-sitl-quad')
    groups, lines = {}, []
    for sample, row, keep in zip(samples, flying, steady):
        if keep:
            groups.setdefault(row.phase, []).append(sample)
    assert set(groups) == {'takeoff', 'hover', 'leg 5 90', 'leg 10 270'}
    for phase, chosen in groups.items():
        measured = np.mean([s.power_w for s in chosen])
        model = np.mean(quad.power_w([s.airspeed_mps for s in chosen],
                                     [s.climb_mps for s in chosen]))
        lines.append(f'{phase}: {measured:.1f} W measured, {model:.1f} W by the airframe')
        assert abs(measured - model) < 2.0, lines[-1]
    assert main(['fit-airframe', str(tlog), '--name', 'fresh', '--output',
                 str(tmp_path / 'fresh.yaml')]) == 0
    printed = capsys.readouterr().out
    assert 'fresh' in printed
    print('\n' + '\n'.join(lines + [printed.strip()]))    # for the record (pytest -s)
