"""Costs that scale with hostile sizes: a 1000-vertex keep-out zone's rows built from its convex
pieces grouped by size (not every triangle padded to the convex core's hundreds of
vertices), and the dual bound over a long horizon found without stepping through every slot
once its programme rises by the same amount everywhere. Each against the computation it
replaces, to the same numbers."""

from __future__ import annotations

import dataclasses
import math
import time

from helpers import build_no_polygon, keep_out_plan_file, run_fuzz_target
import numpy as np
import pytest

from uav_comm_planner import paper_scenario
from uav_comm_planner.core import bound
from uav_comm_planner.core.initial import straight_line
from uav_comm_planner.core.model import snr_per_watt
from uav_comm_planner.core.zone_rows import _polygon_half_planes, ZoneModel
from uav_comm_planner.core.zones import KeepOutPolygon, MAX_TOTAL_VERTICES, Zones
from uav_comm_planner.errors import FenceFileError
from uav_comm_planner.vehicle.fence import read_zones
from uav_comm_planner.vehicle.geodesy import Home


def star(vertices: int, centre=(1000.0, 0.0), outer: float = 150.0,
         inner: float = 100.0) -> KeepOutPolygon:
    """A star of ``vertices`` corners alternately ``outer`` and ``inner`` from ``centre``:
    half its corners reflex, so it splits into a convex core and a triangle per tooth."""
    k = np.arange(vertices)
    radius = np.where(k % 2 == 0, outer, inner)
    angle = 2 * math.pi * k / vertices
    return KeepOutPolygon(np.column_stack([centre[0] + radius * np.cos(angle),
                                           centre[1] + radius * np.sin(angle)]))


def path_past(points: int = 60) -> np.ndarray:
    x = np.linspace(0.0, 2000.0, points + 2)
    return np.column_stack([x, 250.0 * np.sin(x / 300.0)])


def test_a_stars_rows_are_each_pieces_own_half_planes_and_cost_little():
    model = ZoneModel.of(Zones(keep_out=(star(1000), star(40, centre=(400.0, -300.0)))))
    sizes = sorted(len(piece) for piece in model.polygons)
    assert sizes[-1] > 100 and sizes[0] <= 4      # a large core beside small teeth
    path = path_past()
    started = time.perf_counter()
    rows = model.rows(path)
    elapsed = time.perf_counter() - started
    # The reference: every piece on its own, unpadded.
    a, b = path[:-1], path[1:]
    wanted = model.margin_m + 1e-3
    for index in (0, len(model.polygons) // 2, len(model.polygons) - 1):
        n, support, separation = _polygon_half_planes(a, b, model.polygons[index][None])
        offset = support[0] + np.minimum(wanted, separation[0])
        k = 2 * index
        np.testing.assert_allclose(rows.normals[:, k], n[0, :-1], atol=1e-12)
        np.testing.assert_allclose(rows.normals[:, k + 1], n[0, 1:], atol=1e-12)
        np.testing.assert_allclose(rows.offsets[:, k], offset[:-1], atol=1e-9)
        np.testing.assert_allclose(rows.offsets[:, k + 1], offset[1:], atol=1e-9)
    assert rows.normals.shape == (len(path) - 2, model.rows_per_slot, 2)
    # Padding every piece to the core's size took 2.6 s here for 100 slots.
    assert elapsed < 0.5, elapsed


def full_programme(geometry, weights, nu, num_slots):
    """The dynamic programme stepped through every slot (the bound as it was computed)."""
    original = bound._uniform_rise
    bound._uniform_rise = lambda *args: None
    try:
        return bound.trajectory_bound(geometry, weights, nu, num_slots)
    finally:
        bound._uniform_rise = original


@pytest.mark.parametrize('slots', [50, 400, 3000])
@pytest.mark.parametrize('nu', [0.003, 0.1, 3.0])
def test_the_bound_over_a_long_horizon_is_the_full_programmes(slots, nu):
    scenario = dataclasses.replace(paper_scenario('II'), num_slots=slots,
                                   horizon_s=float(slots))
    geometry = bound._geometry(scenario)
    weights = np.array([0.5, 0.2, 0.3])
    fast = bound.trajectory_bound(geometry, weights, nu, slots)
    exact = full_programme(geometry, weights, nu, slots)
    assert fast == pytest.approx(exact, rel=1e-12, abs=1e-12)


def test_the_rise_is_none_until_every_reachable_state_rose_alike():
    cells = np.array([[0.0, -np.inf], [1.0, 2.0]])
    assert bound._uniform_rise(cells, -np.inf, cells + 0.5, -np.inf) == 0.5
    # A state reached for the first time: the rise of the others says nothing yet.
    reached = np.array([[0.5, 3.0], [1.5, 2.5]])
    assert bound._uniform_rise(cells, -np.inf, reached, -np.inf) is None
    uneven = cells + np.array([[0.5, 0.0], [0.5, 0.6]])
    assert bound._uniform_rise(cells, -np.inf, uneven, -np.inf) is None
    assert bound._uniform_rise(cells, 1.0, cells + 0.5, 1.2) is None


def test_the_bound_at_the_compute_budgets_edge_costs_a_second_or_two():
    """N = 1, M = 100 000 (N M at the default budget): stepped through every slot, each of
    the dozen evaluations of the golden-section search was 100 000 steps (over a minute)."""
    scenario = dataclasses.replace(paper_scenario('I'), ground_nodes_m=((1000.0, 300.0),),
                                   num_slots=100_000, horizon_s=100_000.0)
    p = np.full((1, scenario.num_slots), scenario.power_budget_w)
    a = snr_per_watt(straight_line(scenario), scenario)
    started = time.perf_counter()
    value = bound.dual_upper_bound(scenario, p, a)
    elapsed = time.perf_counter() - started
    assert math.isfinite(value) and value > 0
    assert elapsed < 10.0, elapsed


def test_a_fences_vertices_are_counted_before_any_polygon_is_built(tmp_path, monkeypatch):
    """A hundred 1000-vertex polygons took 4.8 s of checking, polygon by polygon, before the
    total was refused (the node reads its fence on its executor)."""
    home = Home(47.397742, 8.545594, 488.0)
    ring = [[47.39 + 0.001 * math.sin(2 * math.pi * k / 1000),
             8.54 + 0.001 * math.cos(2 * math.pi * k / 1000)] for k in range(1000)]
    polygons = [[[lat + 0.003 * i, lon] for lat, lon in ring]
                for i in range(MAX_TOTAL_VERTICES // 1000 + 1)]
    path = keep_out_plan_file(tmp_path / 'fence.plan', polygons)
    build_no_polygon(monkeypatch)
    with pytest.raises(FenceFileError, match=f'the fence has {len(polygons) * 1000} polygon '
                                             f'vertices in all, more than {MAX_TOTAL_VERTICES}'):
        read_zones(path, home)


def test_a_short_seeded_run_of_the_parameter_design_and_table_fuzzer_finds_nothing(capsys):
    import re

    status = run_fuzz_target('fuzz_inputs', ['--cases', '60', '--seed', '5'])
    out = capsys.readouterr().out
    assert status == 0, out
    assert '0 failures' in out
    for kind in ('parameters', 'design', 'table'):
        assert re.search(rf'{kind} +refused +\d+', out), out


def test_a_path_with_more_corners_than_slots_asks_for_slots_without_a_warning():
    """Four stars' path has 33 corners, each a slot point: 20 slots cannot fly it whatever the
    horizon (the advice was a horizon of 1.8e308 s, after an overflow warning)."""
    import warnings

    from devtools.zone_probes import zones_of

    from uav_comm_planner import plan
    from uav_comm_planner.errors import InfeasibleHorizonError

    scenario = dataclasses.replace(paper_scenario('I'), zones=zones_of('four-stars'),
                                   num_slots=20, horizon_s=40.0)
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        with pytest.raises(InfeasibleHorizonError) as refused:
            plan(scenario)
    message = str(refused.value)
    stretches = int(message.split('its ')[1].split(' stretches')[0])
    assert stretches > scenario.num_slots + 1
    assert f'need num_slots {stretches - 1} or more' in message
    assert 'horizon_s to' not in message and len(message) < 400
    # With the slots it asks for, that path is planned.
    enough = dataclasses.replace(scenario, num_slots=stretches - 1, horizon_s=600.0)
    assert math.isfinite(plan(enough).min_throughput)
