"""The link going down in the middle of something, against the fake vehicle: an upload cut on
any transport (EOF, a port's error, a silence) is a typed loss, said once and sent again on
the next connection; a refusal is not sent again."""

from __future__ import annotations

import errno
import time

from fake_vehicle import Events, FakeVehicle
from helpers import two_node_stream_reference
import pytest

from uav_comm_planner.errors import VehicleLinkError, VehicleLinkLostError
from uav_comm_planner.tools import cli
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.mavlink import telemetry
from uav_comm_planner.vehicle.mavlink.files import write_mission_file
from uav_comm_planner.vehicle.mavlink.items import MissionItem, NAV_WAYPOINT
from uav_comm_planner.vehicle.mavlink.link import (connect, LinkSettings, LinkWatch,
                                                   upload_and_verify)
from uav_comm_planner.vehicle.mavlink.telemetry import Position, SILENCE_S

HOME = Home(47.0, 8.0, 400.0)
ITEMS = [MissionItem(NAV_WAYPOINT, 0, x=47.0 + k * 1e-4, y=8.0, z=10.0 * k, current=k == 0)
         for k in range(6)]


def wait_position(events: Events) -> None:
    events.wait(lambda: any(isinstance(e, Position) for _, e in events.seen), 'position')


def counts(vehicle: FakeVehicle, kind: str) -> int:
    return sum(1 for entry in vehicle.log if entry[0] == kind)


# The link: every transport's loss is a VehicleLinkLostError.

def _eof(vehicle, link) -> None:
    vehicle.hang_up_on = 'MISSION_ITEM_INT'         # TCP: the vehicle closes the connection


def _port_error(vehicle, link) -> None:
    # A serial port whose device went away: pyserial's SerialException is an OSError (EIO).
    receive, asked = link.recv, []

    def failing(n=None):
        if any(entry[0] == 'MISSION_ITEM_INT' for entry in vehicle.log):
            asked.append(n)
            raise OSError(errno.EIO, 'Input/output error')
        return receive(n)
    link.recv = failing


def _silence(vehicle, link) -> None:
    # UDP or a radio out of range: nothing fails, nothing more arrives.
    vehicle.quiet_on = 'MISSION_ITEM_INT'
    link.watch = LinkWatch(silence_s=SILENCE_S)


@pytest.mark.parametrize('cut, said', [(_eof, 'closed the TCP connection'),
                                       (_port_error, 'Input/output error'),
                                       (_silence, 'nothing heard from the vehicle for 2 s')])
def test_an_upload_cut_on_any_transport_is_a_link_loss_not_a_refusal(cut, said):
    settings = LinkSettings(timeout_s=2.0, retries=5)
    with FakeVehicle('good') as vehicle:
        link = connect(vehicle.url, timeout_s=5.0)
        try:
            cut(vehicle, link)
            began = time.monotonic()
            with pytest.raises(VehicleLinkLostError, match=said):
                upload_and_verify(link, ITEMS, settings)
            took = time.monotonic() - began
        finally:
            link.close()
    print(f'{cut.__name__}: lost after {took:.2f} s')
    # Found by the cut itself or the silence, not by the retries (5 x 2 s).
    assert took < SILENCE_S + 1.0


def test_the_command_line_upload_finds_a_silent_link_in_the_silence_not_the_retries(
        tmp_path, capsys):
    path = write_mission_file(ITEMS, tmp_path / 'mission.waypoints', HOME)
    with FakeVehicle('good') as vehicle:
        vehicle.quiet_on = 'MISSION_ITEM_INT'
        code = cli.main(['upload', str(path), '--connect', vehicle.url, '--timeout', '2',
                         '--retries', '5', '--max-home-distance', 'inf'])
        took = time.monotonic() - vehicle.quiet_at
    error = capsys.readouterr().err.strip()
    print(f'silent link found {took:.2f} s after it went quiet: {error}')
    assert code == 2 and '\n' not in error
    assert 'nothing heard from the vehicle for 2 s' in error
    assert took < SILENCE_S + 1.0                   # the retries alone would take 10 s
    assert counts(vehicle, 'MISSION_COUNT') == 1


def test_a_vehicle_that_heartbeats_but_never_answers_is_still_a_refusal():
    settings = LinkSettings(timeout_s=0.3, retries=2)
    with FakeVehicle('silent') as vehicle:
        link = connect(vehicle.url, timeout_s=5.0)
        link.watch = LinkWatch(silence_s=SILENCE_S)
        try:
            with pytest.raises(VehicleLinkError, match='stopped answering') as raised:
                upload_and_verify(link, ITEMS, settings)
        finally:
            link.close()
    assert not isinstance(raised.value, VehicleLinkLostError)


def test_an_item_answered_twice_is_not_the_end_of_the_upload():
    # ArduPilot at a simulator's speed-up asks for an item again before our answer arrives;
    # the second answer meets it expecting the next item: INVALID_SEQUENCE, and it goes on.
    with FakeVehicle('impatient') as vehicle:
        link = connect(vehicle.url, timeout_s=5.0)
        try:
            upload_and_verify(link, ITEMS, LinkSettings(timeout_s=1.0, retries=2))
        finally:
            link.close()
    assert [item.seq for item in vehicle.stored] == list(range(len(ITEMS)))
    assert counts(vehicle, 'MISSION_ITEM_INT') > len(ITEMS)      # the duplicates answered


# The bridge: a cut upload is said once and sent again once the link is back.

def test_an_eof_while_the_current_item_is_set_is_a_loss_and_the_upload_is_sent_again():
    events = Events()
    with FakeVehicle('good', positions=True) as vehicle:
        vehicle.hang_up_on = 'MISSION_SET_CURRENT'
        bridge = telemetry.VehicleBridge(vehicle.url, HOME, events)
        try:
            wait_position(events)
            bridge.upload(ITEMS, current_seq=2, tag='replan')
            events.wait(lambda: events.links('uploaded'), 'upload on the next connection')
        finally:
            bridge.stop()
    (_, lost), = events.links('lost')
    assert 'closed the TCP connection (EOF)' in lost.message
    assert events.links('error') == []
    (_, uploaded), = events.links('uploaded')
    assert uploaded.tag == 'replan' and 'current item 2' in uploaded.message
    assert vehicle.connections == 2
    assert counts(vehicle, 'MISSION_COUNT') == 2 and counts(vehicle, 'MISSION_SET_CURRENT') == 2


def test_an_upload_the_link_goes_silent_in_is_lost_within_the_silence_and_sent_again():
    events = Events()
    with FakeVehicle('good', positions=True) as vehicle:
        vehicle.quiet_on = 'MISSION_ITEM_INT'
        bridge = telemetry.VehicleBridge(vehicle.url, HOME, events)
        try:
            wait_position(events)
            bridge.upload(ITEMS, tag='plan')
            events.wait(lambda: events.links('lost'), 'loss of the silent link')
            vehicle.quiet = False
            events.wait(lambda: events.links('uploaded'), 'upload on the next connection')
        finally:
            bridge.stop()
    (lost_at, lost), = events.links('lost')
    print(f'silence during the upload found {lost_at - vehicle.quiet_at:.2f} s after it began')
    assert lost_at - vehicle.quiet_at < SILENCE_S + 1.0
    assert 'nothing heard from the vehicle' in lost.message
    assert events.links('error') == []
    (_, uploaded), = events.links('uploaded')
    assert uploaded.tag == 'plan' and len(vehicle.stored) == len(ITEMS)


def test_stopping_the_bridge_ends_an_upload_at_once_and_says_nothing():
    events = Events()
    with FakeVehicle('silent', positions=True) as vehicle:
        bridge = telemetry.VehicleBridge(vehicle.url, HOME, events)
        try:
            wait_position(events)
            bridge.upload(ITEMS, tag='plan')
            events.wait(lambda: counts(vehicle, 'MISSION_COUNT') >= 1, 'upload begun')
        finally:
            began = time.monotonic()
            bridge.stop()
            took = time.monotonic() - began
    print(f'stopped during an upload in {took:.2f} s')
    assert took < 1.0 and not bridge._thread.is_alive()
    assert events.links('lost') == [] and events.links('error') == []


# Wind estimates across a reconnection.

def test_winds_heard_before_a_reconnections_first_position_keep_the_smoothing():
    from uav_comm_planner.mission.wind import WindEstimate
    from uav_comm_planner.vehicle.mavlink.telemetry import Wind

    events = Events()
    with FakeVehicle('good', positions=True) as vehicle:
        vehicle.wind = (5.0, 0.0)           # from the north: the air moves south
        vehicle.positions_after_s = 0.5     # each connection: winds first, then positions
        bridge = telemetry.VehicleBridge(vehicle.url, HOME, events)
        try:
            wait_position(events)
            time.sleep(1.5)
            vehicle.wind = (5.0, 90.0)      # from the east
            cut_at = time.monotonic()
            vehicle.hang_up()
            events.wait(lambda: any(isinstance(e, Position) for t, e in events.seen
                                    if t > cut_at), 'position after the reconnection')
            time.sleep(1.0)
        finally:
            bridge.stop()
    before = [e.time_s for t, e in events.seen if isinstance(e, Position) and t < cut_at]
    winds = [e for _, e in events.seen if isinstance(e, Wind)]
    after = [w for w in winds if w.east_mps < -1.0]
    assert len(events.links('connected')) == 2 and after
    times = [w.time_s for w in winds]
    assert times == sorted(times) and min(w.time_s for w in after) >= max(before)
    estimate = WindEstimate(10.0)
    for wind in winds:
        estimate.add(wind.time_s, wind.east_mps, wind.north_mps)
    east, north = estimate.velocity_mps
    print(f'{len(after)} winds from the east after the reconnection: estimate east {east:.2f}, '
          f'north {north:.2f} m/s')
    # About 2 s of the new wind (the reconnection's 1.5 s included) against a 10 s time
    # constant: closer to the old wind than to the new one (a reset would give the new one).
    assert 0.1 < abs(east + 5.0) - abs(east) and abs(north + 5.0) < abs(north)
    assert -2.5 < east < -0.1


# A stream's fallback and a new mission's upload, in order.

@pytest.fixture(scope='module')
def reference():
    return two_node_stream_reference()


@pytest.mark.parametrize('replan', [False, True], ids=['new plan', 'replan in flight'])
def test_a_streams_fallback_never_acts_on_the_mission_uploaded_after_it(reference, replan):
    from uav_comm_planner.vehicle.mavlink.guided import COPTER_MODES, StreamJob, TargetStream

    events = Events()
    with FakeVehicle('good', positions=True) as vehicle:
        vehicle.mode = COPTER_MODES['GUIDED']
        stream = TargetStream(HOME, events)
        bridge = telemetry.VehicleBridge(vehicle.url, HOME, events, stream=stream)
        try:
            wait_position(events)
            bridge.upload(ITEMS, tag='old')
            events.wait(lambda: events.links('uploaded'), 'the old mission uploaded')
            now_s = [e for _, e in events.seen if isinstance(e, Position)][-1].time_s
            # The old plan's fallback resumes its own mission at item 4.
            stream.start(StreamJob(reference, now_s, 100.0, 'auto', lambda elapsed_s: 4))
            events.wait(lambda: stream.targets_sent >= 5, 'targets streamed')
            logged = len(vehicle.log)
            # As VehicleAdapter.fly does: the stream stopped, then the new mission queued.
            if replan:
                stream.stop('a new plan is in force', resume_seq=2, mission='new')
                bridge.upload(ITEMS[:5], current_seq=2, tag='new')
            else:
                stream.stop('a new plan is in force')
                bridge.upload(ITEMS[:5], tag='new')
            events.wait(lambda: len(events.links('uploaded')) == 2 and not stream.active,
                        'the new mission uploaded and the stream stopped')
            time.sleep(0.3)
        finally:
            bridge.stop()
    log = vehicle.log[logged:]
    count = log.index(('MISSION_COUNT', 5))
    auto = ('SET_MODE', COPTER_MODES['AUTO'])
    print(log[:count + 1], [entry for entry in log[count:] if entry[0] != 'MISSION_ITEM_INT'])
    if replan:
        # Nothing for the old mission; AUTO at the new mission's item 2 once it is on board.
        assert auto not in log[:count] and ('MISSION_SET_CURRENT', 4) not in log
        assert ('MISSION_SET_CURRENT', 2) in log[count:] and auto in log[count:]
    else:
        # The old plan's fallback lands on the old mission, before the new upload starts.
        assert ('MISSION_SET_CURRENT', 4) in log[:count] and auto in log[:count]
        assert not any(entry[0] == 'MISSION_SET_CURRENT' for entry in log[count:])
    (_, stopped), = [(t, e) for t, e in events.seen if getattr(e, 'kind', '') == 'stopped']
    assert f'mission item {2 if replan else 4}' in stopped.message


# The link made again while an upload is pending.

@pytest.mark.parametrize('name, value', [('home_distance_limit_m', 2000.0),
                                         ('flight_mode', 'stream')])
def test_a_link_made_again_mid_upload_uploads_the_plan_again_and_the_clock_starts(
        harness, name, value):
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    from uav_comm_planner.vehicle.mavlink.guided import COPTER_MODES

    with FakeVehicle('silent', positions=True) as vehicle:
        vehicle.where = (HOME.latitude_deg, HOME.longitude_deg, 100.0)    # at q0, at rest
        vehicle.mode = COPTER_MODES['AUTO']
        # The home parameters: a silent vehicle does not tell its home either.
        # A plan the vehicle flies (its default 10 m/s).
        h = harness(mavlink_url=vehicle.url, home_latitude_deg=HOME.latitude_deg,
                    home_longitude_deg=HOME.longitude_deg, home_altitude_m=HOME.altitude_m,
                    max_speed_mps=10.0, horizon_s=300.0)
        h.published(1)
        h.spin_until(lambda: counts(vehicle, 'MISSION_COUNT') >= 1, 'upload begun')
        assert h.node.vehicle.upload_pending
        answer = h.call('set_parameters', SetParameters.Request(
            parameters=[Parameter(name, value=value).to_parameter_msg()]))
        assert answer.results[0].successful
        vehicle.reset('good')               # the new link's vehicle answers
        h.spin_until(lambda: h.node.progress.started, 'mission clock started at q0')
        assert not h.node.vehicle.upload_pending and h.node.vehicle.uploads_verified == 1
        assert h.node.stats.plans_published == 1          # the same plan, not a new one
        assert vehicle.connections == 2 and len(vehicle.stored) > 0


# The reconnection backoff, in autopilot time.

def test_the_reconnection_backoff_counts_autopilot_time_at_a_simulators_speedup():
    from uav_comm_planner.vehicle.mavlink.telemetry import (MIN_RECONNECT_PAUSE_S,
                                                            reconnect_pause_s)

    # 1 s doubling to 8 s of autopilot time, at the clock rate the last connection showed.
    assert [reconnect_pause_s(k, None) for k in range(5)] == [1.0, 2.0, 4.0, 8.0, 8.0]
    assert reconnect_pause_s(3, 20.0) == pytest.approx(0.4)
    assert reconnect_pause_s(0, 1000.0) == MIN_RECONNECT_PAUSE_S
    events = Events()
    with FakeVehicle('good', positions=True) as vehicle:
        vehicle.speedup = 10.0
        bridge = telemetry.VehicleBridge(vehicle.url, HOME, events)
        try:
            wait_position(events)
            time.sleep(1.5)                 # the clock rate measured over 1 s and more
            vehicle.hang_up()
            events.wait(lambda: len(events.links('connected')) == 2, 'reconnection')
        finally:
            bridge.stop()
    (lost_at, _), = events.links('lost')
    again_at = events.links('connected')[1][0]
    print(f'connected again {again_at - lost_at:.2f} s (wall) after the loss at speed-up 10')
    assert again_at - lost_at < 0.5         # 1 s of autopilot time, 0.1 s of wall clock


def test_the_watch_counts_silence_only_while_the_link_is_read(monkeypatch):
    from types import SimpleNamespace

    from uav_comm_planner.vehicle.mavlink import link as link_module

    now = [100.0]
    monkeypatch.setattr(link_module.time, 'monotonic', lambda: now[0])
    watch, link = LinkWatch(silence_s=2.0), SimpleNamespace(mav_count=7)

    def look_until_lost(step_s: float) -> float:
        began = now[0]
        with pytest.raises(VehicleLinkLostError, match='nothing heard .* for 2 s'):
            for _ in range(1000):
                now[0] += step_s
                watch.check(link)
        return now[0] - began
    watch.check(link)
    now[0] += 30.0                  # the process stalled 30 s: half a second of silence
    watch.check(link)
    link.mav_count = 9              # a message: the silence starts again
    watch.check(link)
    took = look_until_lost(0.1)
    assert took == pytest.approx(2.1)
    stopping = LinkWatch(should_stop=lambda: True)
    with pytest.raises(VehicleLinkLostError, match='being stopped'):
        stopping.check(link)
