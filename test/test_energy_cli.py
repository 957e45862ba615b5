"""Energy on the command line: the airframe's energy stated and recomputable from the JSON, a
cap kept, a battery that cannot fly refused before planning, and the least-energy plan."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from uav_comm_planner.tools import cli

#: Case I at 30 m/s over 200 s (50 slots of 4 s): Zeng's airframe flies it.
CASE = ('plan', '--case', 'I', '--speed', '30', '--horizon', '200', '--airframe', 'zeng2019')


def run(capsys, *argv):
    status = cli.main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def eq12(speed: float, airframe: dict) -> float:
    """Zeng 2019 eq. (12) from the JSON's own airframe fields."""
    p0, pi = airframe['blade_profile_power_w'], airframe['induced_power_w']
    u_tip, v0 = airframe['tip_speed_mps'], airframe['induced_velocity_mps']
    drag = 0.5 * (airframe['fuselage_drag_ratio'] * airframe['air_density_kg_per_m3']
                  * airframe['rotor_solidity'] * airframe['rotor_disc_area_m2'])
    return (p0 * (1 + 3 * speed ** 2 / u_tip ** 2)
            + pi * math.sqrt(math.sqrt(1 + speed ** 4 / (4 * v0 ** 4))
                             - speed ** 2 / (2 * v0 ** 2))
            + drag * speed ** 3)


def recomputed_energy_j(data: dict) -> tuple[float, list[float]]:
    """The horizon's energy from the JSON's trajectory, scenario and airframe: each leg
    q0 -> q[1] -> ... -> qF at constant velocity over one slot, at its airspeed."""
    scenario = data['scenario']
    slot = scenario['horizon_s'] / scenario['num_slots']
    towards = math.radians(scenario['wind_from_deg'] + 180.0)
    wind = scenario['wind_speed_mps'] * np.array([math.sin(towards), math.cos(towards)])
    path = [scenario['start_m'], *data['trajectory'], scenario['goal_m']]
    powers = [eq12(float(np.linalg.norm((np.subtract(b, a)) / slot - wind)),
                   scenario['airframe']) for a, b in zip(path, path[1:])]
    return sum(powers) * slot, powers


@pytest.mark.parametrize('wind', [[], ['--wind', '5,45']])
def test_the_json_energy_equals_a_recomputation_from_its_own_trajectory(tmp_path, capsys, wind):
    result = tmp_path / 'r.json'
    status, out, _ = run(capsys, *CASE, *wind, '--json', str(result))
    assert status == 0 and 'propulsion (zeng2019): horizon' in out
    data = json.loads(result.read_text())
    energy, powers = recomputed_energy_j(data)
    assert data['propulsion_energy_j'] == pytest.approx(energy, rel=1e-12)
    np.testing.assert_allclose(data['propulsion_power_w'], powers, rtol=1e-12)
    assert data['mission_energy_j'] == pytest.approx(
        data['takeoff_energy_j'] + energy + data['landing_energy_j'], rel=1e-12)


def test_a_cap_below_the_free_plan_s_energy_is_kept_and_costs_throughput(tmp_path, capsys):
    free_file, capped_file = tmp_path / 'free.json', tmp_path / 'capped.json'
    assert run(capsys, *CASE, '--json', str(free_file))[0] == 0
    free = json.loads(free_file.read_text())
    cap_wh = 0.7 * free['propulsion_energy_j'] / 3600.0
    status, out, _ = run(capsys, *CASE, '--energy-budget-wh', f'{cap_wh:.6f}',
                         '--json', str(capped_file))
    assert status == 0 and f'(horizon budget {cap_wh:.2f} Wh)' in out
    capped = json.loads(capped_file.read_text())
    assert recomputed_energy_j(capped)[0] <= cap_wh * 3600.0 * (1 + 1e-6)
    assert capped['min_throughput'] < free['min_throughput']


def test_a_cap_no_flight_keeps_is_refused_in_one_line(capsys):
    # 51 legs of 4 s at Zeng's least power (126.0 W) need 7.14 Wh.
    status, out, err = run(capsys, *CASE, '--energy-budget-wh', '7.0')
    assert status == 2 and out == ''
    assert err.count('\n') == 1 and 'below what any flight of this horizon needs: 7.14 Wh' in err


def test_a_battery_that_cannot_fly_is_refused_with_the_energy_needed_and_available(capsys):
    status, out, err = run(capsys, *CASE, '--battery-wh', '12')
    assert status == 2 and out == '' and err.count('\n') == 1
    assert 'the battery cannot fly this mission: it needs at least 12.76 Wh' in err
    assert '9.6 Wh are available (12 Wh less the 20% reserve)' in err
    assert 'a larger battery (--battery-wh' in err


def test_the_battery_s_allowance_caps_the_horizon(tmp_path, capsys):
    result = tmp_path / 'r.json'
    # 20 Wh less the 20 % reserve, takeoff (1.87 Wh) and landing (3.74 Wh) leave 10.38 Wh for
    # the horizon, below the free plan's 13.5 Wh.
    status, out, _ = run(capsys, *CASE, '--battery-wh', '20', '--json', str(result))
    assert status == 0 and 'battery: 20.00 Wh, 16.00 Wh available' in out
    data = json.loads(result.read_text())
    allowance = 16.0 - (data['takeoff_energy_j'] + data['landing_energy_j']) / 3600.0
    assert data['scenario']['energy_budget_wh'] == pytest.approx(allowance, rel=1e-12)
    assert data['propulsion_energy_j'] <= allowance * 3600.0 * (1 + 1e-6)
    assert data['mission_energy_j'] <= 16.0 * 3600.0 * (1 + 1e-6)
    assert 'flies it with' in out


def test_the_least_energy_plan_meets_the_target_below_the_optimal_plan_s_energy(tmp_path,
                                                                                capsys):
    free_file, least_file = tmp_path / 'free.json', tmp_path / 'least.json'
    assert run(capsys, *CASE, '--json', str(free_file))[0] == 0
    free = json.loads(free_file.read_text())
    target = 0.995 * free['min_throughput']
    status, _, _ = run(capsys, *CASE, '--min-throughput', f'{target:.6f}',
                       '--json', str(least_file))
    assert status == 0
    least = json.loads(least_file.read_text())
    assert min(least['rates']) >= target * (1 - 1e-12)
    assert least['propulsion_energy_j'] < free['propulsion_energy_j']
    assert least['min_throughput_target'] == pytest.approx(target)
    status, _, err = run(capsys, *CASE, '--min-throughput', '1000')
    assert status == 2 and 'no plan found reaches 1000 bit/s' in err


@pytest.mark.parametrize('flag', ['--battery-wh', '--energy-budget-wh', '--min-throughput'])
def test_energy_options_need_an_airframe(capsys, flag):
    status, _, err = run(capsys, 'plan', '--case', 'I', flag, '10')
    assert status == 2 and 'needs --airframe' in err


def test_an_unknown_airframe_is_refused_with_the_names(capsys, tmp_path):
    status, _, err = run(capsys, *CASE[:-1], 'no-such-frame')
    assert status == 2 and "unknown airframe 'no-such-frame'" in err and 'zeng2019' in err
    bad = tmp_path / 'bad.yaml'
    bad.write_text('name: x\nblade_profile_power_w: 80\n')
    status, _, err = run(capsys, *CASE[:-1], str(bad))
    assert status == 2 and 'missing' in err and err.count('\n') == 1


def test_the_energy_sweep_buys_throughput_with_energy(tmp_path, capsys):
    table, figure = tmp_path / 'sweep.json', tmp_path / 'sweep.svg'
    status, out, _ = run(capsys, 'energy-sweep', '--case', 'I', '--speed', '30', '--horizon',
                         '200', '--airframe', 'zeng2019', '--budgets-wh', '7.0,8.0,10.0,14.0',
                         '--json', str(table), '--figure', str(figure))
    assert status == 0 and 'no plan' in out       # 7 Wh: below the least energy, 7.14 Wh
    rows = json.loads(table.read_text())['rows']
    assert rows[0]['min_throughput'] is None
    planned = rows[1:]
    for row in planned:
        assert row['energy_wh'] <= row['budget_wh'] * (1 + 1e-6)
    assert planned[0]['min_throughput'] < planned[1]['min_throughput'] \
        < planned[2]['min_throughput']
    assert '<svg' in figure.read_text()
    status, _, err = run(capsys, 'energy-sweep', '--case', 'I', '--budgets-wh', '8')
    assert status == 2 and 'needs --airframe' in err
