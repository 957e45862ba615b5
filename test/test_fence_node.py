"""The node's fence: ``fence_file`` read at start-up into every plan's zones, refused with the
file named when bad, ``fence_margin_m`` validated on set (the last good plan kept), the zones
on the latched ``zone_markers`` topic, and the fence uploaded before the mission to a real
ArduCopter SITL over the node's link."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from visualization_msgs.msg import Marker, MarkerArray

from devtools.sitl import open_link, start_sitl, why_not_runnable
from uav_comm_planner.core.zones import KeepOutCircle, KeepOutPolygon, OperatingArea, Zones
from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.ros.node import PlannerNode
from uav_comm_planner.ros.publishing import OUTPUT_QOS, TOPIC_ZONE_MARKERS
from uav_comm_planner.vehicle.fence import fence_from_zones, read_zones, zone_outlines
from uav_comm_planner.vehicle.geodesy import DEFAULT_HOME, Home
from uav_comm_planner.vehicle.mavlink.fence import fence_items, MISSION_TYPE_FENCE
from uav_comm_planner.vehicle.mavlink.items import mismatches
from uav_comm_planner.vehicle.mavlink.link import download_mission

HOME = Home(*DEFAULT_HOME)
#: Away from the harness's plan (its nodes lie between y = -150 and 250).
ZONES = Zones(OperatingArea([(-500.0, -1000.0), (2500.0, -1000.0), (2500.0, 1000.0),
                             (-500.0, 1000.0)]),
              (KeepOutCircle((1000.0, -700.0), 50.0),
               KeepOutPolygon([(0.0, -50.0), (40.0, -50.0), (20.0, -80.0)])))


def fence_file(folder: Path, zones: Zones = ZONES, home: Home = HOME) -> Path:
    path = folder / 'fence.plan'
    path.write_text(json.dumps({'fileType': 'Plan', 'version': 1,
                                'geoFence': fence_from_zones(zones, home).plan_section()}))
    return path


def test_the_fence_file_is_in_every_plan_and_on_zone_markers(harness, tmp_path):
    path = fence_file(tmp_path)
    h = harness(fence_file=str(path))
    h.published(1)
    zones = h.node.current_plan.result.scenario.zones
    assert zones == read_zones(path, HOME)
    received: list[MarkerArray] = []
    # Latched: a subscriber that joins after the plan still gets the zones.
    h.probe.create_subscription(MarkerArray, TOPIC_ZONE_MARKERS, received.append, OUTPUT_QOS)
    h.spin_until(lambda: received, 'zone markers')
    markers = received[-1].markers
    assert markers[0].action == Marker.DELETEALL
    strips = markers[1:]
    assert [(m.ns, m.id, m.type) for m in strips] == [
        ('operating_area', 0, Marker.LINE_STRIP), ('keep_out', 0, Marker.LINE_STRIP),
        ('keep_out', 1, Marker.LINE_STRIP)]
    for marker, (_, ring) in zip(strips, zone_outlines(zones)):
        got = np.array([(p.x, p.y) for p in marker.points])
        np.testing.assert_allclose(got, ring)
        assert marker.header.frame_id == 'map'


def test_fence_file_is_read_only_and_a_bad_one_stops_the_start(harness, tmp_path, ros_context):
    h = harness()
    h.published(1)
    answer = h.call('set_parameters', SetParameters.Request(parameters=[
        Parameter('fence_file', value=str(fence_file(tmp_path))).to_parameter_msg()]))
    assert not answer.results[0].successful
    bad = tmp_path / 'bad.geojson'
    bad.write_text('{"type": "FeatureCollection", "features": [{"properties": {}}]}')
    with pytest.raises(InvalidScenarioError,
                       match=r"bad.geojson': features\[0\].properties: has no \"fence\""):
        PlannerNode(context=ros_context, parameter_overrides=[
            Parameter('fence_file', value=str(bad))])


def test_a_margin_the_start_cannot_keep_is_refused_and_the_plan_stays(harness, tmp_path):
    h = harness(fence_file=str(fence_file(tmp_path)))
    h.published(1)
    before = h.node.current_plan
    # The triangle's nearest point is 50 m south of q0 = (0, 0).
    answer = h.call('set_parameters', SetParameters.Request(parameters=[
        Parameter('fence_margin_m', value=60.0).to_parameter_msg()]))
    assert not answer.results[0].successful
    assert 'start_m' in answer.results[0].reason and '60 m' in answer.results[0].reason
    assert h.node.current_plan is before
    answer = h.call('set_parameters', SetParameters.Request(parameters=[
        Parameter('fence_margin_m', value=20.0).to_parameter_msg()]))
    assert answer.results[0].successful, answer.results[0].reason
    h.published(2)
    assert h.node.current_plan.result.scenario.zones.margin_m == 20.0


@pytest.mark.sitl
@pytest.mark.skipif(bool(why_not_runnable()), reason=why_not_runnable())
def test_the_node_uploads_the_fence_before_the_mission(harness, tmp_path):
    home = Home(-35.363262, 149.165237, 584.0)
    (tmp_path / 'sitl').mkdir()
    sitl = start_sitl(tmp_path / 'sitl', home, instances=(20, 29))
    try:
        link = open_link(sitl)
        h = harness(fence_file=str(fence_file(tmp_path, home=home)),
                    mavlink_url=f'tcp:127.0.0.1:{5762 + 10 * sitl.instance}',
                    home_latitude_deg=home.latitude_deg, home_longitude_deg=home.longitude_deg,
                    home_altitude_m=home.altitude_m, max_speed_mps=10.0, horizon_s=400.0,
                    num_slots=100, vehicle_aware=True)
        h.spin_until(lambda: (h.node.vehicle.uploads_verified >= 1
                              or 'upload' in h.node.vehicle.last_error), 'verified upload')
        assert h.node.vehicle.uploads_verified >= 1, h.node.stats.last_error
        stored = download_mission(link, mission_type=MISSION_TYPE_FENCE)
        sent = fence_items(fence_from_zones(read_zones(fence_file(tmp_path, home=home), home),
                                            home))
        assert mismatches(sent, stored, home_row=False) == []
        assert len(download_mission(link)) == len(h.node.current_plan.plan.items)
        link.close()
    finally:
        sitl.stop()


def test_the_file_is_read_at_start_and_a_bad_one_later_keeps_the_last_good_plan(harness,
                                                                                tmp_path):
    path = fence_file(tmp_path)
    h = harness(fence_file=str(path))
    h.published(1)
    read_at_start = h.node.current_plan.result.scenario.zones
    assert read_at_start is not None
    path.write_text('{"geoFence": {"version": 2, "polygons": [{"inclusion": false}]}}')
    # Another parameter: the fence read at start-up stands.
    answer = h.call('set_parameters', SetParameters.Request(parameters=[
        Parameter('power_budget_w', value=4.0).to_parameter_msg()]))
    assert answer.results[0].successful, answer.results[0].reason
    h.published(2)
    good = h.node.current_plan
    assert good.result.scenario.zones == read_at_start
    # A new margin reads the file again: refused with the file and the place, plan kept.
    answer = h.call('set_parameters', SetParameters.Request(parameters=[
        Parameter('fence_margin_m', value=8.0).to_parameter_msg()]))
    assert not answer.results[0].successful
    assert str(path) in answer.results[0].reason
    assert 'geoFence.polygons[0]: has no "polygon"' in answer.results[0].reason
    assert h.node.current_plan is good


def test_the_fence_margin_is_a_distance():
    from uav_comm_planner.ros.params import NodeSettings
    for bad in (-1.0, float('nan'), float('inf'), True, '5'):
        with pytest.raises(InvalidScenarioError, match='fence_margin_m must be'):
            NodeSettings(fence_margin_m=bad)


def test_a_fenced_plan_is_not_moved_to_a_vehicle_home_its_zones_were_not_placed_from():
    """Zones read from the home parameters would land elsewhere if the mission were rebuilt
    for the vehicle's own home: refused, in one line naming both, and nothing uploaded."""
    from types import SimpleNamespace

    from uav_comm_planner.ros.vehicle_state import VehicleState
    reports, uploads = [], []
    state = VehicleState()
    state._report = lambda message, is_error: reports.append((message, is_error))
    state._bridge = SimpleNamespace(upload=lambda *a, **k: uploads.append(a))
    state._reset_state(Home(47.397742, 8.545594, 489.0))       # the vehicle's home
    request = SimpleNamespace(home=HOME, planned_scenario=SimpleNamespace(zones=ZONES))
    state.upload(SimpleNamespace(plan=SimpleNamespace(request=request),
                                 request=SimpleNamespace(start_ns=1)))
    assert uploads == [] and state._pending_tag is None
    (message, is_error), = reports
    assert is_error and 'zones were placed from the home parameters' in message
    assert HOME.latitude_deg != 47.397742
    assert '47.3977420' in message and f'{HOME.latitude_deg:.7f}' in message
