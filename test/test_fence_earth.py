"""Fences on the real Earth: a zone beyond the planning frame's reach (tens of kilometres, the
antipode) refused, never folded into the frame; a fence written back exactly as it was read;
the margin kept from a fence edge as the autopilot draws it (straight in latitude and
longitude), not from its chord in the planning frame."""

from __future__ import annotations

import json
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from uav_comm_planner import paper_scenario, SolverSettings
from uav_comm_planner.errors import FenceFileError
from uav_comm_planner.mission.pipeline import plan_mission
from uav_comm_planner.mission.request import MissionRequest
from uav_comm_planner.vehicle import fence as fence_module
from uav_comm_planner.vehicle.fence import MAX_FENCE_DISTANCE_M, read_fence, read_zones
from uav_comm_planner.vehicle.geodesy import (enu_to_geodetic, geodetic_to_enu,
                                              geodetic_to_plane, Home)
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink.items import NAV_WAYPOINT, Q0_SEQ

CLI = [sys.executable, '-m', 'uav_comm_planner.tools.cli']
ZURICH = Home(47.397742, 8.545594, 488.0)
#: ArduPilot's metres per degree (LATLON_TO_M, per 1e-7 degree), the scale of the frame
#: ``get_vector_xy_from_origin_NE`` puts fence vertices in.
ARDUPILOT_M_PER_DEG = 0.011131884502145034 * 1e7


def plan_fence_file(path: Path, polygons=(), circles=()) -> Path:
    path.write_text(json.dumps({'fileType': 'Plan', 'version': 1, 'geoFence': {
        'version': 2,
        'polygons': [{'inclusion': inclusion, 'version': 1, 'polygon': vertices}
                     for inclusion, vertices in polygons],
        'circles': [{'inclusion': inclusion, 'version': 1,
                     'circle': {'center': center, 'radius': radius}}
                    for inclusion, center, radius in circles]}}))
    return path


def run(*arguments: str) -> subprocess.CompletedProcess:
    return subprocess.run(CLI + list(arguments), capture_output=True, text=True, timeout=300)


ANTIPODE_BOX = [[-47.78, -171.46], [-47.78, -171.45], [-47.77, -171.45], [-47.77, -171.46]]


def test_a_zone_at_the_antipode_is_refused_not_folded_into_the_frame(tmp_path):
    path = plan_fence_file(tmp_path / 'fence.plan', [(False, ANTIPODE_BOX)])
    with pytest.raises(FenceFileError, match=r'fence polygon 1: the point \(-47\.7\d*, '
                                             r'-171\.4\d*\) reaches 127\d\d km from home.*'
                                             r'farther than the planning frame holds \(50 km\)'):
        read_zones(path, ZURICH)
    # What the frame would have made of it: a box a kilometre from home, on the other side.
    east, north, _ = geodetic_to_enu(np.array(ANTIPODE_BOX)[:, 0], np.array(ANTIPODE_BOX)[:, 1],
                                     ZURICH.altitude_m, ZURICH)
    assert np.hypot(east, north).max() < 2000.0


def test_the_antipode_on_the_command_line_is_one_line_and_exit_2(tmp_path):
    path = plan_fence_file(tmp_path / 'fence.plan', [(False, ANTIPODE_BOX)])
    mission = tmp_path / 'mission.plan'
    done = run('plan', '--case', 'I', '--home=47.397742,8.545594,488', '--fence', str(path),
               '--mission', str(mission))
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('uav-comm-planner: error: fence file'), \
        done.stderr
    assert 'farther than the planning frame holds (50 km)' in lines[0]
    assert not mission.exists()


def box_at(north_m: float, side_m: float = 100.0) -> list[list[float]]:
    """A keep-out box ``north_m`` north of Zurich's home (degrees)."""
    latitude, longitude, _ = enu_to_geodetic(
        np.array([0.0, side_m, side_m, 0.0]), north_m + np.array([0.0, 0.0, side_m, side_m]),
        0.0, ZURICH)
    return [[float(a), float(b)] for a, b in zip(latitude, longitude)]


def test_the_bound_is_the_distance_on_the_ground_circles_with_their_radius(tmp_path):
    near = plan_fence_file(tmp_path / 'near.plan', [(False, box_at(MAX_FENCE_DISTANCE_M - 200))])
    assert len(read_zones(near, ZURICH).keep_out) == 1
    far = plan_fence_file(tmp_path / 'far.plan', [(False, box_at(MAX_FENCE_DISTANCE_M + 10))])
    with pytest.raises(FenceFileError, match=r'reaches 50\.1\d* km from home'):
        read_zones(far, ZURICH)
    center = box_at(MAX_FENCE_DISTANCE_M - 1000)[0]
    inside = plan_fence_file(tmp_path / 'c1.plan', circles=[(False, center, 900.0)])
    assert read_zones(inside, ZURICH).keep_out[0].radius_m == 900.0
    beyond = plan_fence_file(tmp_path / 'c2.plan', circles=[(False, center, 1100.0)])
    with pytest.raises(FenceFileError, match='fence circle 1: .* with its radius of 1100 m'):
        read_zones(beyond, ZURICH)


def test_a_far_place_maps_exactly_back_through_the_missions_conversion():
    latitude, longitude = np.array([47.55, 47.05, 47.75]), np.array([8.8, 8.5, 8.9])
    east, north, distance = geodetic_to_plane(latitude, longitude, ZURICH)
    back_latitude, back_longitude, _ = enu_to_geodetic(east, north, 0.0, ZURICH)
    np.testing.assert_allclose(back_latitude, latitude, atol=1e-11, rtol=0)
    np.testing.assert_allclose(back_longitude, longitude, atol=1e-11, rtol=0)
    assert 25e3 < distance[0] < 26e3
    # geodetic_to_enu at home's height drops the ground's fall below the plane (51 m here),
    # which moves the place sideways by that times d / R: 0.2 m at 25 km, 10 m at 95 km.
    old_east, old_north, _ = geodetic_to_enu(np.array([47.55]), np.array([8.8]),
                                             ZURICH.altitude_m, ZURICH)
    assert 0.15 < np.hypot(old_east - east[0], old_north - north[0])[0] < 0.3


#: A fence 30-45 km across, every vertex given to 12 decimals (more than a .plan's 8).
FIELD = [[47.121234567891, 8.281234567891], [47.121234567891, 8.901234567891],
         [47.681234567891, 8.901234567891], [47.681234567891, 8.281234567891]]
FAR_BLOCK = [[47.651111111111, 8.851111111111], [47.651111111111, 8.861111111111],
             [47.661111111111, 8.856111111111]]
FAR_DISC = ([47.15432109876, 8.31234567891], 250.5)


@pytest.mark.parametrize('geojson', [False, True])
def test_a_fence_is_written_back_exactly_as_it_was_read(tmp_path, geojson):
    if geojson:
        def ring(vertices):
            return [[[lon, lat] for lat, lon in vertices + vertices[:1]]]
        source = tmp_path / 'fence.geojson'
        source.write_text(json.dumps({'type': 'FeatureCollection', 'features': [
            {'type': 'Feature', 'properties': {'fence': 'inclusion'},
             'geometry': {'type': 'Polygon', 'coordinates': ring(FIELD)}},
            {'type': 'Feature', 'properties': {'fence': 'exclusion'},
             'geometry': {'type': 'Polygon', 'coordinates': ring(FAR_BLOCK)}},
            {'type': 'Feature', 'properties': {'fence': 'exclusion', 'radius_m': FAR_DISC[1]},
             'geometry': {'type': 'Point', 'coordinates': FAR_DISC[0][::-1]}}]}))
    else:
        # The inclusion polygon second: the file's order is kept too.
        source = plan_fence_file(tmp_path / 'fence.plan', [(False, FAR_BLOCK), (True, FIELD)],
                                 [(False, *FAR_DISC)])
    mission = tmp_path / 'mission.plan'
    done = run('plan', '--case', 'I', '--speed', '10', '--horizon', '400', '--slots', '40',
               '--home=47.397742,8.545594,488', '--fence', str(source), '--mission',
               str(mission))
    assert done.returncode == 0, done.stderr
    written, read = read_fence(mission), read_fence(source)
    assert written == read
    field = [p for p in written.polygons if p.inclusion][0]
    assert field.vertices_deg[0] == tuple(FIELD[0])   # all 12 decimals
    # And read again, the same zones in the planning frame.
    again = read_zones(mission, ZURICH)
    first = read_zones(source, ZURICH)
    assert again == first


#: A field 22.8 km east to west with its north edge on the parallel 47.05 (home at 47.0, 8.5):
#: the parallel bends 11 m off the chord between the field's corners in the planning frame.
FIELD_HOME = Home(47.0, 8.5, 500.0)
NORTH_EDGE_DEG = 47.05
LARGE_FIELD = [[46.99, 8.35], [46.99, 8.65], [NORTH_EDGE_DEG, 8.65], [NORTH_EDGE_DEG, 8.35]]


def north_clearance_as_ardupilot_draws_it(points_m: np.ndarray) -> np.ndarray:
    """Each point's distance south of the field's north edge in ArduPilot's fence frame (north
    metres = latitude difference times its LATLON_TO_M): the edge is the parallel there."""
    latitude, _, _ = enu_to_geodetic(points_m[:, 0], points_m[:, 1], 0.0, FIELD_HOME)
    return (NORTH_EDGE_DEG - latitude) * ARDUPILOT_M_PER_DEG


def plan_against_the_north_edge(tmp_path: Path):
    path = plan_fence_file(tmp_path / 'field.plan', [(True, LARGE_FIELD)])
    zones = read_zones(path, FIELD_HOME, margin_m=5.0)
    # Nodes north of the field: the plan presses against the middle of the north edge.
    scenario = paper_scenario('I', ground_nodes_m=((-600.0, 6200.0), (0.0, 6400.0),
                                                   (600.0, 6200.0)),
                              start_m=(-1500.0, 5000.0), goal_m=(1500.0, 5000.0),
                              max_speed_mps=10.0, horizon_s=400.0, num_slots=40)
    return zones, plan_mission(MissionRequest(scenario, SolverSettings(compute_baselines=False),
                                              VehicleLimits(), home=FIELD_HOME, zones=zones))


def test_the_margin_is_kept_from_the_edge_the_autopilot_draws(tmp_path):
    zones, planned = plan_against_the_north_edge(tmp_path)
    trajectory = np.asarray(planned.result.trajectory)
    clearance = north_clearance_as_ardupilot_draws_it(trajectory)
    # The plan reaches the margin (the test is about the edge), and keeps it there: each cut
    # piece's chord is within a millimetre of the edge, the solver's cushion is a millimetre
    # (a cut tolerance of 1 cm left points 6 mm inside the margin).
    assert clearance.min() < 6.0
    assert clearance.min() >= 5.0 - 1e-4
    rows = [item for item in planned.items[Q0_SEQ:] if item.command == NAV_WAYPOINT]
    latitudes = np.array([item.x for item in rows])
    # To the mission's 1e-8 degree (1.1 mm).
    assert ((NORTH_EDGE_DEG - latitudes) * ARDUPILOT_M_PER_DEG).min() >= 5.0 - 0.0006
    # The field's long edges were cut into 115 pieces each, at points on their parallels; its
    # short ones (meridians, straight in the frame) not.
    vertices = zones.area.vertices_m
    assert len(vertices) == 4 + 2 * 114
    latitude, _, _ = enu_to_geodetic(vertices[:, 0], vertices[:, 1], 0.0, FIELD_HOME)
    on_parallel = np.minimum(abs(latitude - 46.99), abs(latitude - NORTH_EDGE_DEG))
    assert on_parallel.max() < 1e-10


def test_without_the_cut_edges_the_plan_would_cross_the_margin(tmp_path, monkeypatch):
    """The check above can fail: with each edge its chord, the plan passes 5.9 m beyond the
    edge the autopilot draws, while keeping 5 m from the chord."""
    monkeypatch.setattr(fence_module, 'EDGE_CHORD_TOLERANCE_M', 1e9)
    zones, planned = plan_against_the_north_edge(tmp_path)
    trajectory = np.asarray(planned.result.trajectory)
    assert zones.clearance(trajectory).min() > 4.999
    assert north_clearance_as_ardupilot_draws_it(trajectory).min() < -5.0


def test_an_edge_needing_more_vertices_than_a_zone_holds_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(fence_module, 'EDGE_CHORD_TOLERANCE_M', 1e-6)
    path = plan_fence_file(tmp_path / 'field.plan', [(True, LARGE_FIELD)])
    with pytest.raises(FenceFileError, match='need more than 1000 vertices'):
        read_zones(path, FIELD_HOME)


def raw_degrees_inside(polygon: list, point: tuple[float, float]) -> bool:
    """W. R. Franklin's PNPOLY on raw (latitude, longitude), as ArduPilot's Polygon_outside
    and PX4's Geofence::insidePolygon test a position."""
    inside = False
    for (x1, y1), (x2, y2) in zip(polygon, polygon[-1:] + polygon[:-1]):
        if (y1 > point[1]) != (y2 > point[1]) and \
                point[0] < (x2 - x1) * (point[1] - y1) / (y2 - y1) + x1:
            inside = not inside
    return inside


def test_an_edge_across_the_antimeridian_is_refused_as_the_autopilots_draw_it_the_long_way(
        tmp_path):
    """ArduPilot's Polygon_outside (raw 1e-7 degree integers) and PX4's insidePolygon (raw
    degrees) join 179.98 and -179.97 through longitude 0: the inclusion field below is, to
    the autopilot, every longitude but the strip the plan flies in."""
    home = Home(0.0, 179.99, 0.0)
    across = [[-0.02, 179.98], [-0.02, -179.97], [0.02, -179.97], [0.02, 179.98]]
    path = plan_fence_file(tmp_path / 'across.plan', [(True, across)])
    with pytest.raises(FenceFileError, match=r'fence polygon 1: its edge from vertex 1 to '
                                             r'vertex 2 crosses the antimeridian \(longitude '
                                             r'179\.98 to -179\.97\)'):
        read_zones(path, home)
    # What the autopilots enforce (PNPOLY on raw latitude, longitude): home is outside.
    assert not raw_degrees_inside(across, (home.latitude_deg, home.longitude_deg))
    assert raw_degrees_inside(across, (0.0, 0.0))      # and the far side of the Earth inside
    beside = [[-0.02, 179.95], [-0.02, 179.999], [0.02, 179.999], [0.02, 179.95]]
    zones = read_zones(plan_fence_file(tmp_path / 'beside.plan', [(True, beside)]), home)
    assert zones.area is not None


def test_a_vertex_given_twice_in_a_row_is_refused_with_its_place(tmp_path):
    """Its edge has no length: it was refused as "crosses itself: edges 2 and 7 meet" (the
    numbering of the cut pieces), or would be written back without it if dropped."""
    triangle = [[47.40, 8.56], [47.40, 8.56], [47.41, 8.57], [47.40, 8.57]]
    path = plan_fence_file(tmp_path / 'twice.plan', [(False, triangle)])
    with pytest.raises(FenceFileError, match=r'polygons\[0\].polygon: vertices 0 and 1 are the '
                                             r'same place \(47.4, 8.56\): remove one'):
        read_zones(path, ZURICH)
    # The closing repeat of a ring is no repeat.
    closed = plan_fence_file(tmp_path / 'closed.plan', [(False, triangle[1:] + triangle[1:2])])
    assert len(read_zones(closed, ZURICH).keep_out) == 1


def test_a_polygon_that_crosses_itself_names_the_files_edges_not_their_cut_pieces(tmp_path):
    """A bow tie of 10 km edges: each edge is cut into pieces to follow it as the autopilot
    draws it, and the refusal names the edges as the file numbers them (it named pieces
    45 and 136)."""
    bow_tie = [[47.39, 8.54], [47.48, 8.67], [47.39, 8.67], [47.48, 8.54]]
    vertices, edge = fence_module._edges_as_drawn('polygon 1', tuple(map(tuple, bow_tie)),
                                                  ZURICH)
    assert len(vertices) > 20 and np.array_equal(np.unique(edge), np.arange(4))
    path = plan_fence_file(tmp_path / 'bow_tie.plan', [(False, bow_tie)])
    with pytest.raises(FenceFileError, match=r'fence polygon 1: a keep-out polygon crosses '
                                             r'itself: edges 1 and 3 meet \(edge k from '
                                             r'vertex k to the next\)'):
        read_zones(path, ZURICH)
    shifted = bow_tie[1:] + bow_tie[:1]          # the same crossing, edges numbered one less
    path = plan_fence_file(tmp_path / 'shifted.plan', [(True, shifted)])
    with pytest.raises(FenceFileError, match=r'the operating area crosses itself: edges 2 and '
                                             r'4 meet'):
        read_zones(path, ZURICH)
    completed = run('plan', '--case', 'I', '--home=47.397742,8.545594,488', '--fence',
                    str(path))
    assert completed.returncode == 2, completed.stderr
    assert completed.stderr.count('\n') == 1 and 'edges 2 and 4 meet' in completed.stderr
