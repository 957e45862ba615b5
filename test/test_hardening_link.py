"""The vehicle link under bad input: URLs checked before anything opens, every connect and
upload bounded by a deadline, a vehicle that loops, answers out of range or reads back wrong
refused with its reason, and nothing left behind (threads, descriptors)."""

from __future__ import annotations

import os
import threading
import time

from fake_vehicle import FakeVehicle
from helpers import run_fuzz_target
import pytest

from uav_comm_planner.errors import InvalidLinkUrlError, InvalidScenarioError, VehicleLinkError
from uav_comm_planner.ros.params import NodeSettings
from uav_comm_planner.tools import cli
from uav_comm_planner.vehicle.mavlink.items import MissionItem, NAV_WAYPOINT
from uav_comm_planner.vehicle.mavlink.link import connect, LinkSettings, upload_and_verify
from uav_comm_planner.vehicle.mavlink.urls import parse_link_url

ITEMS = [MissionItem(NAV_WAYPOINT, 0, x=47.0 + k * 1e-4, y=8.0, z=10.0 * k, current=k == 0)
         for k in range(6)]
QUICK = LinkSettings(timeout_s=0.3, retries=2, busy_retries=1, busy_pause_s=0.05,
                     deadline_s=5.0)


@pytest.mark.parametrize('url, message', [
    ('mission.tlog', "unknown kind 'mission.tlog'"),
    ('csv:/etc/passwd:x=1', "unknown kind 'csv'"),
    ('uds:/tmp/socket', "unknown kind 'uds'"),
    ('tcp:127.0.0.1', 'expected tcp:HOST:PORT'),
    ('tcp:127.0.0.1:0', 'port must be a number in 1..65535'),
    ('udpin:0.0.0.0:65536', 'port must be a number in 1..65535'),
    ('tcp:127.0.0.1:-5', 'port must be a number in 1..65535'),
    ('tcp:bad_host!:5760', 'neither an IPv4 address nor a host name'),
    ('tcp:300.1.1.1:5760', 'neither an IPv4 address nor a host name'),
    ('tcp:127.0.0.1:5760\n', 'control characters'),
    ('/dev/zero', 'a memory device'),
    ('/dev/does-not-exist,57600', 'No such file or directory'),
    ('/dev/null,fast', 'baud rate must be a number'),
    ('/etc/passwd', 'a serial link is a device under /dev/'),
    ('x' * 600, 'longer than 512'),
])
def test_link_urls_are_checked_before_anything_opens(url, message):
    with pytest.raises(InvalidLinkUrlError, match=message):
        parse_link_url(url)


def test_good_link_urls_are_given_to_pymavlink_as_they_were_written():
    for url in ('tcp:127.0.0.1:5760', 'udpin:0.0.0.0:14550', 'udpout:gcs.local:14550',
                'tcpin:0.0.0.0:5760', 'udp:localhost:14550'):
        assert str(parse_link_url(url)) == url


def test_a_serial_link_needs_a_character_device_and_pyserial(tmp_path, monkeypatch):
    from uav_comm_planner.vehicle.mavlink import urls
    with pytest.raises(InvalidLinkUrlError, match='not a character device'):
        parse_link_url('/dev/shm' if os.path.isdir('/dev/shm') else '/dev')
    monkeypatch.setattr(urls, 'serial_available', lambda: False)
    monkeypatch.setattr(urls, 'MEMORY_DEVICES_MAJOR', -1)   # /dev/null stands for a port
    with pytest.raises(InvalidLinkUrlError, match=r"need pyserial.*\[serial\]"):
        parse_link_url('/dev/null,57600')
    monkeypatch.setattr(urls, 'serial_available', lambda: True)
    assert parse_link_url('/dev/null,57600').baud == 57600


def test_node_settings_refuse_a_bad_link_url_when_set():
    with pytest.raises(InvalidLinkUrlError, match='port must be'):
        NodeSettings(mavlink_url='tcp:127.0.0.1:99999')
    with pytest.raises(InvalidScenarioError, match='mavlink_url must be a string'):
        NodeSettings(mavlink_url=5)
    assert NodeSettings(mavlink_url='udpin:0.0.0.0:14550').mavlink_url


def test_upload_refuses_a_bad_url_in_one_line_before_reading_the_mission(tmp_path, capsys):
    fifo = tmp_path / 'm.waypoints'
    os.mkfifo(fifo)     # reading it would block: the URL is refused first
    assert cli.main(['upload', str(fifo), '--connect', 'replay.tlog']) == 2
    out, err = capsys.readouterr()
    assert err.count('\n') == 1 and "unknown kind 'replay.tlog'" in err


@pytest.fixture
def no_leaks():
    """Checks that a test leaves no thread and no file descriptor behind."""
    threads = set(threading.enumerate())
    descriptors = set(os.listdir('/proc/self/fd'))
    yield
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:
        extra_threads = [t for t in threading.enumerate() if t not in threads and t.is_alive()]
        extra_fds = set(os.listdir('/proc/self/fd')) - descriptors
        if not extra_threads and not extra_fds:
            return
        time.sleep(0.05)
    assert not extra_threads and not extra_fds, (extra_threads, extra_fds)


def transfer(behaviour: str, *, settings: LinkSettings = QUICK, connect_timeout_s: float = 2.0,
             **options) -> float:
    """Upload ITEMS to a fake vehicle of ``behaviour``; the seconds it took."""
    with FakeVehicle(behaviour, **options) as vehicle:
        began = time.monotonic()
        try:
            link = connect(vehicle.url, timeout_s=connect_timeout_s)
            try:
                upload_and_verify(link, ITEMS, settings)
            finally:
                link.close()
        finally:
            elapsed = time.monotonic() - began
    return elapsed


def test_a_good_vehicle_takes_the_mission(no_leaks):
    assert transfer('good') < 3.0


@pytest.mark.parametrize('behaviour, message', [
    ('mute', 'no heartbeat from .* within 1 s'),
    ('silent', 'stopped answering after the mission count'),
    ('loop', 'keeps asking for items .* it loops'),
    ('out_of_range', 'asked for item 9 of a 6-item mission'),
    ('wrong_ack', 'the vehicle refused the mission: MAV_MISSION_'),
    ('wrong_count', 'it reports 7 items, 6 were uploaded'),
    ('wrong_item', 'does not hold the mission uploaded'),
])
def test_a_vehicle_that_misbehaves_is_refused_in_time_with_the_reason(
        no_leaks, behaviour, message):
    began = time.monotonic()
    with pytest.raises(VehicleLinkError, match=message):
        transfer(behaviour, connect_timeout_s=1.0)
    assert time.monotonic() - began < QUICK.deadline_s + 1.0


def test_a_vehicle_that_answers_slowly_is_cut_at_the_deadline(no_leaks):
    began = time.monotonic()
    settings = LinkSettings(timeout_s=1.0, retries=1, deadline_s=1.0)
    with pytest.raises(VehicleLinkError, match='did not finish within its deadline of 1 s'):
        transfer('slow', settings=settings, delay_s=0.3)
    assert time.monotonic() - began < 3.0


@pytest.mark.parametrize('changes', [{'timeout_s': 0.0}, {'deadline_s': float('nan')},
                                     {'retries': -1}, {'busy_retries': True},
                                     {'timeout_s': float('inf')}])
def test_link_settings_are_checked(changes):
    with pytest.raises(VehicleLinkError, match='link setting'):
        LinkSettings(**changes)


def test_the_vehicle_thread_stops_at_once_even_while_it_waits_for_a_heartbeat(no_leaks):
    from uav_comm_planner.vehicle.geodesy import Home
    from uav_comm_planner.vehicle.mavlink.telemetry import VehicleBridge

    with FakeVehicle('mute') as vehicle:
        bridge = VehicleBridge(vehicle.url, Home(47.0, 8.0, 400.0), lambda event: None,
                               connect_timeout_s=30.0)
        time.sleep(0.5)                      # connected, waiting for the heartbeat
        began = time.monotonic()
        bridge.stop()
        assert time.monotonic() - began < 2.0
        assert not bridge._thread.is_alive()


def test_reconnection_attempts_back_off(monkeypatch, no_leaks):
    from uav_comm_planner.vehicle.geodesy import Home
    from uav_comm_planner.vehicle.mavlink import telemetry

    attempts, events = [], []

    def refused(url, **options):
        attempts.append(time.monotonic())
        raise VehicleLinkError(f'cannot open {url!r}: refused')
    monkeypatch.setattr(telemetry, 'connect', refused)
    monkeypatch.setattr(telemetry, 'RECONNECT_PAUSE_S', 0.05)
    bridge = telemetry.VehicleBridge('tcp:127.0.0.1:9', Home(47.0, 8.0, 400.0), events.append)
    time.sleep(1.6)
    bridge.stop()
    # 0.05, 0.1, 0.2, 0.4, 0.8 s: six attempts at most, not one every 0.05 s.
    assert 3 <= len(attempts) <= 6, len(attempts)
    gaps = [b - a for a, b in zip(attempts, attempts[1:])]
    assert all(later > earlier for earlier, later in zip(gaps, gaps[1:]))
    assert len(events) == 1 and 'retrying' in events[0].message


def test_a_short_seeded_run_of_the_fake_vehicle_fuzzer_finds_nothing(capsys):
    status = run_fuzz_target('fuzz_vehicle', ['--cases', '60', '--seed', '7'])
    out = capsys.readouterr().out
    assert status == 0, out
    assert '0 failures' in out and 'api good' in out
