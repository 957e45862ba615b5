"""``uav-comm-planner upload`` against ArduCopter SITL: upload, read back, refusals, drops.

The vehicle is the real autopilot (``../shared/sitl/arducopter``, see ``test/sitl.py``). The
test holds the SITL's first MAVLink port; the command under test connects to its second
(TCP 5762 + 10 I), directly or through a proxy that cuts the link after a few items.
"""

from __future__ import annotations

from pathlib import Path
import socket
import subprocess
import sys
import threading

from pymavlink import mavutil
import pytest

from devtools.sitl import open_link, start_sitl, why_not_runnable
from uav_comm_planner import paper_scenario, plan, SolverSettings
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.mavlink.files import (export_mission, read_mission_file,
                                                    read_waypoints)
from uav_comm_planner.vehicle.mavlink.items import mismatches
from uav_comm_planner.vehicle.mavlink.link import download_mission

HOME = Home(-35.363262, 149.165237, 584.0)
CLI = [sys.executable, '-m', 'uav_comm_planner.tools.cli']


def needs_sitl(test):
    """Marks a test that flies or talks to the SITL (``-m 'not sitl'`` leaves it out); skipped,
    with the reason, only where the binary cannot run."""
    return pytest.mark.sitl(
        pytest.mark.skipif(bool(why_not_runnable()), reason=why_not_runnable())(test))


@pytest.fixture(scope='module')
def vehicle(tmp_path_factory):
    """A running SITL, the test's link to it, and the URL of its second port."""
    sitl = start_sitl(tmp_path_factory.mktemp('sitl'), HOME)
    try:
        link = open_link(sitl)
        yield link, f'tcp:127.0.0.1:{5762 + 10 * sitl.instance}', 5762 + 10 * sitl.instance
        link.close()
    finally:
        sitl.stop()


@pytest.fixture(scope='module')
def mission_file(tmp_path_factory) -> Path:
    """The letter's case I flown at 10 m/s, as a .waypoints mission."""
    scenario = paper_scenario('I', max_speed_mps=10.0, horizon_s=400.0, num_slots=50)
    result = plan(scenario, SolverSettings(compute_baselines=False))
    return export_mission(result, tmp_path_factory.mktemp('mission') / 'case_I.waypoints',
                          HOME)


def upload(path: Path, url: str, *options: str) -> subprocess.CompletedProcess:
    return subprocess.run(CLI + ['upload', str(path), '--connect', url, *options],
                          capture_output=True, text=True, timeout=120)


@needs_sitl
def test_upload_puts_the_mission_on_the_vehicle_and_reads_it_back(vehicle, mission_file):
    link, url, _ = vehicle
    done = upload(mission_file, url)
    assert done.returncode == 0, done.stderr
    items = read_waypoints(mission_file)
    assert f'{len(items)} items uploaded' in done.stdout
    # Read back independently, on the test's own link.
    stored = download_mission(link)
    assert mismatches(items, stored) == []
    assert len(stored) == len(items) > 5


@needs_sitl
def test_a_qgroundcontrol_plan_file_uploads_the_same_mission(vehicle, mission_file):
    link, url, _ = vehicle
    plan_file = mission_file.with_suffix('.plan')
    scenario = paper_scenario('I', max_speed_mps=10.0, horizon_s=400.0, num_slots=50)
    export_mission(plan(scenario, SolverSettings(compute_baselines=False)), plan_file, HOME)
    done = upload(plan_file, url)
    assert done.returncode == 0, done.stderr
    items = read_mission_file(plan_file)
    assert [item.command for item in items] == [
        item.command for item in read_mission_file(mission_file)]
    assert mismatches(items, download_mission(link)) == []


def refused_item_file(mission_file: Path, folder: Path) -> Path:
    """The mission with item 3 changed to a command ArduCopter does not know."""
    lines = mission_file.read_text().splitlines()
    fields = lines[4].split('\t')
    fields[3] = '31999'
    lines[4] = '\t'.join(fields)
    path = folder / 'unsupported.waypoints'
    path.write_text('\n'.join(lines) + '\n')
    return path


@needs_sitl
def test_a_refused_item_is_one_line_and_exit_2(vehicle, mission_file, tmp_path):
    _, url, _ = vehicle
    done = upload(refused_item_file(mission_file, tmp_path), url)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert 'MAV_MISSION_UNSUPPORTED' in lines[0] and 'item 3' in lines[0]


class CuttingProxy:
    """TCP proxy to ``port`` that closes both sides after ``items`` MISSION_ITEM_INT."""

    def __init__(self, port: int, items: int) -> None:
        self._upstream_port = port
        self._items = items
        self.server = socket.create_server(('127.0.0.1', 0))
        self.port = self.server.getsockname()[1]
        self.forwarded_items = 0
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        client, _ = self.server.accept()
        upstream = socket.create_connection(('127.0.0.1', self._upstream_port))
        parser = mavutil.mavlink.MAVLink(None)
        parser.robust_parsing = True

        def back() -> None:
            try:
                while data := upstream.recv(4096):
                    client.sendall(data)
            except OSError:
                pass
        threading.Thread(target=back, daemon=True).start()
        try:
            while data := client.recv(4096):
                for message in parser.parse_buffer(data) or []:
                    if message.get_type() == 'MISSION_ITEM_INT':
                        self.forwarded_items += 1
                upstream.sendall(data)
                if self.forwarded_items >= self._items:
                    break
        except OSError:
            pass
        for end in (client, upstream, self.server):
            end.close()


@needs_sitl
def test_a_link_that_drops_mid_upload_is_one_line_and_exit_2(vehicle, mission_file):
    _, _, port = vehicle
    proxy = CuttingProxy(port, items=4)
    done = upload(mission_file, f'tcp:127.0.0.1:{proxy.port}', '--timeout', '0.5',
                  '--retries', '2')
    assert proxy.forwarded_items >= 4
    assert done.returncode == 2, done.stdout
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert 'uav-comm-planner: error:' in lines[0]
    assert 'link lost' in lines[0] or 'stopped answering' in lines[0], lines[0]


@pytest.mark.slow
def test_no_vehicle_and_bad_files_are_one_line_and_exit_2(tmp_path, mission_file):
    with socket.create_server(('127.0.0.1', 0)) as unused:
        port = unused.getsockname()[1]
    done = upload(mission_file, f'tcp:127.0.0.1:{port}', '--connect-timeout', '2')
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    text = tmp_path / 'mission.txt'
    text.write_text('not a mission')
    done = upload(text, 'tcp:127.0.0.1:1')
    assert done.returncode == 2 and '.waypoints' in done.stderr
    broken = tmp_path / 'broken.plan'
    broken.write_text('{"mission": {}}')
    done = upload(broken, 'tcp:127.0.0.1:1')
    assert done.returncode == 2 and 'not a QGroundControl .plan' in done.stderr
    done = upload(tmp_path / 'missing.waypoints', 'tcp:127.0.0.1:1')
    assert done.returncode == 2 and 'no such mission file' in done.stderr
