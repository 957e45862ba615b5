"""A fence through the planning pipeline and the command line: ``plan --fence`` puts the file's
zones in the request, the .plan mission carries them as its geoFence, the figure draws them,
a mission whose legs would enter a zone is never built, and every bad fence is one line and
exit 2."""

from __future__ import annotations

import json
from pathlib import Path
import re
import subprocess
import sys

import numpy as np
import pytest
from test_fence import same_polygon

from uav_comm_planner import paper_scenario, plan, SolverSettings
from uav_comm_planner.core.zones import KeepOutCircle, KeepOutPolygon, OperatingArea, Zones
from uav_comm_planner.errors import PlannerError
from uav_comm_planner.mission.pipeline import plan_mission
from uav_comm_planner.mission.request import MissionRequest
from uav_comm_planner.vehicle.fence import (DRAWN_CIRCLE_SIDES, fence_from_zones, read_zones,
                                            zone_outlines)
from uav_comm_planner.vehicle.geodesy import DEFAULT_HOME, geodetic_to_enu, Home
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink.fence import fence_items, mission_clearance
from uav_comm_planner.vehicle.mavlink.files import read_plan
from uav_comm_planner.vehicle.mavlink.items import NAV_LAND, NAV_WAYPOINT, Q0_SEQ

CLI = [sys.executable, '-m', 'uav_comm_planner.tools.cli']
HOME = Home(*DEFAULT_HOME)
AREA = OperatingArea([(-200.0, -300.0), (2200.0, -300.0), (2200.0, 800.0), (-200.0, 800.0)])
#: Away from case I's plan (its nodes are at y = 400 and beyond): every plan keeps out.
ASIDE = KeepOutPolygon([(900.0, -250.0), (1100.0, -250.0), (1000.0, -150.0)])
#: Across case I's straight line.
ACROSS = KeepOutCircle((1000.0, 0.0), 100.0)
SCENARIO = dict(max_speed_mps=10.0, horizon_s=400.0, num_slots=40)


def fence_file(folder: Path, zones: Zones, name: str = 'fence.plan') -> Path:
    path = folder / name
    path.write_text(json.dumps({'fileType': 'Plan', 'version': 1,
                                'geoFence': fence_from_zones(zones, HOME).plan_section()}))
    return path


def run(*arguments: str) -> subprocess.CompletedProcess:
    return subprocess.run(CLI + list(arguments), capture_output=True, text=True, timeout=300)


def test_plan_fence_writes_the_zones_into_the_plan_mission_and_the_figure(tmp_path):
    zones = Zones(AREA, (ASIDE,), margin_m=10.0)
    mission, figure = tmp_path / 'mission.plan', tmp_path / 'plan.svg'
    done = run('plan', '--case', 'I', '--speed', '10', '--horizon', '400', '--slots', '40',
               '--fence', str(fence_file(tmp_path, zones)), '--fence-margin', '10',
               '--mission', str(mission), '--figure', str(figure))
    assert done.returncode == 0, done.stderr
    back = read_zones(mission, HOME)
    same_polygon(back.area.vertices_m, AREA.vertices_m, 1e-3)
    same_polygon(back.keep_out[0].vertices_m, ASIDE.vertices_m, 1e-3)
    assert mission_clearance(read_plan(mission), HOME, zones) >= 0
    svg = figure.read_text()
    assert 'operating area' in svg and 'keep-out zone' in svg


@pytest.mark.parametrize('content, match', [
    ('{"geoFence": {"version": 2, "polygons": [{"inclusion": false}]}}',
     r"fence.plan': geoFence.polygons\[0\]: has no \"polygon\""),
    ('not json', 'is not valid JSON'),
])
def test_a_bad_fence_is_one_line_and_exit_2_before_planning(tmp_path, content, match):
    path = tmp_path / 'fence.plan'
    path.write_text(content)
    mission = tmp_path / 'mission.plan'
    done = run('plan', '--case', 'I', '--fence', str(path), '--mission', str(mission))
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('uav-comm-planner: error:'), done.stderr
    assert re.search(match, lines[0]), lines[0]
    assert not mission.exists()


def test_a_goal_inside_a_fence_zone_is_one_line_and_exit_2(tmp_path):
    zones = Zones(keep_out=(KeepOutCircle((2000.0, 0.0), 50.0),))
    done = run('plan', '--case', 'I', '--fence', str(fence_file(tmp_path, zones)))
    assert done.returncode == 2
    assert len(done.stderr.strip().splitlines()) == 1
    assert 'goal_m' in done.stderr and 'keep-out zone' in done.stderr


def test_the_fence_margin_must_be_a_distance(tmp_path):
    done = run('plan', '--case', 'I', '--fence', str(fence_file(tmp_path, Zones(AREA))),
               '--fence-margin', '-1')
    assert done.returncode == 2 and 'margin must be >= 0' in done.stderr


def ignoring_zones(scenario, settings=None, **options):
    """A planner that plans as if there were no zones: what the pipeline's last check must
    catch."""
    return plan(scenario.replace(zones=None), settings, **options)


def test_a_mission_whose_legs_enter_a_zone_is_never_built(tmp_path):
    # A wall 20 m thick across the whole field: every path from q0 to qF crosses it.
    wall = KeepOutPolygon([(990.0, -5000.0), (1010.0, -5000.0), (1010.0, 5000.0),
                           (990.0, 5000.0)])
    request = MissionRequest(paper_scenario('I', **SCENARIO),
                             SolverSettings(compute_baselines=False), VehicleLimits(),
                             zones=Zones(keep_out=(wall,)))
    planned = plan_mission(request, planner=ignoring_zones)
    assert planned.items is None
    assert "the mission's legs enter the zones" in planned.items_error
    assert 'least clearance is -10.00 m' in planned.items_error  # half the wall, at its middle
    with pytest.raises(PlannerError, match='legs enter the zones'):
        planned.write(tmp_path / 'mission.plan')
    assert not (tmp_path / 'mission.plan').exists()


def test_mission_clearance_is_the_exact_clearance_of_the_flown_polyline():
    request = MissionRequest(paper_scenario('I', **SCENARIO),
                             SolverSettings(compute_baselines=False), VehicleLimits())
    planned = plan_mission(request)
    zones = Zones(keep_out=(KeepOutCircle((1000.0, -200.0), 50.0),))
    # Independently: the waypoints' polyline sampled densely, each sample's distance to the
    # circle's centre, less the radius.
    rows = [i for i in planned.items[Q0_SEQ:] if i.command in (NAV_WAYPOINT, NAV_LAND)]
    east, north, _ = geodetic_to_enu(np.array([r.x for r in rows]),
                                     np.array([r.y for r in rows]), HOME.altitude_m, HOME)
    points = np.column_stack([east, north])
    t = np.linspace(0, 1, 2001)[:, None]
    dense = np.concatenate([a + t * (b - a) for a, b in zip(points[:-1], points[1:])])
    expected = np.linalg.norm(dense - [1000.0, -200.0], axis=1).min() - 50.0
    assert abs(mission_clearance(planned.items, HOME, zones) - expected) < 0.01


def test_zone_outlines_are_closed_rings_of_each_zone():
    outlines = zone_outlines(Zones(AREA, (ASIDE, ACROSS)))
    assert [kind for kind, _ in outlines] == ['area', 'keep_out', 'keep_out']
    for _, ring in outlines:
        np.testing.assert_array_equal(ring[0], ring[-1])
    circle = outlines[2][1]
    assert len(circle) == DRAWN_CIRCLE_SIDES + 1
    np.testing.assert_allclose(np.linalg.norm(circle - [1000.0, 0.0], axis=1), 100.0)


def test_the_documented_example_fence_is_the_flight_tests_field_and_wall():
    from test_fence_flight import AREA as FLIGHT_AREA, HOME as SITL_HOME, WALL
    example = Path(__file__).resolve().parents[1] / 'docs' / 'fence_example.geojson'
    zones = read_zones(example, SITL_HOME)
    same_polygon(zones.area.vertices_m, FLIGHT_AREA.vertices_m, 1e-3)
    same_polygon(zones.keep_out[0].vertices_m, WALL.vertices_m, 1e-3)


def test_a_planned_mission_carries_its_zones_fence_items():
    zones = Zones(AREA, (ASIDE,))
    request = MissionRequest(paper_scenario('I', **SCENARIO),
                             SolverSettings(compute_baselines=False), VehicleLimits(),
                             zones=zones)
    planned = plan_mission(request)
    assert planned.items is not None
    assert planned.fence == tuple(fence_items(fence_from_zones(zones, HOME)))
    assert plan_mission(MissionRequest(paper_scenario('I', **SCENARIO),
                                       SolverSettings(compute_baselines=False))).fence is None
