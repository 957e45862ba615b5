"""Plans inside the zones: the scenario's and the request's zones, the restrictions the
trajectory step adds, the starts around the zones, and every plan checked by the zones' exact
clearance (:meth:`~uav_comm_planner.core.zones.Zones.path_clearance`)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from uav_comm_planner.core.detour import (around_zones, GRAPH_CHUNK,
                                          GRAPH_CLEARANCE_M, graph_corners, GRAPHS, hover_start,
                                          outside_point, path_length, segments_clear,
                                          shortest_path)
from uav_comm_planner.core.sca.fast import trajectory_step_clarabel
from uav_comm_planner.core.feasibility import within_speed_limit
from uav_comm_planner.core.model import average_rates, flown_path, snr_per_watt
from uav_comm_planner.core.optimizer import optimal_power, plan
from uav_comm_planner.core.power import waterfilling_power
from uav_comm_planner.core.receding import CLEAR_START_MAX_M, FlownSlots, replan
from uav_comm_planner.core.scenario import paper_scenario, Scenario, SolverSettings
from uav_comm_planner.core.sca.reference import trajectory_step_cvxpy
from uav_comm_planner.core.zone_rows import _outward_edges, ZONE_CUSHION_M, zone_model
from uav_comm_planner.core.zones import KeepOutCircle, KeepOutPolygon, OperatingArea, Zones
from uav_comm_planner.errors import (InfeasibleHorizonError, InvalidScenarioError,
                                     PlanCancelledError, WalledInError)
from uav_comm_planner.mission.pipeline import plan_mission
from uav_comm_planner.mission.request import InFlight, MissionRequest
from uav_comm_planner.tools.serialize import scenario_from_dict, scenario_to_dict
from uav_comm_planner.vehicle.waypoints import simplify, zone_check

AREA = OperatingArea([(-100, -100), (2100, -100), (2100, 600), (-100, 600)])


def letter_zones(**changes) -> Zones:
    """The letter's area with a disc across case I's straight line and a triangle."""
    fields = dict(area=AREA, keep_out=(KeepOutCircle((1000.0, 0.0), 100.0),
                                       KeepOutPolygon([(500, -60), (620, -60), (560, 40)])))
    fields.update(changes)
    return Zones(**fields)


def test_start_and_goal_must_keep_the_margin_with_the_numbers():
    with pytest.raises(InfeasibleHorizonError, match=r'start_m .* inside .* -10.00 m.* 5 m'):
        paper_scenario('I', zones=Zones(keep_out=(KeepOutCircle((0, 0), 10),)))
    with pytest.raises(InfeasibleHorizonError, match=r'goal_m .* closer .* 2.00 m, .* 5 m'):
        paper_scenario('I', zones=Zones(keep_out=(KeepOutCircle((2000, 12), 10),)))
    with pytest.raises(InfeasibleHorizonError, match='outside the operating area'):
        paper_scenario('II', zones=Zones(area=OperatingArea([(-1, -1), (2001, -1), (2001, 1)])))
    with pytest.raises(InvalidScenarioError, match='zones must be a Zones'):
        paper_scenario('I', zones=[KeepOutCircle((0, 0), 10)])


def test_scenarios_with_equal_zones_compare_and_hash_equal_and_survive_json():
    scenario = paper_scenario('I', zones=letter_zones())
    again = paper_scenario('I', zones=Zones.from_dict(letter_zones().to_dict()))
    assert scenario == again and hash(scenario) == hash(again)
    assert scenario != paper_scenario('I')
    assert scenario_from_dict(json.loads(json.dumps(scenario_to_dict(scenario)))) == scenario
    assert scenario_from_dict(scenario_to_dict(paper_scenario('I'))).zones is None
    with pytest.raises(InvalidScenarioError, match='keep-out zone is'):
        Zones.from_dict({'keep_out': [{'center_m': [0, 0]}]})


def test_a_request_s_zones_replace_the_scenario_s():
    zones = letter_zones()
    request = MissionRequest(paper_scenario('I'), zones=zones)
    assert request.planned_scenario.zones == zones
    assert MissionRequest(paper_scenario('I')).planned_scenario == paper_scenario('I')
    with pytest.raises(InfeasibleHorizonError, match='start_m'):
        _ = MissionRequest(paper_scenario('I'), zones=Zones(
            keep_out=(KeepOutCircle((0, 0), 10),))).planned_scenario
    with pytest.raises(InvalidScenarioError, match='zones must be a Zones'):
        MissionRequest(paper_scenario('I'), zones='fence.plan')


# The restriction: rows that hold at the path they are built at and imply the zones.

def star(rng: np.random.Generator, centre, size: float, points: int, dent: float) -> np.ndarray:
    """A polygon round ``centre`` at sorted random angles, every other vertex pulled in by
    ``dent`` (0: convex, on a circle)."""
    angles = np.sort(rng.uniform(0.0, 2 * np.pi, points))
    radii = size * np.where(np.arange(points) % 2, 1.0 - dent, 1.0)
    return np.asarray(centre) + radii[:, None] * np.stack([np.cos(angles), np.sin(angles)], 1)


def random_zones(rng: np.random.Generator, side: float) -> Zones:
    """One to three keep-out zones (circles, convex and non-convex polygons) in the middle of
    the side x side square, inside an area a little larger than it, with a notch half the
    time, and a margin of 2 to 10 m."""
    keep_out = []
    for _ in range(int(rng.integers(1, 4))):
        kind = rng.choice(['circle', 'convex', 'star'])
        centre = rng.uniform(0.25 * side, 0.75 * side, 2)
        size = float(rng.uniform(0.05, 0.15)) * side
        if kind == 'circle':
            keep_out.append(KeepOutCircle(tuple(centre), size))
            continue
        while True:
            try:
                keep_out.append(KeepOutPolygon(star(
                    rng, centre, size, int(rng.integers(4, 9)),
                    0.0 if kind == 'convex' else float(rng.uniform(0.3, 0.6)))))
                break
            except InvalidScenarioError:       # angles too close: collinear or crossing
                continue
    a, s = 0.15 * side, side
    outline = [(-a, -a), (s + a, -a), (s + a, s + a), (-a, s + a)]
    if rng.uniform() < 0.5:                    # a notch down from the top edge
        outline[3:3] = [(0.6 * s, s + a), (0.5 * s, 0.8 * s), (0.4 * s, s + a)]
    return Zones(area=OperatingArea(outline), keep_out=tuple(keep_out),
                 margin_m=float(rng.uniform(2.0, 10.0)))


def random_zoned_scenario(seed: int) -> Scenario:
    """2 to 4 nodes in a 600-1500 m square flown corner to corner in 30 slots, with time for
    a path two and a half times the diagonal, and random zones clear of q0 and qF; odd seeds
    in a wind of up to 15 m/s."""
    rng = np.random.default_rng(seed)
    side = float(rng.uniform(600.0, 1500.0))
    slot_s = 2.5 * np.sqrt(2.0) * side / (31 * 50.0)
    wind = dict(wind_speed_mps=float(rng.uniform(0, 15)),
                wind_from_deg=float(rng.uniform(0, 360))) if seed % 2 else {}
    while True:
        try:
            return Scenario(ground_nodes_m=rng.uniform(0, side, (int(rng.integers(2, 5)), 2)),
                            start_m=(0.0, 0.0), goal_m=(side, side), num_slots=30,
                            horizon_s=30 * slot_s, max_speed_mps=50.0,
                            zones=random_zones(rng, side), **wind)
        except InfeasibleHorizonError:             # q0 or qF in a zone: draw again
            continue


def clearance_of(q: np.ndarray, scenario: Scenario) -> float:
    return scenario.zones.path_clearance(flown_path(q, scenario))


@pytest.mark.parametrize('seed', range(4))
def test_rows_hold_where_they_are_built_and_every_path_keeping_them_keeps_the_zones(seed):
    scenario = random_zoned_scenario(seed)
    zones, rng = scenario.zones, np.random.default_rng(100 + seed)
    model = zone_model(zones)
    path = flown_path(around_zones(scenario), scenario)
    assert zones.path_clearance(path) >= zones.margin_m
    for cushion in (0.0, ZONE_CUSHION_M):
        rows = model.rows(path, cushion_m=cushion)
        assert rows.normals.shape == (scenario.num_slots, model.rows_per_slot, 2)
        assert rows.slack(path[1:-1]).min() >= -1e-9
    # Random moves, each as far as the rows allow (up to its length): many end on a row's
    # boundary, where the restriction is tightest.
    x = path[1:-1]
    on_boundary = 0
    for _ in range(40):
        d = rng.normal(0.0, float(rng.choice([0.01, 0.1, 0.3])) * scenario.goal_m[0], x.shape)
        rate = np.einsum('mkj,mj->mk', rows.normals, d)
        slack = rows.slack(x)
        shrinking = rate < 0
        t = min(1.0, float(np.min(slack[shrinking] / -rate[shrinking], initial=np.inf)))
        on_boundary += t < 1.0
        q = x + t * d
        assert rows.slack(q).min() >= -1e-9
        assert clearance_of(q, scenario) >= zones.margin_m - 1e-9
    assert on_boundary >= 10


@pytest.mark.parametrize('seed', range(8))
def test_convex_pieces_and_pockets_give_the_polygons_distances(seed):
    rng = np.random.default_rng(seed)
    polygon = None
    while polygon is None:
        try:
            polygon = KeepOutPolygon(star(rng, (0, 0), 100.0, int(rng.integers(5, 12)), 0.5))
        except InvalidScenarioError:
            continue
    pieces = polygon.convex_pieces()
    assert all(KeepOutPolygon(piece).convex for piece in pieces)
    points = rng.uniform(-120, 120, (400, 2))
    outside = polygon.clearance(points)
    by_pieces = np.min([KeepOutPolygon(piece).clearance(points) for piece in pieces], axis=0)
    np.testing.assert_allclose(np.maximum(by_pieces, 0), np.maximum(outside, 0), atol=1e-9)
    assert ((by_pieces <= 0) == (outside <= 0)).all()
    # An area is its hull less its pockets: inside it, the clearance is the least of the
    # distance to the hull's edge lines and the distances to the pockets.
    area = OperatingArea(polygon.vertices_m)
    hull, pockets = area.hull_and_pockets()
    inside = points[area.clearance(points) > 0]
    normals, offsets = _outward_edges(hull)
    to_hull = (offsets[None] - inside @ normals.T).min(axis=1)
    to_pockets = np.min([KeepOutPolygon(p).clearance(inside) for p in pockets]
                        or [np.full(len(inside), np.inf)], axis=0)
    np.testing.assert_allclose(np.minimum(to_hull, to_pockets), area.clearance(inside),
                               atol=1e-9)


def test_the_fast_step_equals_the_cvxpy_step_with_zones():
    scenario = paper_scenario('I', zones=letter_zones())
    q = around_zones(scenario)
    for _ in range(3):
        p = waterfilling_power(snr_per_watt(q, scenario), scenario.power_budget_w).p
        reference = trajectory_step_cvxpy(q, p, scenario)
        fast = trajectory_step_clarabel(q, p, scenario)
        assert fast.bound == pytest.approx(reference.bound, rel=1e-6)
        np.testing.assert_allclose(fast.q, reference.q, atol=0.1)
        for step in (fast, reference):
            assert clearance_of(step.q, scenario) >= scenario.zones.margin_m
        q = fast.q


# Plans: every slot point and every leg out of every zone, the objective never lower.

def check_plan(result, scenario: Scenario) -> None:
    assert clearance_of(result.trajectory, scenario) >= scenario.zones.margin_m - 1e-6
    values = [step.min_throughput for step in result.history]
    assert all(b >= a for a, b in zip(values, values[1:]))
    assert within_speed_limit(result.trajectory, scenario)


@pytest.mark.parametrize('seed', range(6))
def test_random_plans_keep_every_zone_on_both_paths(seed):
    scenario = random_zoned_scenario(seed)
    fast = plan(scenario)
    check_plan(fast, scenario)
    reference = plan(scenario, power_method='conic', trajectory_method='cvxpy')
    check_plan(reference, scenario)
    assert fast.min_throughput == pytest.approx(reference.min_throughput, rel=1e-4)
    assert fast.min_throughput >= fast.baselines['straight'] * (1 - 1e-9)


# The letter's case I with a zone across its straight line, and a node inside it.

def letter_across(**changes) -> Scenario:
    """Case I with a disc across the straight line that also holds node 2 (1000, 200), and a
    non-convex polygon near node 1, inside the letter's area grown by 100 m."""
    zones = letter_zones(keep_out=(
        KeepOutCircle((1000.0, 100.0), 150.0),
        KeepOutPolygon([(300, 250), (420, 250), (420, 450), (380, 450), (380, 300),
                        (300, 300)])))
    return paper_scenario('I', zones=zones, **changes)


@pytest.fixture(scope='module')
def across():
    scenario = letter_across()
    return scenario, plan(scenario), plan(paper_scenario('I'))


def test_the_letter_s_case_with_a_zone_across_its_line_beats_both_baselines_outside_it(across):
    scenario, result, _ = across
    check_plan(result, scenario)
    straight, hover = around_zones(scenario), hover_start(scenario)
    for baseline in (straight, hover):
        assert clearance_of(baseline, scenario) >= scenario.zones.margin_m
        assert within_speed_limit(baseline, scenario)
    # The straight line crosses the disc; the baseline goes round it.
    assert scenario.zones.path_clearance([scenario.start_m, scenario.goal_m]) < 0
    rates = {name: float(average_rates(q, optimal_power(q, scenario), scenario).min())
             for name, q in (('straight', straight), ('hover', hover))}
    assert result.min_throughput > max(rates.values())
    assert result.baselines['straight'] == pytest.approx(rates['straight'], rel=1e-12)
    print(f'\ncase I with the zones: {result.min_throughput:.4f} bit/s; straight line round '
          f'them {rates["straight"]:.4f}, hover-and-fly outside them {rates["hover"]:.4f}')


def test_a_node_inside_a_zone_is_served_from_outside_it(across):
    scenario, result, free = across
    disc = scenario.zones.keep_out[0]
    node = np.array(scenario.ground_nodes_m[1])
    assert disc.clearance([node])[0] < 0                       # node 2 is inside the disc
    nearest_allowed = disc.radius_m + scenario.zones.margin_m - np.linalg.norm(
        node - np.array(disc.center_m))
    path = flown_path(result.trajectory, scenario)
    closest = min(_segment_distance(node, a, b) for a, b in zip(path[:-1], path[1:]))
    assert closest >= nearest_allowed - 1e-6
    assert closest <= nearest_allowed + 1.0                    # as near as the zone lets it
    # Without the zone the UAV passes close over it (8 m); with it every node still gets a
    # fair share.
    free_path = flown_path(free.trajectory, paper_scenario('I'))
    assert min(_segment_distance(node, a, b) for a, b in zip(free_path[:-1], free_path[1:])) \
        < nearest_allowed / 4
    assert result.rates.min() == pytest.approx(result.rates.max(), rel=1e-3)
    assert result.min_throughput < free.min_throughput


def _segment_distance(point: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    t = 0.0 if not ab.any() else float(np.clip((point - a) @ ab / (ab @ ab), 0.0, 1.0))
    return float(np.linalg.norm(point - (a + t * ab)))


# Requests with no way round the zones are refused with the numbers.

def test_a_goal_walled_off_is_refused():
    # Two rooms joined by a corridor 8 m wide: with a margin of 5 m nothing passes.
    area = OperatingArea([(-50, -50), (500, -50), (500, -4), (1500, -4), (1500, -50),
                          (2050, -50), (2050, 50), (1500, 50), (1500, 4), (500, 4), (500, 50),
                          (-50, 50)])
    scenario = paper_scenario('I', zones=Zones(area=area, margin_m=5.0))
    with pytest.raises(InfeasibleHorizonError, match='no path from q0 to qF keeps the margin '
                                                     'of 5 m'):
        plan(scenario)
    # A margin of 3 m fits through.
    narrower = scenario.replace(zones=Zones(area=area, margin_m=3.0))
    check_plan(plan(narrower, SolverSettings(starts=('straight',))), narrower)
    # A rest in flight walled off from qF is refused at once: neither more slots nor a slower
    # speed finds a way round.
    calls = []

    def recording(rest, settings, **options):
        calls.append(rest.num_slots)
        return plan(rest, settings, **options)
    in_flight = InFlight(position_m=(100.0, 0.0), flown=FlownSlots.none(3),
                         previous_q=np.zeros((0, 2)), mission_id=1, segment=0, slots_kept=0)
    with pytest.raises(WalledInError, match='walled in'):
        plan_mission(MissionRequest(scenario, in_flight=in_flight, items=False,
                                    vehicle_aware=False), planner=recording)
    assert calls == [scenario.num_slots]
    slow = scenario.replace(max_speed_mps=10.0, horizon_s=400.0)
    calls.clear()
    with pytest.raises(WalledInError, match='walled in'):      # planned for the vehicle
        plan_mission(MissionRequest(slow, in_flight=in_flight, items=False),
                     planner=recording)
    assert calls == [slow.num_slots]


def test_a_way_round_longer_than_the_horizon_is_refused_with_the_horizon_it_needs():
    wall = KeepOutPolygon([(950, -2000), (1050, -2000), (1050, 450), (950, 450)])
    zones = Zones(keep_out=(wall,))
    short = paper_scenario('I', num_slots=20, horizon_s=20.0, zones=zones)
    with pytest.raises(InfeasibleHorizonError, match=r'is (\d+\.\d) m .* needs (\d+) legs .* '
                                                     r'has 21; raise horizon_s to') as error:
        plan(short)
    text = str(error.value)
    length = float(text.split(' is ')[1].split(' m')[0])
    corners = shortest_path(zones, short.start_m, short.goal_m)
    assert length == pytest.approx(path_length(corners), abs=0.05)
    assert length > 2 * np.hypot(1000.0, 455.0) - 1.0       # over the wall's top, at the margin
    needed = float(text.split('raise horizon_s to ')[1].split(' s')[0])
    check_plan(plan(short.replace(horizon_s=needed)), short.replace(horizon_s=needed))
    with pytest.raises(InfeasibleHorizonError):
        plan(short.replace(horizon_s=needed - 0.1))


# The mission flown: its legs are not straightened across a zone.

def test_simplifying_a_leg_never_cuts_a_zone():
    disc = KeepOutCircle((0.0, 0.0), 100.0)
    zones = Zones(keep_out=(disc,), margin_m=5.0)
    # Plan points round the disc 2 degrees apart, each leg tangent to it at the margin.
    angles = np.radians(np.arange(0.0, 181.0, 2.0))
    points = 105.0 / np.cos(np.radians(1.0)) * np.stack([np.cos(angles), np.sin(angles)], 1)
    assert zones.path_clearance(points) >= zones.margin_m - 1e-9
    plain = simplify(points, 1.0)
    assert zones.path_clearance(points[plain]) < zones.margin_m - 0.5   # chords cut inside
    kept = simplify(points, 1.0, zone_check(zones))
    assert zones.path_clearance(points[kept]) >= zones.margin_m - 1e-9
    assert len(kept) == len(points)     # at exactly the margin no chord keeps it


def multirotor_across() -> Scenario:
    """:func:`letter_across` at a multirotor's 10 m/s: 400 s in 100 slots of 4 s."""
    return letter_across(max_speed_mps=10.0, horizon_s=400.0, num_slots=100)


def test_the_vehicle_s_mission_keeps_every_zone_through_the_pipeline():
    zones = letter_across().zones
    request = MissionRequest(multirotor_across().replace(zones=None), zones=zones)
    mission = plan_mission(request)
    scenario = mission.result.scenario
    assert scenario.zones == zones
    schedule = mission.vehicle_plan.schedule
    assert len(schedule.legs) >= 2 and mission.items
    flown = np.vstack([schedule.stops[0].position_m]
                      + [leg.vertices[1:] for leg in schedule.legs])
    assert zones.path_clearance(flown) >= zones.margin_m - 1e-6
    for leg, stop in zip(schedule.legs, schedule.stops[1:]):
        assert np.array_equal(leg.vertices[-1], stop.position_m)
    check_plan(mission.vehicle_plan.ideal, mission.vehicle_plan.ideal.scenario)
    assert mission.result.min_throughput > mission.vehicle_plan.ideal.baselines['straight']


@pytest.mark.parametrize('k, position, kept', [
    (20, None, True),                 # 30 m south of the plan: the old rest still keeps out
    (15, (370.0, 420.0), False)])     # west of the L's bar: the old rest's first leg cuts it
def test_a_replan_in_flight_keeps_the_zones_and_leaves_out_a_rest_that_would_cut_them(
        across, k, position, kept):
    mission, first, _ = across
    flown = FlownSlots(first.power[:, :k], first.trajectory[:k])
    position = first.trajectory[k - 1] + np.array([0.0, -30.0]) if position is None \
        else np.array(position)
    assert mission.zones.clearance([position])[0] >= mission.zones.margin_m
    receding = replan(mission, position, flown, previous_q=first.trajectory[k:])
    rest = receding.result.scenario
    assert rest.zones == mission.zones and rest.start_m == tuple(position)
    check_plan(receding.result, rest)
    # The rest of the old plan from the new position is one more start only if it keeps the
    # zones (and the speed limits).
    old_rest = first.trajectory[k:]
    assert within_speed_limit(old_rest, rest)
    assert (clearance_of(old_rest, rest) >= mission.zones.margin_m) == kept
    assert ('previous' in receding.result.start_throughputs) == kept


@pytest.mark.parametrize('inside_m', [0.3, 2.0])
def test_a_replan_from_just_inside_the_margin_starts_at_the_margin(across, inside_m):
    """A vehicle flying a plan that hugs the margin drifts a little inside it: the rest starts
    at the nearest point that keeps the margin, not refused."""
    mission, first, _ = across
    k = 20
    flown = FlownSlots(first.power[:, :k], first.trajectory[:k])
    disc = mission.zones.keep_out[0]
    centre = np.array(disc.center_m)
    away = (first.trajectory[k - 1] - centre) / np.linalg.norm(first.trajectory[k - 1] - centre)
    position = centre + (disc.radius_m + mission.zones.margin_m - inside_m) * away
    assert 0 < mission.zones.clearance([position])[0] < mission.zones.margin_m
    receding = replan(mission, position, flown, previous_q=first.trajectory[k:])
    rest = receding.result.scenario
    start = np.array(rest.start_m)
    assert mission.zones.clearance([start])[0] >= mission.zones.margin_m
    # Radially out of the disc, by what was missing and the graph's clearance.
    np.testing.assert_allclose(start, position + (inside_m + GRAPH_CLEARANCE_M) * away,
                               atol=1e-9)
    check_plan(receding.result, rest)
    # In the disc itself, or farther inside the margin than the node counts the vehicle at q0
    # from, the position stays refused.
    from uav_comm_planner.ros.flight import START_RADIUS_M
    assert CLEAR_START_MAX_M == START_RADIUS_M
    for depth_m in (mission.zones.margin_m + 1.0, CLEAR_START_MAX_M + 0.5):
        with pytest.raises(InvalidScenarioError, match='zone'):
            replan(mission, centre + (disc.radius_m + mission.zones.margin_m - depth_m) * away,
                   flown)


def test_a_many_sided_non_convex_zone_across_the_letter_s_line_is_kept_out():
    rng = np.random.default_rng(7)
    polygon = None
    while polygon is None:
        try:
            polygon = KeepOutPolygon(star(rng, (1000.0, 100.0), 150.0, 16, 0.3))
        except InvalidScenarioError:
            continue
    assert not polygon.convex and len(polygon.convex_pieces()) < 14    # triangles joined
    scenario = paper_scenario('I', zones=Zones(area=AREA, keep_out=(polygon,)))
    result = plan(scenario)
    check_plan(result, scenario)
    assert result.min_throughput > result.baselines['straight']


def test_a_plan_cancelled_while_its_visibility_graph_is_built_stops_there():
    """Zones of many corners make the visibility graph the long part of a plan (it grows
    with their cube): the plan's should_stop is asked between chunks of it, and a cancelled
    graph is not kept."""
    discs = tuple(KeepOutCircle((x, 0.0 if x == 1000.0 else 350.0), 40.0)
                  for x in np.linspace(200.0, 1800.0, 9))     # the middle one on the line
    zones = Zones(area=AREA, keep_out=discs)
    corners = len(graph_corners(zones))
    pairs = corners * (corners - 1) // 2
    assert pairs > 2 * GRAPH_CHUNK
    scenario = paper_scenario('I', zones=zones)
    asked = []

    def should_stop() -> bool:
        asked.append(True)
        return len(asked) >= 2          # the first two asks are the graph's first chunks
    GRAPHS.clear()
    before = GRAPHS.stored
    with pytest.raises(PlanCancelledError):
        plan(scenario, should_stop=should_stop)
    print(f'{corners} corners, {pairs} pairs: asked {len(asked)} times')
    assert len(asked) == 2
    assert GRAPHS.stored == before and zones not in GRAPHS
    # Not cancelled, the same plan builds the graph (none was kept), once, and keeps it.
    check_plan(plan(scenario), scenario)
    assert GRAPHS.stored == before + 1 and zones in GRAPHS


def test_the_hover_start_hovers_at_each_node_s_nearest_point_outside_the_zones(across):
    scenario = across[0]
    zones = scenario.zones
    disc = zones.keep_out[0]
    node = np.array(scenario.ground_nodes_m[1])
    point = outside_point(zones, node)
    # Radially out of the disc to the margin and the graph's 5 cm.
    reach = disc.radius_m + zones.margin_m + GRAPH_CLEARANCE_M
    np.testing.assert_allclose(np.linalg.norm(point - np.array(disc.center_m)), reach)
    out, inside = point - np.array(disc.center_m), node - np.array(disc.center_m)
    assert out[0] * inside[1] - out[1] * inside[0] == pytest.approx(0.0, abs=1e-6)
    assert out @ inside > 0
    assert np.array_equal(outside_point(zones, scenario.ground_nodes_m[2]),
                          np.array(scenario.ground_nodes_m[2]))       # node 3 is outside
    q = hover_start(scenario)
    assert clearance_of(q, scenario) >= zones.margin_m
    assert within_speed_limit(q, scenario)
    # It hovers there: several slots at the very point.
    assert np.sum(np.all(q == point, axis=1)) >= 2


def test_two_nodes_served_from_one_point_share_its_hovers():
    zones = Zones(keep_out=(KeepOutCircle((1000.0, 100.0), 150.0),))
    scenario = paper_scenario('I', ground_nodes_m=((1000, 150), (1000, 200), (1800, 400)),
                              zones=zones)
    shared = outside_point(zones, scenario.nodes[0])
    assert np.array_equal(shared, outside_point(zones, scenario.nodes[1]))
    q = hover_start(scenario)
    assert q.shape == (scenario.num_slots, 2) and within_speed_limit(q, scenario)
    assert clearance_of(q, scenario) >= zones.margin_m
    check_plan(plan(scenario), scenario)


def test_a_leg_on_the_line_through_a_zones_edge_but_far_from_it_is_clear():
    """Collinear with an edge, 500 m short of it: clear; a hover on that line too."""
    square = Zones(keep_out=(KeepOutPolygon([[1000, 0], [1100, 0], [1100, 100], [1000, 100]]),),
                   margin_m=5.0)
    assert segments_clear(square, [0.0, 0.0], [500.0, 0.0]).tolist() == [True]
    assert segments_clear(square, [0.0, 0.0], [2000.0, 0.0]).tolist() == [False]
    assert segments_clear(square, [0.0, -3.0], [2000.0, -3.0]).tolist() == [False]
    wall = Zones(keep_out=(KeepOutPolygon([[800, 200], [900, 200], [900, 300], [800, 300]]),),
                 margin_m=5.0)
    scenario = Scenario(ground_nodes_m=((500.0, 200.0), (1500.0, -300.0)), goal_m=(2000.0, 0.0),
                        zones=wall)
    result = plan(scenario)
    assert wall.path_clearance(flown_path(result.trajectory, scenario)) >= 5.0 - 1e-6


def test_a_node_at_the_launch_point_keeps_every_slot_of_the_hover_start():
    scenario = Scenario(ground_nodes_m=((0.0, 0.0), (1500.0, -300.0)), goal_m=(2000.0, 0.0),
                        num_slots=50,
                        zones=Zones(keep_out=(KeepOutCircle((1000.0, 300.0), 100.0),)))
    assert hover_start(scenario).shape == (50, 2)
    result = plan(scenario, SolverSettings(starts=('hover',)))
    assert result.trajectory.shape == (50, 2)
