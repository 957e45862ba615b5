"""Fence files: QGroundControl .plan geoFence and GeoJSON read into zones, checked against an
independent local-tangent-plane conversion; the .plan export read back; MAVLink fence items;
every bad file refused with the file and the place named."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from uav_comm_planner import paper_scenario, plan, SolverSettings
from uav_comm_planner.core.zones import KeepOutCircle, KeepOutPolygon, OperatingArea, Zones
from uav_comm_planner.errors import FenceFileError, MissionExportError
from uav_comm_planner.vehicle.fence import (CIRCLE_SIDES, fence_from_zones, GeoFence,
                                            read_checked_fence, read_fence, read_zones)
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.mavlink.fence import fence_from_items, fence_items
from uav_comm_planner.vehicle.mavlink.files import export_mission
from uav_comm_planner.vehicle.mavlink.items import mismatches

HOME = Home(-35.363262, 149.165237, 584.0)
WGS84_A = 6378137.0
WGS84_E2 = 6.69437999014e-3


def _ecef(latitude: float, longitude: float, height: float) -> np.ndarray:
    phi, lam = math.radians(latitude), math.radians(longitude)
    n = WGS84_A / math.sqrt(1 - WGS84_E2 * math.sin(phi) ** 2)
    return np.array([(n + height) * math.cos(phi) * math.cos(lam),
                     (n + height) * math.cos(phi) * math.sin(lam),
                     (n * (1 - WGS84_E2) + height) * math.sin(phi)])


def enu_metres(latitude: float, longitude: float, home: Home = HOME) -> tuple[float, float]:
    """East, north metres of a point at home's height, by WGS84 ECEF and the local rotation:
    an independent check of the package's ENU conversion."""
    phi, lam = math.radians(home.latitude_deg), math.radians(home.longitude_deg)
    d = _ecef(latitude, longitude, home.altitude_m) - _ecef(home.latitude_deg,
                                                            home.longitude_deg, home.altitude_m)
    east = -math.sin(lam) * d[0] + math.cos(lam) * d[1]
    north = (-math.sin(phi) * math.cos(lam) * d[0] - math.sin(phi) * math.sin(lam) * d[1]
             + math.cos(phi) * d[2])
    return east, north


def degrees_at(east_m: float, north_m: float, home: Home = HOME) -> list[float]:
    """The point at ``east_m``, ``north_m`` by :func:`enu_metres`, found by Newton steps on the
    local radii of curvature: the fence files' degrees."""
    phi = math.radians(home.latitude_deg)
    w = math.sqrt(1 - WGS84_E2 * math.sin(phi) ** 2)
    east_per_deg = math.radians(WGS84_A / w * math.cos(phi))
    north_per_deg = math.radians(WGS84_A * (1 - WGS84_E2) / w ** 3)
    latitude, longitude = home.latitude_deg, home.longitude_deg
    for _ in range(20):
        east, north = enu_metres(latitude, longitude, home)
        latitude += (north_m - north) / north_per_deg
        longitude += (east_m - east) / east_per_deg
    return [latitude, longitude]


AREA_M = [(-200.0, -300.0), (2200.0, -300.0), (2200.0, 700.0), (-200.0, 700.0)]
BLOCK_M = [(900.0, -100.0), (1100.0, -100.0), (1100.0, 100.0), (900.0, 100.0)]
DISC_M = ((400.0, 400.0), 80.0)


def plan_file(folder: Path, geo_fence: dict) -> Path:
    path = folder / 'fence.plan'
    path.write_text(json.dumps({'fileType': 'Plan', 'version': 1, 'geoFence': geo_fence,
                                'mission': {'items': [], 'version': 2}}))
    return path


def the_plan_fence() -> dict:
    return {'version': 2,
            'polygons': [{'inclusion': True, 'version': 1,
                          'polygon': [degrees_at(*p) for p in AREA_M]},
                         {'inclusion': False, 'version': 1,
                          'polygon': [degrees_at(*p) for p in BLOCK_M]}],
            'circles': [{'inclusion': False, 'version': 1,
                         'circle': {'center': degrees_at(*DISC_M[0]), 'radius': DISC_M[1]}}]}


def the_geojson(closed: bool = True) -> dict:
    def ring(points):
        lon_lat = [degrees_at(*p)[::-1] for p in points]
        return [lon_lat + lon_lat[:1]] if closed else [lon_lat]
    return {'type': 'FeatureCollection', 'features': [
        {'type': 'Feature', 'properties': {'fence': 'inclusion'},
         'geometry': {'type': 'Polygon', 'coordinates': ring(AREA_M)}},
        {'type': 'Feature', 'properties': {'fence': 'exclusion', 'name': 'block'},
         'geometry': {'type': 'Polygon', 'coordinates': ring(BLOCK_M)}},
        {'type': 'Feature', 'properties': {'fence': 'exclusion', 'radius_m': DISC_M[1]},
         'geometry': {'type': 'Point', 'coordinates': degrees_at(*DISC_M[0])[::-1]}}]}


def same_polygon(vertices: np.ndarray, expected, tolerance_m: float) -> None:
    """``vertices`` hold ``expected`` (in either orientation, from any vertex) to the
    tolerance, and any others lie on its edges within the bend of an edge straight in latitude
    and longitude (the cut points :func:`read_zones` puts on a long edge; 8 cm at 2.4 km)."""
    matched = [min(range(len(vertices)), key=lambda i: math.dist(vertices[i], p))
               for p in expected]
    for index, vertex in zip(matched, expected):
        assert math.dist(vertices[index], vertex) < tolerance_m, vertex
    steps = np.diff(sorted(matched) + [sorted(matched)[0] + len(vertices)])
    assert len(set(matched)) == len(expected) and (steps > 0).all()
    assert np.abs(KeepOutPolygon(expected).clearance(vertices)).max() < 0.2


def check_zones(zones: Zones, tolerance_m: float = 0.001) -> None:
    assert isinstance(zones.area, OperatingArea)
    same_polygon(zones.area.vertices_m, AREA_M, tolerance_m)
    block, disc = zones.keep_out
    assert isinstance(block, KeepOutPolygon) and isinstance(disc, KeepOutCircle)
    same_polygon(block.vertices_m, BLOCK_M, tolerance_m)
    np.testing.assert_allclose(disc.center_m, DISC_M[0], atol=tolerance_m)
    assert disc.radius_m == DISC_M[1]


def test_a_plan_geofence_becomes_the_zones_in_metres(tmp_path):
    zones = read_zones(plan_file(tmp_path, the_plan_fence()), HOME, margin_m=7.0)
    check_zones(zones)
    assert zones.margin_m == 7.0


@pytest.mark.parametrize('closed', [True, False])
def test_a_geojson_fence_gives_the_same_zones(tmp_path, closed):
    path = tmp_path / 'fence.geojson'
    path.write_text(json.dumps(the_geojson(closed)))
    check_zones(read_zones(path, HOME))
    assert read_fence(path) == read_fence(plan_file(tmp_path, the_plan_fence()))


def test_an_inclusion_circle_is_the_polygon_inscribed_in_it(tmp_path):
    centre, radius = (1000.0, 200.0), 1500.0
    path = plan_file(tmp_path, {'version': 2, 'polygons': [], 'circles': [
        {'inclusion': True, 'circle': {'center': degrees_at(*centre), 'radius': radius}}]})
    area = read_zones(path, HOME).area
    assert len(area.vertices_m) == CIRCLE_SIDES
    distances = np.linalg.norm(area.vertices_m - np.array(centre), axis=1)
    np.testing.assert_allclose(distances, radius, atol=0.05)
    # Every point inside the polygon is inside the circle; the polygon covers almost all of it.
    rng = np.random.default_rng(3)
    points = np.array(centre) + rng.uniform(-radius, radius, (20000, 2))
    inside = area.clearance(points) > 0
    assert (np.linalg.norm(points[inside] - centre, axis=1) <= radius + 0.05).all()
    covered = inside.sum() / (np.linalg.norm(points - centre, axis=1) < radius).sum()
    assert covered > 0.99


@pytest.fixture(scope='module')
def result():
    return plan(paper_scenario('I', max_speed_mps=10.0, horizon_s=400.0, num_slots=40),
                SolverSettings(compute_baselines=False))


def test_zones_written_to_a_plan_read_back_the_same(tmp_path, result):
    zones = Zones(OperatingArea(AREA_M), (KeepOutPolygon(BLOCK_M), KeepOutCircle(*DISC_M)))
    path = export_mission(result, tmp_path / 'mission.plan', HOME, zones=zones)
    section = json.loads(path.read_text())['geoFence']
    assert [p['inclusion'] for p in section['polygons']] == [True, False]
    assert [c['inclusion'] for c in section['circles']] == [False]
    back = read_zones(path, HOME)
    check_zones(back, 0.002)
    # A plan without zones keeps the empty geoFence QGroundControl expects.
    plain = export_mission(result, tmp_path / 'plain.plan', HOME)
    assert json.loads(plain.read_text())['geoFence'] == {'circles': [], 'polygons': [],
                                                         'version': 2}


def test_zones_that_leave_the_globe_are_an_export_error(tmp_path, result):
    zones = Zones(keep_out=(KeepOutCircle((0.0, 9e6), 10.0),))
    target = tmp_path / 'mission.plan'
    with pytest.raises(MissionExportError, match='farther than a fence goes'):
        export_mission(result, target, HOME, zones=zones)
    assert not target.exists()


def test_fence_items_carry_the_vertex_count_and_radius_and_read_back(tmp_path):
    fence = read_fence(plan_file(tmp_path, the_plan_fence()))
    items = fence_items(fence)
    assert [item.command for item in items] == [5001] * 4 + [5002] * 4 + [5004]
    assert [item.params[0] for item in items] == [4.0] * 8 + [DISC_M[1]]
    assert (items[0].x, items[0].y) == tuple(fence.polygons[0].vertices_deg[0])
    assert fence_from_items(items) == fence
    assert mismatches(items, items, home_row=False) == []
    moved = list(items)
    moved[5] = type(items[5])(**{**items[5].__dict__, 'x': items[5].x + 1e-6})
    wrong = mismatches(items, moved, home_row=False)
    assert len(wrong) == 1 and wrong[0].startswith('item 5:')


def test_zones_to_a_fence_and_back_are_the_same_to_a_millimetre():
    zones = Zones(OperatingArea(AREA_M), (KeepOutCircle(*DISC_M),))
    back = fence_from_zones(zones, HOME).zones(HOME)
    same_polygon(back.area.vertices_m, AREA_M, 1e-3)
    np.testing.assert_allclose(back.keep_out[0].center_m, DISC_M[0], atol=1e-3)


def bad(fence: dict) -> dict:
    return {'version': 2, 'polygons': [], 'circles': [], **fence}


POLYGON = [degrees_at(*p) for p in BLOCK_M]
BAD_PLAN_FENCES = [
    (bad({'version': 1}), r'geoFence.version: is 1'),
    (bad({'polygons': {}}), r'geoFence.polygons: must be a list'),
    (bad({'polygons': [{'polygon': POLYGON}]}), r'geoFence.polygons\[0\]: has no "inclusion"'),
    (bad({'polygons': [{'inclusion': 'yes', 'polygon': POLYGON}]}),
     r'polygons\[0\].inclusion: must be true or false'),
    (bad({'polygons': [{'inclusion': False, 'polygon': POLYGON[:2]}]}),
     r'polygons\[0\].polygon: has 2 distinct vertices'),
    (bad({'polygons': [{'inclusion': False, 'polygon': [*POLYGON[:2], [95.0, 149.0]]}]}),
     r'polygons\[0\].polygon\[2\]: latitude 95.0 is not in'),
    (bad({'polygons': [{'inclusion': False, 'polygon': [*POLYGON[:2], ['a', 1]]}]}),
     r'polygons\[0\].polygon\[2\]: must be \[latitude, longitude\]'),
    (bad({'polygons': [{'inclusion': False,
                        'polygon': [POLYGON[0], POLYGON[2], POLYGON[1], POLYGON[3]]}]}),
     r'fence polygon 1: a keep-out polygon crosses itself'),
    (bad({'circles': [{'inclusion': False, 'circle': {'center': POLYGON[0], 'radius': 0}}]}),
     r'circles\[0\].circle.radius: must be a positive number of metres, got 0'),
    (bad({'circles': [{'inclusion': False, 'circle': {'radius': 5}}]}),
     r'circles\[0\].circle: has no "center"'),
    (bad({'polygons': [{'inclusion': True, 'polygon': POLYGON}],
          'circles': [{'inclusion': True, 'circle': {'center': POLYGON[0], 'radius': 50}}]}),
     r'2 inclusion zones; the planner takes one operating area'),
    (bad({}), r'holds no fence zone'),
]


@pytest.mark.parametrize('fence, match', BAD_PLAN_FENCES)
def test_a_bad_plan_fence_names_the_file_and_the_place(tmp_path, fence, match):
    path = plan_file(tmp_path, fence)
    with pytest.raises(FenceFileError, match=match) as caught:
        read_zones(path, HOME)
    assert str(path) in str(caught.value)
    with pytest.raises(FenceFileError, match=match):
        read_checked_fence(path)


def geojson_with(feature: dict) -> dict:
    return {'type': 'FeatureCollection', 'features': [feature]}


RING = [[*reversed(p)] for p in POLYGON]
BAD_GEOJSON = [
    ({'type': 'Feature'}, r'is not a GeoJSON FeatureCollection'),
    (geojson_with({'properties': {}, 'geometry': {}}),
     r'features\[0\].properties: has no "fence"'),
    (geojson_with({'properties': {'fence': 'keep out'},
                   'geometry': {'type': 'Polygon', 'coordinates': [RING]}}),
     r'properties.fence: must be "inclusion" or "exclusion", got "keep out"'),
    (geojson_with({'properties': {'fence': 'exclusion'},
                   'geometry': {'type': 'Polygon', 'coordinates': [RING, RING]}}),
     r'coordinates: must hold exactly one ring'),
    (geojson_with({'properties': {'fence': 'exclusion'},
                   'geometry': {'type': 'LineString', 'coordinates': RING}}),
     r'geometry.type: is "LineString"'),
    (geojson_with({'properties': {'fence': 'exclusion'},
                   'geometry': {'type': 'Point', 'coordinates': RING[0]}}),
     r'properties: has no "radius_m"'),
    (geojson_with({'properties': {'fence': 'exclusion'},
                   'geometry': {'type': 'Polygon', 'coordinates': [[[200.0, 0.0], *RING]]}}),
     r'coordinates\[0\]\[0\]: longitude 200.0 is not in'),
    # Integers beyond a double: refused like any bad number, not an OverflowError.
    (geojson_with({'properties': {'fence': 'exclusion', 'radius_m': 10 ** 400},
                   'geometry': {'type': 'Point', 'coordinates': RING[0]}}),
     r'radius_m: must be a positive number of metres'),
    (geojson_with({'properties': {'fence': 'exclusion', 'radius_m': 20},
                   'geometry': {'type': 'Point', 'coordinates': [10 ** 400, 47.0]}}),
     r'coordinates: .* is out of range for degrees'),
]


@pytest.mark.parametrize('document, match', BAD_GEOJSON)
def test_a_bad_geojson_fence_names_the_file_and_the_place(tmp_path, document, match):
    path = tmp_path / 'fence.geojson'
    path.write_text(json.dumps(document))
    with pytest.raises(FenceFileError, match=match) as caught:
        read_zones(path, HOME)
    assert str(path) in str(caught.value)


def test_unreadable_fence_files_are_fence_file_errors(tmp_path):
    with pytest.raises(FenceFileError, match='unknown fence format'):
        read_fence(tmp_path / 'fence.kml')
    with pytest.raises(FenceFileError, match='no such fence file'):
        read_fence(tmp_path / 'missing.plan')
    broken = tmp_path / 'broken.geojson'
    broken.write_text('{"type": ')
    with pytest.raises(FenceFileError, match='not valid JSON'):
        read_fence(broken)
    folder = tmp_path / 'folder.plan'
    folder.mkdir()
    with pytest.raises(FenceFileError, match='not a regular file'):
        read_fence(folder)


def test_a_plan_without_a_geofence_holds_an_empty_fence(tmp_path):
    path = tmp_path / 'm.plan'
    path.write_text(json.dumps({'mission': {}}))
    assert read_fence(path) == GeoFence()
