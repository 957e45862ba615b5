"""The zones' geometry against brute force: clearances of points and segments measured by
sampling the boundaries densely, and the validation of bad polygons."""

from __future__ import annotations

import numpy as np
import pytest

from uav_comm_planner.core.zones import (KeepOutCircle, KeepOutPolygon, OperatingArea,
                                         Zones)
from uav_comm_planner.errors import InvalidScenarioError


def boundary_samples(vertices: np.ndarray, per_edge: int = 1000) -> np.ndarray:
    t = np.linspace(0.0, 1.0, per_edge, endpoint=False)[:, None]
    return np.concatenate([a + t * (b - a) for a, b in
                           zip(vertices, np.roll(vertices, -1, axis=0))])


def brute_inside(point: np.ndarray, vertices: np.ndarray) -> bool:
    """Inside by the winding angle: the angles subtended by the edges sum to 2 pi inside."""
    angles = np.arctan2(*(vertices - point).T[::-1])
    turns = np.diff(np.append(angles, angles[0]))
    turns = (turns + np.pi) % (2 * np.pi) - np.pi
    return abs(turns.sum()) > np.pi


@pytest.mark.parametrize('seed', range(6))
def test_point_and_segment_clearance_of_a_random_convex_polygon_match_brute_force(seed):
    rng = np.random.default_rng(seed)
    angles = np.sort(rng.uniform(0, 2 * np.pi, 7))
    vertices = np.c_[np.cos(angles), np.sin(angles)] * rng.uniform(20, 60) + rng.uniform(-9, 9, 2)
    zone = KeepOutPolygon(vertices)
    samples = boundary_samples(zone.vertices_m)
    points = rng.uniform(-90, 90, (40, 2))
    for point, clearance in zip(points, zone.clearance(points)):
        distance = np.linalg.norm(samples - point, axis=1).min()
        expected = -distance if brute_inside(point, zone.vertices_m) else distance
        assert clearance == pytest.approx(expected, abs=0.05)
    for _ in range(12):
        a, b = rng.uniform(-90, 90, (2, 2))
        along = a + np.linspace(0, 1, 301)[:, None] * (b - a)
        distances = np.array([np.linalg.norm(samples - p, axis=1).min() for p in along])
        inside = np.array([brute_inside(p, zone.vertices_m) for p in along])
        worst = float(np.where(inside, -distances, distances).min())
        got = zone.segment_clearance(a, b)
        if worst > 0:
            assert got == pytest.approx(worst, abs=0.1)
        else:
            assert got <= 0.0 and got == pytest.approx(min(worst, 0.0), abs=0.5)


def test_a_segment_through_a_circle_has_negative_clearance_and_one_beside_it_its_distance():
    circle = KeepOutCircle((0.0, 0.0), 10.0)
    assert circle.segment_clearance((-20, 4), (20, 4)) == pytest.approx(-6.0)
    assert circle.segment_clearance((-20, 15), (20, 15)) == pytest.approx(5.0)
    assert circle.segment_clearance((20, 0), (30, 0)) == pytest.approx(10.0)


def test_the_operating_area_counts_inside_as_clear_and_leaving_it_as_negative():
    area = OperatingArea([[-100, -100], [100, -100], [100, 100], [-100, 100]])
    assert area.clearance([[0, 0], [150, 0]]).tolist() == [100.0, -50.0]
    assert area.segment_clearance((0, 0), (50, 0)) == pytest.approx(50.0)
    assert area.segment_clearance((0, 0), (150, 0)) == pytest.approx(-50.0)


def test_zones_report_the_least_clearance_of_a_path_over_its_legs_not_only_its_points():
    square = KeepOutPolygon([[0, 0], [10, 0], [10, 10], [0, 10]])
    zones = Zones(keep_out=(square,), margin_m=2.0)
    path = np.array([[-5.0, 5.0], [15.0, 5.0]])   # both points clear, the leg is not
    assert zones.clearance(path).min() == pytest.approx(5.0)
    assert zones.path_clearance(path) == pytest.approx(-5.0)


@pytest.mark.parametrize('vertices, message', [
    ([[0, 0], [10, 10], [10, 0], [0, 10]], 'crosses itself'),
    ([[0, 0], [1, 1], [2, 2]], 'no area'),
    ([[0, 0], [1, 1]], '3 to'),
    ([[0, 0], [1, np.nan], [2, 0]], 'not finite'),
])
def test_bad_polygons_are_refused_with_the_reason(vertices, message):
    with pytest.raises(InvalidScenarioError, match=message):
        KeepOutPolygon(vertices)


def test_bad_circles_and_margins_are_refused():
    with pytest.raises(InvalidScenarioError, match='radius'):
        KeepOutCircle((0, 0), 0.0)
    with pytest.raises(InvalidScenarioError, match='margin'):
        Zones(margin_m=-1.0)
    with pytest.raises(InvalidScenarioError, match='KeepOutCircle or KeepOutPolygon'):
        Zones(keep_out=((0, 0),))


@pytest.mark.parametrize('data, message', [
    ({'keep_out': [{'center_m': [0, 0], 'radius_m': True}]}, 'radius must be a number'),
    ({'keep_out': [{'center_m': [0, 0], 'radius_m': 10 ** 400}]}, 'radius must be a finite'),
    ({'keep_out': [{'center_m': [0, 0, 1], 'radius_m': 5}]}, r'centre must be a finite \(x, y\)'),
    ({'keep_out': [{'center_m': [10 ** 400, 0], 'radius_m': 5}]}, 'centre must be a finite'),
    ({'margin_m': 10 ** 400}, 'margin must be a finite number'),
    ({'margin_m': False}, 'margin must be a number'),
    # NumPy would read True as 1.0 and parse '12': a vertex or a centre is a number.
    ({'keep_out': [{'vertices_m': [[True, 0], [10, 0], [0, 10]]}]}, r'list of \(x, y\)'),
    ({'keep_out': [{'vertices_m': [['0', '0'], [10, 0], [0, 10]]}]}, r'list of \(x, y\)'),
    ({'area': [[0, 0], [100, 0], [0, False]]}, r'operating area must be a list of \(x, y\)'),
    ({'keep_out': [{'center_m': [True, 0], 'radius_m': 5}]}, 'centre must be a finite'),
    ({'keep_out': [{'center_m': ['12', 0], 'radius_m': 5}]}, 'centre must be a finite'),
])
def test_zones_from_a_file_refuse_bad_numbers_with_a_typed_error(data, message):
    with pytest.raises(InvalidScenarioError, match=message):
        Zones.from_dict(data)
