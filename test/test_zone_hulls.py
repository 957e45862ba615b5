"""Zones wrapped by their hulls in the paths round them: a non-convex zone with nothing else
near its hull has only its hull's corners in the visibility graph, the paths round it are
those of the graph of every pair of those corners tested zone by zone, never longer than
the paths through every corner of the zone, and a path from inside the hull (a pocket) is
found with the zone's own corners."""

from __future__ import annotations

import math

import numpy as np
from test_detour_scaling import compare_paths, old_shortest_length, star

from uav_comm_planner.core.detour import (corner_graph, GRAPH_CLEARANCE_M, graph_corners,
                                          GRAPHS, shortest_path)
from uav_comm_planner.core.zone_hulls import isolation_m, wrapped_hulls, zones_holding
from uav_comm_planner.core.zones import KeepOutCircle, KeepOutPolygon, OperatingArea, Zones

U_SHAPE = np.array([(0, 0), (300, 0), (300, 300), (200, 300), (200, 100), (100, 100),
                    (100, 300), (0, 300)], dtype=float) + (850.0, -150.0)


def lone_zones(seed: int) -> Zones:
    """Two to four stars of 3 to 12 points, far enough apart to be wrapped, and a box."""
    rng = np.random.default_rng(seed)
    count = int(rng.integers(2, 5))
    centres = [(250.0 + 1500.0 * k / max(count - 1, 1), rng.uniform(-300.0, 300.0))
               for k in range(count)]
    zones = [star(int(rng.integers(3, 13)), centre, rng.uniform(120.0, 200.0),
                  rng.uniform(30.0, 110.0)) for centre in centres]
    zones.append(KeepOutPolygon([(900, 700), (1000, 700), (1000, 760), (900, 760)]))
    return Zones(keep_out=tuple(zones), margin_m=float(rng.uniform(0.0, 20.0)))


def reach(zones: Zones) -> float:
    return zones.margin_m + GRAPH_CLEARANCE_M


def test_lone_stars_are_wrapped_and_their_paths_are_the_brute_force_graphs():
    compared = equal = wrapped = 0
    worst = 0.0
    for seed in range(16):
        zones = lone_zones(seed)
        wrapped += len(wrapped_hulls(zones, reach(zones)))
        more, same, excess = compare_paths(seed, zones)
        compared, equal, worst = compared + more, equal + same, max(worst, excess)
    print(f'{wrapped} zones wrapped; {compared} paths, {equal} of the brute-force length, '
          f'the others at most {worst:.2e} longer')
    assert wrapped >= 32 and compared > 100 and equal >= 0.97 * compared
    assert worst < 2e-5


def test_a_zone_near_the_hull_or_inside_it_keeps_the_zone_from_being_wrapped():
    u = KeepOutPolygon(U_SHAPE)
    alone = Zones(keep_out=(u, KeepOutCircle((500.0, 600.0), 50.0)), margin_m=5.0)
    assert list(wrapped_hulls(alone, reach(alone))) == [0]
    np.testing.assert_array_equal(wrapped_hulls(alone, reach(alone))[0],
                                  U_SHAPE[[0, 1, 2, 3, 6, 7]])
    in_pocket = Zones(keep_out=(u, KeepOutCircle((1000.0, 50.0), 10.0)), margin_m=5.0)
    near = isolation_m(alone, reach(alone))
    close = Zones(keep_out=(u, KeepOutCircle((1000.0, 150.0 + 10.0 + near - 0.5), 10.0)),
                  margin_m=5.0)
    apart = Zones(keep_out=(u, KeepOutCircle((1000.0, 150.0 + 10.0 + near + 0.5), 10.0)),
                  margin_m=5.0)
    area = OperatingArea([(-100, -1000), (2100, -1000), (2100, 1000), (-100, 1000)])
    tight = Zones(area, (u,), margin_m=5.0)
    cut = Zones(OperatingArea([(-100, -1000), (2100, -1000), (2100, 145), (-100, 145)]), (u,),
                margin_m=5.0)
    assert not wrapped_hulls(in_pocket, reach(in_pocket))
    assert not wrapped_hulls(close, reach(close))
    assert list(wrapped_hulls(apart, reach(apart))) == [0]
    assert list(wrapped_hulls(tight, reach(tight))) == [0]
    assert not wrapped_hulls(cut, reach(cut))


def test_a_path_out_of_a_pocket_uses_the_zones_own_corners():
    zones = Zones(keep_out=(KeepOutPolygon(U_SHAPE),), margin_m=5.0)
    pocket, outside = np.array([1000.0, 20.0]), np.array([1000.0, -400.0])
    assert zones_holding(zones, reach(zones), pocket[None]) == {0}
    assert zones_holding(zones, reach(zones), outside[None]) == frozenset()
    hull_only = graph_corners(zones)
    assert len(hull_only) < len(graph_corners(zones, frozenset({0})))
    path = shortest_path(zones, pocket, outside)
    length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
    expected = old_shortest_length(zones, pocket, outside)
    assert math.isclose(length, expected, rel_tol=1e-12)
    assert zones.path_clearance(path) >= zones.margin_m - 1e-9
    # Out of the pocket's mouth, round the U's arm: longer than the straight line.
    assert length > 400.0 + 2 * 150.0


def test_a_thousand_vertex_stars_graph_has_only_its_hulls_corners():
    zones = Zones(keep_out=(star(500, (1000.0, 0.0), 150.0, 100.0),), margin_m=5.0)
    GRAPHS.clear()
    corners, lengths = corner_graph(zones)
    # One corner round each of the 500 outer vertices (the hull turns 0.7 degrees at each).
    assert len(corners) == 500
    assert np.count_nonzero(lengths) < 5 * len(corners)
    path = shortest_path(zones, np.array([700.0, 0.0]), np.array([1300.0, 0.0]))
    assert zones.path_clearance(path) >= zones.margin_m - 1e-9
    # Round a near circle of radius 155: about half its perimeter and the two lines to it.
    length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
    print(f'{length:.2f} m round the star')
    assert 2 * math.sqrt(300 ** 2 - 155 ** 2) + 155 * 1.0 < length < 2 * 145 + math.pi * 156
