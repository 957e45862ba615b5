"""Faults of the link and of the position, without SITL: a link the vehicle closes or that goes
silent (said once, reconnected, no pymavlink flood), a mission for another place refused
before upload, the mission clock started only when the vehicle holds q0 in AUTO or GUIDED,
and a short glitch of the position that never replans."""

from __future__ import annotations

from dataclasses import dataclass
import math
import time

from fake_vehicle import Events, FakeVehicle
import numpy as np
import pytest

from uav_comm_planner import paper_scenario, plan, SolverSettings
from uav_comm_planner.core.receding import (FlownSlots, lengthened, mission_rates_flown,
                                            rest_of_mission)
from uav_comm_planner.errors import InfeasibleHorizonError, MissionTooFarError
from uav_comm_planner.mission.pipeline import plan_mission
from uav_comm_planner.mission.progress import off_plan, planned_position
from uav_comm_planner.mission.request import InFlight, MissionRequest
from uav_comm_planner.ros.battery import BatteryWatch
from uav_comm_planner.ros.flight import MissionFlight, OFF_PLAN_CONFIRM_S, SOURCE_TELEMETRY
from uav_comm_planner.ros.params import NodeSettings, PlannerConfig
from uav_comm_planner.tools import cli
from uav_comm_planner.vehicle.geodesy import enu_to_geodetic, Home
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink import telemetry
from uav_comm_planner.vehicle.mavlink.home import (distance_m, EARTH_RADIUS_M,
                                                   mission_far_from_vehicle)
from uav_comm_planner.vehicle.mavlink.items import MissionItem, NAV_TAKEOFF, NAV_WAYPOINT
from uav_comm_planner.vehicle.mavlink.telemetry import HomeReport, Position, SILENCE_S

HOME = Home(47.0, 8.0, 400.0)
CANBERRA = (-35.363262, 149.165237, 584.0)
ITEMS = [MissionItem(NAV_WAYPOINT, 0, x=47.0 + k * 1e-4, y=8.0, z=10.0 * k, current=k == 0)
         for k in range(6)]


def test_a_link_the_vehicle_closes_is_said_once_and_made_again_without_a_flood(capfd):
    events = Events()
    with FakeVehicle('good', positions=True) as vehicle:
        bridge = telemetry.VehicleBridge(vehicle.url, HOME, events)
        try:
            events.wait(lambda: any(isinstance(e, Position) for _, e in events.seen),
                        'position')
            vehicle.hang_up()
            events.wait(lambda: len(events.links('connected')) >= 2, 'reconnection')
            time.sleep(0.5)
        finally:
            bridge.stop()
    lost = events.links('lost')
    assert len(lost) == 1 and 'closed the TCP connection (EOF)' in lost[0][1].message
    assert vehicle.connections >= 2
    out, err = capfd.readouterr()
    assert 'EOF on TCP socket' not in out + err


def test_a_silent_link_is_found_within_3_s_and_the_gap_is_said():
    events = Events()
    with FakeVehicle('good', positions=True) as vehicle:
        bridge = telemetry.VehicleBridge(vehicle.url, HOME, events)
        try:
            events.wait(lambda: any(isinstance(e, Position) for _, e in events.seen),
                        'position')
            vehicle.quiet = True
            quiet_at = time.monotonic()
            events.wait(lambda: events.links('lost'), 'loss of the silent link')
            time.sleep(1.0)
            vehicle.quiet = False
            events.wait(lambda: events.links('gap'), 'telemetry gap')
        finally:
            bridge.stop()
    (lost_at, lost), = events.links('lost')
    print(f'silence found {lost_at - quiet_at:.2f} s after the vehicle went quiet')
    assert SILENCE_S - 0.1 <= lost_at - quiet_at < 3.0     # heard last just before quiet
    assert 'nothing heard from the vehicle' in lost.message
    (_, gap), = events.links('gap')
    assert gap.seconds >= SILENCE_S and 'the link was down' in gap.message


def test_the_bridge_follows_the_vehicle_home_and_refuses_a_mission_for_another_place():
    events = Events()
    with FakeVehicle('good', positions=True, home=CANBERRA) as vehicle:
        bridge = telemetry.VehicleBridge(vehicle.url, None, events)
        try:
            events.wait(lambda: any(isinstance(e, Position) for _, e in events.seen),
                        'position in the vehicle frame')
            bridge.upload(ITEMS, tag='zurich-ish')
            events.wait(lambda: events.links('error'), 'refusal')
        finally:
            bridge.stop()
    homes = [e for _, e in events.seen if isinstance(e, HomeReport)]
    assert homes[0].adopted and homes[0].home == Home(*CANBERRA)
    first = next(e for _, e in events.seen if isinstance(e, Position))
    assert math.hypot(first.east_m, first.north_m) < 0.1       # at the vehicle's home
    (_, refused), = events.links('error')
    assert refused.tag == 'zurich-ish' and 'mission upload refused' in refused.message
    assert '(47.0000000, 8.0000000)' in refused.message
    assert '(-35.3632620, 149.1652370)' in refused.message
    assert vehicle.stored == [], 'the mission was uploaded'


def test_distances_are_great_circle_metres():
    assert distance_m((0.0, 0.0), (1.0, 0.0)) == pytest.approx(math.pi / 180 * EARTH_RADIUS_M,
                                                               rel=1e-12)
    # Near home, against the planning frame's own conversion (an independent computation).
    latitude, longitude, _ = enu_to_geodetic(np.array([600.0]), np.array([-800.0]), 0.0, HOME)
    gap = distance_m((HOME.latitude_deg, HOME.longitude_deg), (latitude[0], longitude[0]))
    assert gap == pytest.approx(1000.0, rel=5e-3)


def test_the_mission_check_looks_at_home_and_the_first_waypoint():
    takeoff = MissionItem(NAV_TAKEOFF, 3, z=10.0)
    far_q0 = MissionItem(NAV_WAYPOINT, 3, x=47.02, y=8.0, z=10.0)
    mission = [ITEMS[0], takeoff, far_q0]
    # Home at the vehicle's, its first waypoint (the takeoff has no place) 2.2 km away.
    reason = mission_far_from_vehicle(mission, HOME, None, 1000.0)
    assert "the mission's first waypoint (47.0200000, 8.0000000) is 2224 m" in reason
    assert mission_far_from_vehicle(mission, HOME, None, 3000.0) == ''
    # Without a home, the vehicle's position stands for it; with neither, nothing to check.
    assert 'position' in mission_far_from_vehicle(ITEMS, None, (-35.0, 149.0), 1000.0)
    assert mission_far_from_vehicle(ITEMS, None, None, 1000.0) == ''


def test_upload_refuses_a_mission_for_another_place_in_one_line(tmp_path, capsys):
    mission = tmp_path / 'm.waypoints'
    mission.write_text('QGC WPL 110\n' + ''.join(
        f'{k}\t{int(k == 0)}\t{0 if k == 0 else 3}\t16\t0\t0\t0\t0\t{47 + k * 1e-4:.7f}\t'
        f'8.0000000\t{10.0 * k:.1f}\t1\n' for k in range(4)))
    with FakeVehicle('good', home=CANBERRA) as vehicle:
        argv = ['upload', str(mission), '--connect', vehicle.url, '--connect-timeout', '5']
        assert cli.main(argv) == 2
        _, err = capsys.readouterr()
        assert err.count('\n') == 1 and 'mission refused before upload' in err
        assert '(47.0000000, 8.0000000)' in err and '(-35.3632620, 149.1652370)' in err
        assert vehicle.stored == []
        # A limit wide enough takes it; a limit that is no distance is refused first.
        assert cli.main(argv + ['--max-home-distance', '2e7']) == 0
        assert len(vehicle.stored) == 4
        assert cli.main(argv + ['--max-home-distance', 'nan']) == 2
        _, err = capsys.readouterr()
        assert 'home distance limit must be a positive number' in err
    with pytest.raises(MissionTooFarError):
        raise MissionTooFarError('typed')


# The mission clock and the replans, on MissionFlight with a stand-in node.

SCENARIO = paper_scenario('I', max_speed_mps=10.0, horizon_s=400.0, num_slots=100)


@dataclass
class StandInVehicle:
    """The VehicleAdapter state MissionFlight reads."""

    linked: bool = True
    upload_pending: bool = False
    mode: str | None = 'AUTO'
    speed_mps: float = 0.0

    @property
    def flying_mission(self) -> bool:
        return self.mode in telemetry.MISSION_MODES


class Logger:
    def info(self, message: str) -> None:
        pass


class StandInNode:
    """What MissionFlight asks of its node, recording the replans and the refusals."""

    def __init__(self) -> None:
        self.config = PlannerConfig(SCENARIO, SolverSettings(compute_baselines=False),
                                    NodeSettings(vehicle_aware=False))
        self.vehicle = StandInVehicle()
        self.vehicle.battery = BatteryWatch(self)
        self.submitted: list[tuple[str, object]] = []
        self.refused: list[str] = []

    def get_logger(self) -> Logger:
        return Logger()

    def submit(self, reason: str, in_flight=None) -> None:
        self.submitted.append((reason, in_flight))

    def refuse(self, request: str, message: str, *, nodes=None) -> None:
        self.refused.append(message)

    def clock_s(self) -> float:
        return 0.0


@pytest.fixture(scope='module')
def result():
    return plan(SCENARIO, SolverSettings(compute_baselines=False))


def flight_with(result) -> tuple[MissionFlight, StandInNode]:
    node = StandInNode()
    flight = MissionFlight(node)
    flight.progress.begin(SCENARIO, result)
    return flight, node


def test_the_clock_starts_when_the_vehicle_holds_q0_in_auto_not_in_the_climb(result):
    flight, node = flight_with(result)
    x, y = SCENARIO.start_m
    samples = [  # (mode, height, speed): none of these starts the clock
        ('BRAKE', 100.0, 0.0),      # holding q0, but not flying the mission
        ('LOITER', 100.0, 0.0),
        ('AUTO', 97.6, 2.5),        # climbing, 2.4 m below: the old rule started here
        ('AUTO', 99.5, 1.2),        # at the altitude, still moving
        ('GUIDED', 102.0, 0.1),     # 2 m above
    ]
    for k, (mode, height, speed) in enumerate(samples):
        node.vehicle.mode, node.vehicle.speed_mps = mode, speed
        assert flight.on_position(10.0 + 0.1 * k, x, y, source=SOURCE_TELEMETRY,
                                  height_m=height)
        assert not flight.progress.started, (mode, height, speed)
    node.vehicle.upload_pending = True
    node.vehicle.mode, node.vehicle.speed_mps = 'AUTO', 0.2
    flight.on_position(11.0, x, y, source=SOURCE_TELEMETRY, height_m=99.8)
    assert not flight.progress.started        # the plan is not on the vehicle yet
    node.vehicle.upload_pending = False
    flight.on_position(11.1, x + 1.0, y, source=SOURCE_TELEMETRY, height_m=99.8)
    assert flight.progress.started and flight.progress.segments[0].start_s == 11.1
    # With a link, a uav_pose never starts the clock.
    other, other_node = flight_with(result)
    other.on_position(5.0, x, y, source='uav_pose')
    assert not other.progress.started


def on_plan(result, elapsed_s: float) -> tuple[float, float]:
    return tuple(planned_position(result, elapsed_s))


def test_a_33_m_glitch_for_0_2_s_is_refused_once_and_never_replanned_from(result):
    flight, node = flight_with(result)
    flight.progress.start_clock(0.0)
    times = np.round(np.arange(1, 400) * 0.1, 6)         # 10 Hz, autopilot seconds
    for t in times:
        x, y = on_plan(result, t)
        if 20.0 <= t < 20.2:                             # 33 m north for 0.2 s
            y += 33.0
        flight.on_position(t, x, y, source=SOURCE_TELEMETRY, height_m=100.0)
    assert flight.positions_refused == 2
    assert len(node.refused) == 1 and 'farther than the UAV flies' in node.refused[0]
    assert node.submitted == []
    assert not np.any(np.abs(flight.track.samples[:, 2]
                             - [on_plan(result, t)[1] for t in flight.track.samples[:, 0]])
                      > 1e-9)


def test_a_lasting_deviation_replans_once_it_has_lasted(result):
    flight, node = flight_with(result)
    flight.progress.start_clock(0.0)
    deviation_at = 30.0
    off_at = None
    for t in np.round(np.arange(1, 600) * 0.1, 6):
        x, y = on_plan(result, t)
        if t >= deviation_at:   # drifting north at 4 m/s
            y += 4.0 * (t - deviation_at)
        if off_at is None and off_plan(result, t, (x, y), distance_m=20.0, delay_s=5.0):
            off_at = t
        flight.on_position(t, x, y, source=SOURCE_TELEMETRY, height_m=100.0)
        if node.submitted:
            break
    assert flight.positions_refused == 0
    assert len(node.submitted) == 1
    print(f'off the plan from {off_at:.1f} s, replanned at {t:.1f} s')
    assert off_at + OFF_PLAN_CONFIRM_S - 0.1 <= t <= off_at + OFF_PLAN_CONFIRM_S + 0.15


# A replan that cannot keep qF in time lengthens the mission instead of being refused.

def test_a_rest_out_of_reach_is_lengthened_by_the_fewest_slots_that_reach_qf():
    mission = SCENARIO                              # 100 slots of 4 s at 10 m/s to (2000, 0)
    flown = FlownSlots(np.full((3, 80), 0.01), np.zeros((80, 2)))
    position = (-200.0, 0.0)                        # 2200 m from qF, 20 slots (21 legs) left
    longer = lengthened(mission, position, flown)
    rest_slots = longer.num_slots - flown.num_slots
    print(f'lengthened from {mission.num_slots} to {longer.num_slots} slots')
    assert longer.slot_s == pytest.approx(mission.slot_s, rel=1e-12)
    # Independent: the scenario's own reachability check, one slot fewer and as lengthened.
    rest_of_mission(longer, position, flown)
    with pytest.raises(InfeasibleHorizonError, match='goal unreachable'):
        rest_of_mission(longer.replace(num_slots=longer.num_slots - 1,
                                       horizon_s=(longer.num_slots - 1) * longer.slot_s),
                        position, flown)
    assert (rest_slots + 1) * 10.0 * 4.0 >= 2200.0 > rest_slots * 10.0 * 4.0
    # A mission that reaches qF is itself; qF farther than the mission's own length again
    # stays refused.
    assert lengthened(mission, (1500.0, 0.0), flown) is mission
    assert lengthened(mission, (-1e6, 0.0), flown) is mission


def test_the_lengthened_replan_states_the_whole_mission_over_the_longer_horizon():
    result = plan(SCENARIO, SolverSettings(compute_baselines=False))
    k = 80
    flown = FlownSlots(result.power[:, :k], result.trajectory[:k])
    in_flight = InFlight(position_m=(-200.0, 0.0), flown=flown,
                         previous_q=np.asarray(result.trajectory[k:]), mission_id=1, segment=0,
                         slots_kept=k)
    request = MissionRequest(SCENARIO, SolverSettings(compute_baselines=False),
                             VehicleLimits(), vehicle_aware=False, in_flight=in_flight)
    planned = plan_mission(request)
    receding = planned.receding
    longer = receding.mission
    assert longer.num_slots > SCENARIO.num_slots
    assert receding.mission_energy_w <= SCENARIO.power_budget_w * (1 + 1e-9)
    # The promise, recomputed from every slot's power and position over the longer horizon.
    power = np.hstack([flown.power_w, receding.result.power])
    positions = np.vstack([flown.positions_m, receding.result.trajectory])
    np.testing.assert_allclose(mission_rates_flown(longer, power, positions),
                               receding.mission_rates, rtol=1e-9)
    print(f'promise {receding.mission_min_throughput:.4f} bit/s over {longer.horizon_s:g} s, '
          f'the first plan stated {result.min_throughput:.4f} bit/s over 400 s')


def test_a_lengthened_replan_counts_every_horizon_tried_in_its_solve_time():
    """The vehicle cannot fly the fewest slots that reach qF (it starts and stops), so the
    rest is lengthened again; the plan's solve_time_s covers every attempt: at least the time
    all the planner's calls took (each made at least ``pause_s`` long)."""
    pause_s = 0.02
    calls, durations = [], []

    def slow_planner(scenario, settings, **options):
        began = time.perf_counter()
        calls.append(scenario.num_slots)
        time.sleep(pause_s)
        result = plan(scenario, settings, **options)
        durations.append(time.perf_counter() - began)
        return result
    result = plan(SCENARIO, SolverSettings(compute_baselines=False))
    k = 80
    in_flight = InFlight(position_m=(-200.0, 0.0),
                         flown=FlownSlots(result.power[:, :k], result.trajectory[:k]),
                         previous_q=np.asarray(result.trajectory[k:]), mission_id=1,
                         segment=0, slots_kept=k)
    planned = plan_mission(MissionRequest(SCENARIO, SolverSettings(compute_baselines=False),
                                          VehicleLimits(), in_flight=in_flight),
                           planner=slow_planner)
    print(f'rest slots tried: {calls}; solve time {planned.result.solve_time_s:.3f} s')
    assert len(set(calls)) >= 2                     # lengthened again for the vehicle
    assert planned.result.solve_time_s >= sum(durations)
    assert planned.vehicle_plan.flown.solve_time_s == planned.result.solve_time_s


def test_the_node_lengthens_a_mission_it_cannot_finish_in_time_and_flies_on_with_it(harness):
    from std_srvs.srv import Trigger

    from helpers import NODES_B, SLOTS
    h = harness()
    h.published(1)
    assert h.call('start', Trigger.Request()).success
    h.send_pose(-3000.0, 0.0)       # 5 km from qF: 25 legs of 200 m, fewer than 20 slots left
    h.published(2)
    outcome = h.node.current_plan
    longer = outcome.receding.mission
    print(f'lengthened to {longer.num_slots} slots ({longer.horizon_s:g} s)')
    assert longer.num_slots > SLOTS and h.node.progress.mission.num_slots == longer.num_slots
    assert outcome.receding.mission_energy_w <= longer.power_budget_w * (1 + 1e-9)
    # The lengthened mission is still the mission in flight: new nodes replan its rest.
    h.send_nodes(NODES_B)
    h.published(3)
    rest = h.node.current_plan.request.mission.in_flight
    assert rest is not None and rest.mission_slots == longer.num_slots
    assert h.node.current_plan.receding.mission.num_slots >= longer.num_slots
