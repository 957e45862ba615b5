"""The planner node with ``uavs`` 2 and two ArduCopter SITL vehicles, one link each
(``mavlink_urls``): each vehicle is given its own mission, and each holds, read back on the
test's own link, what the mission export builds independently from the core's fleet plan.

Each vehicle is started at its own q0 (east-north metres from the fleet's frame origin, the
simulator's home CMAC, which the node takes when no home parameter is set); the node holds
each SITL's second MAVLink port (TCP 5762 + 10 I), the test the first.
"""

from __future__ import annotations

import time

from helpers import SLOW_FLEET, slow_fleet, SLOW_FLEET_STARTS, SpunNode
import numpy as np
import pytest

from devtools.sitl import open_link, start_sitl, why_not_runnable
from uav_comm_planner import SolverSettings
from uav_comm_planner.core.fleet import FleetSettings
from uav_comm_planner.mission.fleet import plan_for_missions, uav_result
from uav_comm_planner.vehicle.geodesy import default_home, enu_to_geodetic, Home
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink.items import build_mission_items, mismatches, Q0_SEQ
from uav_comm_planner.vehicle.mavlink.link import download_mission

pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(bool(why_not_runnable()), reason=why_not_runnable())]

#: This module's vehicles' instances (MAVLink TCP 5760 + 10 I), one range each.
INSTANCES = ((85, 89), (90, 94))
#: Wall-clock limit on the uploads (the SITLs must first get a position fix).
UPLOAD_DEADLINE_S = 180.0


def spawn_at(start_m, home: Home) -> Home:
    """The WGS84 point ``start_m`` (east, north metres from ``home``), at home's altitude."""
    latitude, longitude, _ = enu_to_geodetic(np.array([start_m[0]]), np.array([start_m[1]]),
                                             0.0, home)
    return Home(float(latitude[0]), float(longitude[0]), home.altitude_m)


def test_the_node_uploads_each_vehicle_its_own_mission(ros_context, tmp_path):
    home = default_home('ardupilot')
    vehicles, links, spun = [], [], None
    try:
        for k, (start, instances) in enumerate(zip(SLOW_FLEET_STARTS, INSTANCES)):
            folder = tmp_path / f'uav{k + 1}'
            folder.mkdir()
            vehicles.append(start_sitl(folder, spawn_at(start, home), instances=instances))
        links = [open_link(vehicle) for vehicle in vehicles]
        urls = [f'tcp:127.0.0.1:{5762 + 10 * vehicle.instance}' for vehicle in vehicles]
        spun = SpunNode(ros_context, {**SLOW_FLEET, 'mavlink_urls': urls})
        node = spun.node

        def uploaded() -> bool:
            current = node.fleet.current
            return current is not None and node.fleet.links.verified_tag == [
                current.request.start_ns] * 2
        deadline = time.monotonic() + UPLOAD_DEADLINE_S
        while not uploaded():
            assert time.monotonic() < deadline, (
                f'uploads verified {node.fleet.links.uploads_verified}, link errors '
                f'{node.fleet.links.last_error}, node error {node.stats.last_error!r}')
            time.sleep(0.2)
        outcome = node.fleet.current
        # What the mission export builds from the core's fleet plan for the same input.
        core, _ = plan_for_missions(slow_fleet(), FleetSettings(single=SolverSettings()),
                                    VehicleLimits(), 'ardupilot')
        np.testing.assert_allclose(outcome.plan.trajectories, core.trajectories, atol=1e-9)
        held = []
        for k, link in enumerate(links):
            stored = download_mission(link)
            expected = build_mission_items(uav_result(core, k), home, end='land',
                                           firmware='ardupilot', limits=VehicleLimits())
            assert mismatches(outcome.vehicles[k].plan.items, stored) == []
            assert mismatches(expected, stored) == []
            assert len(stored) == len(expected) > Q0_SEQ + 2
            held.append(stored)
        # Each its own: the missions differ, each from its own q0.
        assert mismatches(held[0], held[1]) != []
        for k, stored in enumerate(held):
            q0 = spawn_at(SLOW_FLEET_STARTS[k], home)
            assert (stored[Q0_SEQ].x, stored[Q0_SEQ].y) == pytest.approx(
                (q0.latitude_deg, q0.longitude_deg), abs=2e-7)
        assert node.fleet.links.uploads_verified == [1, 1]
        print(f'fleet missions: {[len(m) for m in held]} items held, read back equal on both '
              f'vehicles; fleet min throughput {outcome.plan.min_throughput:.4g} bit/s')
    finally:
        if spun is not None:
            spun.stop()
        for link in links:
            link.close()
        for vehicle in vehicles:
            vehicle.stop()
