"""``uav-comm-planner plan --uavs K``: the fleet's JSON recomputed from its own arrays, one
mission per vehicle read back through pymavlink, the figure, and one-line errors."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from test_fence import degrees_at, plan_file

from uav_comm_planner.core.energy import horizon_energy_j, JOULES_PER_WH
from uav_comm_planner.core.fleet import FleetScenario
from uav_comm_planner.core.fleet.scenario import DEFAULT_SEPARATION_M
from uav_comm_planner.core.propulsion import ZENG2019
from uav_comm_planner.core.scenario import paper_scenario
from uav_comm_planner.tools import cli
from uav_comm_planner.vehicle.fence import read_zones
from uav_comm_planner.vehicle.geodesy import default_home, geodetic_to_enu
from uav_comm_planner.vehicle.mavlink.files import read_waypoints
from uav_comm_planner.vehicle.mavlink.items import NAV_LAND, NAV_WAYPOINT

CHECKOUT = Path(__file__).resolve().parents[1]
FLEET = ('--uavs', '2', '--start', '0,0;0,500', '--goal', '2000,0;2000,500',
         '--min-separation', '100')


def run(capsys, *argv):
    status = cli.main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def test_the_fleet_json_states_what_its_arrays_give(tmp_path, capsys):
    result_file, figure = tmp_path / 'r.json', tmp_path / 'f.svg'
    status, out, _ = run(capsys, 'plan', *FLEET, '--json', str(result_file),
                         '--figure', str(figure))
    assert status == 0 and 'fleet (joint power and trajectories)' in out
    data = json.loads(result_file.read_text())
    q, p = np.array(data['trajectories']), np.array(data['power'])
    assert q.shape == (2, 50, 2) and p.shape == (2, 3, 50)
    scenario = data['scenario']
    nodes = np.array(scenario['ground_nodes_m'])
    n = len(nodes)
    sigma2 = 10 ** ((scenario['noise_psd_dbm_per_hz'] - 30) / 10)
    scale = n * scenario['reference_gain'] / (scenario['bandwidth_hz'] * sigma2)
    d = ((q[:, None, :, :] - nodes[None, :, None, :]) ** 2).sum(axis=-1) + 100.0 ** 2
    rates = scenario['bandwidth_hz'] / n * np.log2(1 + p * scale / d).mean(axis=2).sum(axis=0)
    assert np.allclose(data['rates'], rates, rtol=1e-12)
    assert data['min_throughput'] == pytest.approx(rates.min(), rel=1e-12)
    assert np.linalg.norm(q[0] - q[1], axis=1).min() >= 100.0
    assert data['closest_approach_m'] >= 100.0
    assert np.all(p >= 0) and np.all(p.sum(axis=(1, 2)) <= scenario['power_budget_w'])
    for k, (start, goal) in enumerate(zip(data['starts_m'], data['goals_m'])):
        legs = np.diff(np.vstack([start, q[k], goal]), axis=0)
        assert np.linalg.norm(legs, axis=1).max() <= scenario['max_speed_mps']
    assert data['min_throughput'] >= max(data['single_uav_throughputs'].values())
    assert '<svg' in figure.read_text()[:400]
    assert figure.read_text().count('UAV 1') >= 1 and 'UAV 2' in figure.read_text()


def test_one_mission_per_vehicle_each_ending_at_its_own_goal(tmp_path, capsys):
    mission, result_file = tmp_path / 'm.waypoints', tmp_path / 'r.json'
    status, out, err = run(capsys, 'plan', '--uavs', '2', '--start', '0,0;0,300',
                           '--goal', '600,0;600,300', '--min-separation', '50',
                           '--nodes', '100,100;500,200', '--speed', '8', '--horizon', '200',
                           '--slots', '40', '--mission', str(mission), '--json',
                           str(result_file))
    assert status == 0, err
    assert not mission.exists()
    # Planned at d_min = 50 m, the missions as ArduCopter times them came within 46.9 m: the
    # plan kept more at its slots, so that the missions keep 50 m.
    (line,) = [line for line in out.splitlines() if line.startswith('missions as ardupilot')]
    closest = float(line.split('closest approach ')[1].split()[0])
    data = json.loads(result_file.read_text())
    assert closest >= 50.0 == data['min_separation_m']
    assert data['planned_separation_m'] > 50.0
    q = np.array(data['trajectories'])
    assert np.linalg.norm(q[0] - q[1], axis=1).min() >= data['planned_separation_m']
    home = default_home('ardupilot')
    for k, goal in enumerate(((600.0, 0.0), (600.0, 300.0)), start=1):
        items = read_waypoints(tmp_path / f'm_uav{k}.waypoints')
        assert f'wrote {tmp_path / f"m_uav{k}.waypoints"}' in out
        assert items[-1].command == NAV_LAND
        last = [item for item in items if item.command == NAV_WAYPOINT][-1]
        east, north, _ = geodetic_to_enu(np.array(last.x), np.array(last.y), 0.0, home)
        assert math.dist((float(east), float(north)), goal) < 0.5


@pytest.mark.parametrize('argv, message', [
    (('--uavs', '2', '--start', '0,0', '--goal', '2000,0;2000,500'), '2 points in --start'),
    (('--uavs', '2', '--goal', '2000,0;2000,500'), '2 points in --start'),
    (('--uavs', '0', '--start', '0,0', '--goal', '2000,0'), '1 to 8 UAVs'),
    (('--uavs', 'two',), 'whole number'),
    (('--min-separation', '100',), 'needs --uavs'),
    (('--start', '0,0;0,500',), 'several need --uavs'),
    (FLEET[:-1] + ('600',), 'less than the separation'),
    (FLEET + ('--min-throughput', '5'), '--min-throughput is for one UAV'),
    (FLEET + ('--energy-budget-wh', '5'), '--energy-budget-wh needs --airframe'),
    (FLEET + ('--fence', 'missing.geojson'), 'missing.geojson'),
    (('--uavs', '2', '--start', '0,0;0,50', '--goal', '2000,0;2000,500'),
     'less than the separation 100 m (the default d_min): move them apart or give a smaller '
     '--min-separation'),
    (FLEET + ('--letter',), '--letter is for one UAV'),
    (FLEET[:-1] + ('nan',), 'min_separation_m'),
    (('--uavs', '2', '--start', '0,0;0,x', '--goal', '1,1;2,2'), 'comma-separated numbers'),
    (FLEET + ('--mission', 'm.txt'), 'unknown mission format'),
])
def test_bad_fleet_input_is_one_line_and_status_2(tmp_path, capsys, argv, message):
    result_file = tmp_path / 'r.json'
    status, out, err = run(capsys, 'plan', *argv, '--json', str(result_file))
    assert status == 2
    assert err.count('\n') == 1 and err.startswith('uav-comm-planner: error: ')
    assert message in err
    assert not result_file.exists()


def test_the_default_separation_keeps_the_uavs_100_m_apart(tmp_path, capsys):
    """Without --min-separation the fleet keeps d_min = 100 m (Wu 2018's); the same fleet
    planned with d_min = 0 lets the two UAVs meet over a node, so the default is what keeps
    them apart. The help states it."""
    closest = {}
    for name, extra in (('default', ()), ('zero', ('--min-separation', '0'))):
        result_file = tmp_path / f'{name}.json'
        status, _, err = run(capsys, 'plan', *FLEET[:-2], *extra, '--json', str(result_file))
        assert status == 0, err
        data = json.loads(result_file.read_text())
        q = np.array(data['trajectories'])
        closest[name] = float(np.linalg.norm(q[0] - q[1], axis=1).min())
        assert data['closest_approach_m'] == pytest.approx(closest[name], abs=1e-9)
        assert data['min_separation_m'] == (100.0 if name == 'default' else 0.0)
    print('closest approach (m):', closest)
    assert closest['default'] >= 100.0 and closest['zero'] < 1.0
    with pytest.raises(SystemExit):
        cli.main(['plan', '--help'])
    help_text = ' '.join(capsys.readouterr().out.split())
    assert "default 100, Wu 2018's d_min" in help_text
    assert FleetScenario(paper_scenario('I'), ((0, 0), (0, 500)),
                         ((2000, 0), (2000, 500))).min_separation_m == DEFAULT_SEPARATION_M


def test_a_mission_the_vehicle_cannot_fly_writes_nothing(tmp_path, capsys):
    """At the letter's 100 m/s, faster than ArduCopter's default cruise (10 m/s): refused
    before the first file (the JSON included)."""
    result_file, mission = tmp_path / 'r.json', tmp_path / 'm.waypoints'
    status, _, err = run(capsys, 'plan', *FLEET, '--json', str(result_file),
                         '--mission', str(mission))
    assert status == 2 and 'the vehicle cannot fly this plan on time' in err
    assert list(tmp_path.iterdir()) == []


def test_missions_that_the_autopilot_would_fly_too_close_are_refused(tmp_path, capsys):
    """Ends exactly d_min apart: no plan with more separation exists, and the missions as
    ArduCopter times them come within 36 m: refused, nothing written."""
    mission = tmp_path / 'm.waypoints'
    status, _, err = run(capsys, 'plan', '--uavs', '2', '--start', '0,0;0,50',
                         '--goal', '600,0;600,50', '--min-separation', '50',
                         '--nodes', '100,100;500,-50', '--speed', '8', '--horizon', '200',
                         '--slots', '40', '--mission', str(mission),
                         '--json', str(tmp_path / 'r.json'))
    assert status == 2 and 'below d_min = 50 m' in err and 'fly the plan streamed' in err
    assert list(tmp_path.iterdir()) == []


SHARED = ('--uavs', '2', '--start', '0,800;0,1200', '--goal', '2000,800;2000,1200',
          '--min-separation', '100', '--nodes', '300,500;1000,1500;1700,600', '--speed', '50',
          '--horizon', '60', '--slots', '30', '--noise-dbm', '-110', '--beta0', '1e-6',
          '--budget', '3', '--shared-band')


def test_the_shared_band_json_states_what_its_arrays_give(tmp_path, capsys):
    """B x (1/M) sum_m sum_k alpha log2(1 + SINR), SINR written out from the JSON's arrays."""
    result_file = tmp_path / 's.json'
    status, out, err = run(capsys, 'plan', *SHARED, '--json', str(result_file),
                           '--figure', str(tmp_path / 's.png'))
    assert status == 0, err
    data = json.loads(result_file.read_text())
    q, p, alpha = (np.array(data[key]) for key in ('trajectories', 'power', 'schedule'))
    assert q.shape == (2, 30, 2) and p.shape == (2, 30) and alpha.shape == (2, 3, 30)
    s = data['scenario']
    nodes = np.array(s['ground_nodes_m'])
    noise = s['bandwidth_hz'] * 10 ** ((s['noise_psd_dbm_per_hz'] - 30) / 10)
    d = ((q[:, None] - nodes[None, :, None]) ** 2).sum(axis=-1) + s['altitude_m'] ** 2
    received = p[:, None, :] * s['reference_gain'] / (noise * d)
    sinr = received / (1 + received.sum(axis=0) - received)
    rates = s['bandwidth_hz'] * (alpha * np.log2(1 + sinr)).sum(axis=0).mean(axis=1)
    assert np.allclose(data['rates'], rates, rtol=1e-10)
    assert data['min_throughput'] == pytest.approx(rates.min(), rel=1e-10)
    assert alpha.sum(axis=1).max() <= 1 + 1e-6 and alpha.sum(axis=0).max() <= 1 + 1e-6
    assert p.min() >= 0 and p.sum(axis=1).max() <= 3.0 * (1 + 1e-9)
    assert np.linalg.norm(q[0] - q[1], axis=1).min() >= 100.0
    (with_control,) = [float(line.split()[-1]) for line in out.splitlines()
                       if line.startswith('shared band, power control')]
    (without,) = [float(line.split()[-1]) for line in out.splitlines()
                  if line.startswith('shared band, no power control')]
    assert with_control == round(data['min_throughput'], 4) and with_control >= without
    assert data['power_control'] and (tmp_path / 's.png').read_bytes()[:4] == b'\x89PNG'


@pytest.mark.parametrize('argv, message', [
    (('--shared-band',), '--shared-band needs --uavs'),
    (FLEET + ('--no-power-control',), '--no-power-control is for --shared-band'),
    (SHARED + ('--mission', 'm.waypoints'), 'missions are not exported yet'),
    (SHARED + ('--airframe', 'zeng2019', '--energy-budget-wh', '50', '--horizon', '100'),
     'shared band is planned without zones or an energy budget'),
])
def test_bad_shared_band_input_is_one_line(tmp_path, capsys, argv, message):
    status, _, err = run(capsys, 'plan', *argv, '--json', str(tmp_path / 'r.json'))
    assert status == 2 and err.count('\n') == 1 and message in err
    assert list(tmp_path.iterdir()) == []


def test_a_fleet_keeps_out_of_the_fence_file_and_within_each_budget(tmp_path, capsys):
    """A keep-out disc (a .plan fence, anchored at the default home) over the middle node, and
    an energy budget per UAV: the JSON's trajectories held against the disc written here and
    their horizon energy recomputed from the JSON's arrays."""
    home = default_home('ardupilot')
    centre, radius = (1000.0, 250.0), 150.0
    fence = plan_file(tmp_path, {'version': 2, 'polygons': [], 'circles': [
        {'inclusion': False, 'version': 1,
         'circle': {'center': degrees_at(*centre, home=home), 'radius': radius}}]})
    result_file = tmp_path / 'r.json'
    status, out, err = run(capsys, 'plan', *FLEET, '--horizon', '100', '--fence', str(fence),
                           '--airframe', 'zeng2019', '--energy-budget-wh', '8.5',
                           '--json', str(result_file), '--figure', str(tmp_path / 'f.svg'))
    assert status == 0, err
    data = json.loads(result_file.read_text())
    q = np.array(data['trajectories'])
    scenario = paper_scenario('I', horizon_s=100.0)
    for k, (start, goal) in enumerate(zip(data['starts_m'], data['goals_m'])):
        path = np.vstack([start, q[k], goal])
        # Every slot point and every leg at least the 5 m margin from the disc (by hand).
        along = np.linspace(0.0, 1.0, 50)[:, None, None]
        points = path[:-1][None] + along * np.diff(path, axis=0)[None]
        assert np.linalg.norm(points - centre, axis=-1).min() >= radius + 5.0 - 0.01
        vehicle = scenario.replace(start_m=tuple(start), goal_m=tuple(goal))
        energy_wh = horizon_energy_j(q[k], vehicle, ZENG2019) / JOULES_PER_WH
        assert energy_wh <= 8.5 and energy_wh == pytest.approx(data['energy_wh'][k], rel=1e-12)
        assert f'UAV {k + 1} horizon energy {energy_wh:.4g} Wh (budget 8.5 Wh)' in out
    assert data['zone_clearance_m'][0] >= 5.0 * (1 - 1e-9) and 'least clearance' in out
    assert data['min_throughput'] >= max(data['single_uav_throughputs'].values())
    drawn = (tmp_path / 'f.svg').read_text()
    assert 'keep-out zone' in drawn and '5 m margin' in drawn and 'UAV 2' in drawn


def test_each_vehicles_mission_keeps_out_of_the_fence(tmp_path, capsys):
    """The example fence's block between the nodes: every leg of each vehicle's mission, read
    back through pymavlink, keeps the 5 m margin (less the geodesy's centimetres)."""
    home = default_home('ardupilot')
    fence = CHECKOUT / 'docs' / 'fence_example.geojson'
    mission = tmp_path / 'm.waypoints'
    status, out, err = run(capsys, 'plan', '--uavs', '2', '--start', '0,300;0,550',
                           '--goal', '1000,300;1000,550', '--min-separation', '50',
                           '--nodes', '300,200;800,450', '--speed', '8', '--horizon', '250',
                           '--slots', '50', f'--home={home.latitude_deg},{home.longitude_deg},'
                           f'{home.altitude_m}', '--fence', str(fence), '--mission', str(mission))
    assert status == 0, err
    zones = read_zones(fence, home)
    for k in (1, 2):
        items = [item for item in read_waypoints(tmp_path / f'm_uav{k}.waypoints')
                 if item.command == NAV_WAYPOINT]
        east, north, _ = geodetic_to_enu(np.array([item.x for item in items]),
                                         np.array([item.y for item in items]), 0.0, home)
        points = np.column_stack([east, north])
        for zone in zones.keep_out:
            least = min(zone.segment_clearance(a, b) for a, b in zip(points[:-1], points[1:]))
            assert least >= zones.margin_m - 0.05, (k, least)
