"""``uav-comm-planner upload`` against PX4 SITL (``../shared/sitl/px4``, its SIH quadrotor).

PX4 answers on UDP only once it has heard a sender, keeps no home row in its missions (seq 0
is the takeoff) and reads frame 3 back as 6: the upload sends a heartbeat first, leaves the
home row out and compares frames with their _INT twins. The command line takes PX4's
ground-station port (``udpout:``, one sender per PX4 run); the test reads the mission back
over PX4's onboard port.
"""

from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import sys

import pytest

from devtools.px4_sitl import runnable_copy
from uav_comm_planner.errors import VehicleLinkError
from uav_comm_planner.vehicle.mavlink.files import read_mission_file
from uav_comm_planner.vehicle.mavlink.items import mismatches, MissionItem
from uav_comm_planner.vehicle.mavlink.link import (connect, download_mission, has_home_row,
                                                   upload_and_verify)

RUN_PX4 = Path(__file__).resolve().parents[2] / 'shared' / 'sitl' / 'px4' / 'run_px4.sh'
CLI = [sys.executable, '-m', 'uav_comm_planner.tools.cli']


def why_px4_cannot_run() -> str:
    if not RUN_PX4.is_file():
        return f'no PX4 SITL at {RUN_PX4}'
    if os.uname().machine != 'x86_64':
        return 'the PX4 SITL binary is built for x86_64'
    return ''


pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(bool(why_px4_cannot_run()), reason=why_px4_cannot_run())]


@pytest.fixture(scope='module')
def px4(tmp_path_factory):
    """A PX4 SITL on a free instance; yields (ground-station URL, onboard URL)."""
    instance = next((n for n in range(9, -1, -1) if not Path(f'/tmp/px4_lock-{n}').exists()),
                    None)
    if instance is None:
        pytest.fail('every PX4 instance 0..9 is taken (/tmp/px4_lock-N)')
    script = runnable_copy(RUN_PX4, tmp_path_factory.mktemp('px4_copy'))
    work = tmp_path_factory.mktemp('px4')
    process = subprocess.Popen(['sh', str(script), str(instance), '4', str(work)],
                               env={**os.environ, 'PX4_PARAM_SDLOG_MODE': '-1'},
                               stdout=open(work / 'px4.log', 'w'), stderr=subprocess.STDOUT)
    try:
        yield (f'udpout:127.0.0.1:{18570 + instance}', f'udpin:127.0.0.1:{14540 + instance}')
    finally:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(20)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def test_upload_puts_a_px4_plan_on_px4_and_reads_it_back(px4, tmp_path):
    ground_station, onboard = px4
    mission = tmp_path / 'm.plan'
    planned = subprocess.run(CLI + ['plan', '--case', 'I', '--speed', '5', '--horizon', '600',
                                    '--slots', '150', '--firmware', 'px4', '--wp-speed', '5',
                                    '--home', '47.397742,8.545594,489', '--mission',
                                    str(mission)], capture_output=True, text=True, timeout=120)
    assert planned.returncode == 0, planned.stderr
    uploaded = subprocess.run(CLI + ['upload', str(mission), '--connect', ground_station],
                              capture_output=True, text=True, timeout=180)
    assert uploaded.returncode == 0, uploaded.stderr
    assert 'read back identical' in uploaded.stdout
    # PX4 holds the file's items after home: the takeoff is its seq 0.
    link = connect(onboard, timeout_s=60.0)
    try:
        assert not has_home_row(link)
        held = download_mission(link)
    finally:
        link.close()
    items = read_mission_file(mission)
    assert len(held) == len(items) - 1
    assert mismatches(items[1:], held, home_row=False) == []


def test_a_mission_px4_refuses_is_one_error_with_the_item(px4):
    _, onboard = px4
    link = connect(onboard, timeout_s=60.0)
    try:
        held = download_mission(link)
        unknown = MissionItem(command=31999, frame=3, params=(0.0, 0.0, 0.0, 0.0),
                              x=47.3977, y=8.5456, z=20.0)
        # Home row first, as the files hold missions; the bad item is PX4's seq 1.
        with pytest.raises(VehicleLinkError, match=r'refused the mission at item 1'):
            upload_and_verify(link, [held[0], held[0], unknown])
    finally:
        link.close()
