"""``uav-comm-planner upload --fence`` against the real autopilots: ArduCopter SITL and PX4 SITL
take the fence items (mission type FENCE), hold exactly them when read back on another link,
and a fence they refuse is one error naming the item and the result."""

from __future__ import annotations

import json
from pathlib import Path
import queue
import subprocess
import sys

import pytest
from test_fence import same_polygon
from test_upload_px4 import RUN_PX4

from devtools.px4_sitl import start_px4, why_px4_not_runnable
from devtools.sitl import open_link, start_sitl, why_not_runnable
from uav_comm_planner import paper_scenario, plan, SolverSettings
from uav_comm_planner.core.zones import KeepOutCircle, KeepOutPolygon, OperatingArea, Zones
from uav_comm_planner.errors import VehicleLinkError
from uav_comm_planner.vehicle.fence import fence_from_zones, read_fence
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.mavlink.fence import (fence_from_items, fence_items,
                                                    MISSION_TYPE_FENCE)
from uav_comm_planner.vehicle.mavlink.items import build_mission_items, mismatches, MissionItem
from uav_comm_planner.vehicle.mavlink.link import connect, download_mission, upload_and_verify
from uav_comm_planner.vehicle.mavlink.telemetry import LinkEvent, VehicleBridge

CLI = [sys.executable, '-m', 'uav_comm_planner.tools.cli']
ARDUPILOT_HOME = Home(-35.363262, 149.165237, 584.0)
PX4_HOME = Home(47.397742, 8.545594, 489.0)
ZONES = Zones(OperatingArea([(-200.0, -300.0), (2200.0, -300.0), (2200.0, 700.0),
                             (-200.0, 700.0)]),
              (KeepOutPolygon([(900.0, -100.0), (1100.0, -100.0), (1000.0, 150.0)]),
               KeepOutCircle((400.0, 400.0), 80.0)))
#: ArduCopter instances this module's SITL takes (TCP 5760 + 10 I).
ARDUPILOT_INSTANCES = (20, 29)
#: The PX4 instance tried first.
PX4_INSTANCE = 8


def fence_plan_file(folder: Path, home: Home) -> Path:
    """A .plan file holding only the fence of ZONES (as QGroundControl saves a fence)."""
    path = folder / 'fence.plan'
    path.write_text(json.dumps({'fileType': 'Plan', 'version': 1,
                                'geoFence': fence_from_zones(ZONES, home).plan_section(),
                                'mission': {'items': [], 'version': 2}}))
    return path


def fence_geojson_file(folder: Path, home: Home) -> Path:
    """The fence of ZONES as GeoJSON, its circle a Point with radius_m."""
    fence = fence_from_zones(ZONES, home)
    features = [{'type': 'Feature',
                 'properties': {'fence': 'inclusion' if p.inclusion else 'exclusion'},
                 'geometry': {'type': 'Polygon',
                              'coordinates': [[[lon, lat] for lat, lon in p.vertices_deg]]}}
                for p in fence.polygons]
    features += [{'type': 'Feature',
                  'properties': {'fence': 'exclusion', 'radius_m': c.radius_m},
                  'geometry': {'type': 'Point', 'coordinates': c.center_deg[::-1]}}
                 for c in fence.circles]
    path = folder / 'fence.geojson'
    path.write_text(json.dumps({'type': 'FeatureCollection', 'features': features}))
    return path


def run(*arguments: str, timeout_s: float = 180.0) -> subprocess.CompletedProcess:
    return subprocess.run(CLI + list(arguments), capture_output=True, text=True,
                          timeout=timeout_s)


def two_vertex_polygon(home: Home) -> list[MissionItem]:
    """An exclusion "polygon" of two vertices: both autopilots refuse it."""
    return [MissionItem(5002, 0, (2.0, 0.0, 0.0, 0.0), home.latitude_deg + d, home.longitude_deg)
            for d in (0.001, 0.002)]


# ArduCopter.

ardupilot_only = pytest.mark.skipif(bool(why_not_runnable()), reason=why_not_runnable())


@pytest.fixture(scope='module')
def ardupilot(tmp_path_factory):
    """An ArduCopter SITL; yields the test's link and the URL of its second port."""
    sitl = start_sitl(tmp_path_factory.mktemp('sitl'), ARDUPILOT_HOME,
                      instances=ARDUPILOT_INSTANCES)
    try:
        link = open_link(sitl)
        yield link, f'tcp:127.0.0.1:{5762 + 10 * sitl.instance}'
        link.close()
    finally:
        sitl.stop()


@pytest.mark.sitl
@ardupilot_only
def test_arducopter_takes_a_geojson_fence_with_the_mission_and_holds_both(ardupilot,
                                                                          tmp_path):
    link, url = ardupilot
    fence_file = fence_geojson_file(tmp_path, ARDUPILOT_HOME)
    mission = tmp_path / 'mission.plan'
    planned = run('plan', '--case', 'I', '--speed', '10', '--horizon', '400', '--slots', '40',
                  '--home=-35.363262,149.165237,584', '--mission', str(mission))
    assert planned.returncode == 0, planned.stderr
    done = run('upload', str(mission), '--fence', str(fence_file), '--connect', url)
    assert done.returncode == 0, done.stderr
    sent = fence_items(read_fence(fence_file))
    assert f'{len(sent)} fence items uploaded' in done.stdout
    assert 'items uploaded' in done.stdout.splitlines()[1]
    stored = download_mission(link, mission_type=MISSION_TYPE_FENCE)
    assert mismatches(sent, stored, home_row=False) == []
    assert len(stored) == 3 + 4 + 1
    # The fence read back is the zones' fence to MISSION_ITEM_INT's 1e-7 degree.
    held = fence_from_items(stored).zones(ARDUPILOT_HOME)
    for got, expected in zip((held.area, *held.keep_out[:1]), (ZONES.area, ZONES.keep_out[0])):
        same_polygon(got.vertices_m, expected.vertices_m, 0.02)
    assert abs(held.keep_out[1].radius_m - 80.0) < 1e-6
    assert download_mission(link)[-1].command == 21  # the mission's NAV_LAND is there too


@pytest.mark.sitl
@ardupilot_only
def test_arducopter_refuses_a_two_vertex_polygon_by_item(ardupilot):
    link, _ = ardupilot
    with pytest.raises(VehicleLinkError,
                       match=r'refused the fence at item 1: MAV_MISSION_ERROR'):
        upload_and_verify(link, two_vertex_polygon(ARDUPILOT_HOME),
                          mission_type=MISSION_TYPE_FENCE)


def test_a_bad_fence_file_is_one_line_and_exit_2_before_any_connection(tmp_path):
    bad = tmp_path / 'fence.geojson'
    bad.write_text(json.dumps({'type': 'FeatureCollection', 'features': [
        {'type': 'Feature', 'properties': {'fence': 'exclusion'},
         'geometry': {'type': 'Polygon', 'coordinates': [[[8.5, 47.3], [8.6, 47.3]]]}}]}))
    done = run('upload', '--fence', str(bad), '--connect', 'tcp:127.0.0.1:1', timeout_s=60)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert str(bad) in lines[0] and 'features[0].geometry.coordinates[0]' in lines[0]
    done = run('upload', '--connect', 'tcp:127.0.0.1:1', timeout_s=60)
    assert done.returncode == 2 and 'nothing to upload' in done.stderr


# PX4.

@pytest.fixture(scope='module')
def px4(tmp_path_factory):
    """A PX4 SITL, on PX4_INSTANCE when it is free; yields (ground-station URL, onboard
    URL)."""
    order = [PX4_INSTANCE, *(n for n in range(9, -1, -1) if n != PX4_INSTANCE)]
    instance = next((n for n in order if not Path(f'/tmp/px4_lock-{n}').exists()), None)
    if instance is None:
        pytest.fail('every PX4 instance 0..9 is taken (/tmp/px4_lock-N)')
    sitl = start_px4(tmp_path_factory.mktemp('px4'), instance, script=RUN_PX4, speedup=4)
    try:
        yield sitl.ground_station_url, sitl.onboard_url
    finally:
        sitl.stop()


px4_only = pytest.mark.skipif(bool(why_px4_not_runnable(RUN_PX4)),
                              reason=why_px4_not_runnable(RUN_PX4))


@pytest.mark.sitl
@px4_only
def test_px4_takes_a_plan_fence_and_holds_it(px4, tmp_path):
    ground_station, onboard = px4
    fence_file = fence_plan_file(tmp_path, PX4_HOME)
    done = run('upload', '--fence', str(fence_file), '--connect', ground_station)
    assert done.returncode == 0, done.stderr
    assert 'fence items uploaded' in done.stdout and 'read back identical' in done.stdout
    link = connect(onboard, timeout_s=60.0)
    try:
        stored = download_mission(link, mission_type=MISSION_TYPE_FENCE)
    finally:
        link.close()
    sent = fence_items(read_fence(fence_file))
    assert mismatches(sent, stored, home_row=False) == []
    assert fence_from_items(stored).zones(PX4_HOME).keep_out[1].radius_m == 80.0


@pytest.mark.sitl
@px4_only
def test_px4_refuses_a_two_vertex_polygon_by_item(px4):
    _, onboard = px4
    link = connect(onboard, timeout_s=60.0)
    try:
        with pytest.raises(VehicleLinkError,
                           match=r'refused the fence at item 0: MAV_MISSION_ERROR'):
            upload_and_verify(link, two_vertex_polygon(PX4_HOME),
                              mission_type=MISSION_TYPE_FENCE)
    finally:
        link.close()


@pytest.mark.sitl
@ardupilot_only
def test_the_vehicle_bridge_uploads_a_fence_only_when_it_changes(ardupilot):
    link, url = ardupilot
    result = plan(paper_scenario('I', max_speed_mps=10.0, horizon_s=400.0, num_slots=40),
                  SolverSettings(compute_baselines=False))
    items = build_mission_items(result, ARDUPILOT_HOME)
    fence = fence_items(fence_from_zones(ZONES, ARDUPILOT_HOME))
    smaller = fence_items(fence_from_zones(Zones(ZONES.area), ARDUPILOT_HOME))
    events: queue.Queue = queue.Queue()
    bridge = VehicleBridge(url, ARDUPILOT_HOME, events.put)

    def uploaded(tag: str) -> str:
        while True:
            event = events.get(timeout=120)
            if isinstance(event, LinkEvent) and event.tag == tag:
                assert event.kind == 'uploaded', event.message
                return event.message
    try:
        bridge.upload(items, fence=fence, tag='first')
        assert f'after a fence of {len(fence)} items' in uploaded('first')
        bridge.upload(items, fence=fence, tag='same')
        assert 'fence' not in uploaded('same')
        bridge.upload(items, fence=smaller, tag='other')
        assert f'after a fence of {len(smaller)} items' in uploaded('other')
    finally:
        bridge.stop()
    stored = download_mission(link, mission_type=MISSION_TYPE_FENCE)
    assert mismatches(smaller, stored, home_row=False) == []
