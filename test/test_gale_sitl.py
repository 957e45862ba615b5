"""A gale on ArduCopter SITL: the node streams a held-out mission, and when its clock starts a
10 m/s wind from the east with 3 m/s turbulence (SIM_WIND_*) rises, above what a plan can
take (the airspeed a plan keeps is the mission's 8 m/s; the quad flies about 10.3 m/s at
its lean limit, and makes little way north against it). The node must answer the gale once
(a refusal on ``planner_status`` and ``/diagnostics``, the plan in force kept), not replan at
every ``replan_interval_s``, never restart the mission once its last slot has begun, and
leave the vehicle at qF or holding (``stream_fallback`` hold: BRAKE once the plan's time is
over).

Everything is measured on the test's own link in autopilot time (``time_boot_ms``): when the
last slot began, the uploads the node made after it, where the vehicle went from there. SITL
instances 95-99, speed-up 5 (the stream's targets are tracked at it).
"""

from __future__ import annotations

import math

from diagnostic_msgs.msg import DiagnosticStatus
import numpy as np
import pytest
from sitl_node import DRAG, flights, HELD_OUT, LinkedNode, Telemetry

from devtools.sitl import MAV, why_not_runnable
from uav_comm_planner.ros.diagnostics import PLANNER
from uav_comm_planner.ros.flight import HOLD_SPEED_MPS
from uav_comm_planner.ros.wind import REASON
from uav_comm_planner.vehicle.evaluation import REACH_RADIUS_M

pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(bool(why_not_runnable()), reason=why_not_runnable())]

INSTANCES = (95, 99)
SPEEDUP = 5
#: The gale the planner is not told, set when the mission clock starts (set before, it kept the
#: vehicle from reaching q0); still air until then, the quad's drag model on from the start so
#: that the autopilot estimates the wind.
GALE = {'SIM_WIND_SPD': 10.0, 'SIM_WIND_TURB': 3.0}
STILL = {'SIM_WIND_SPD': 0.0, 'SIM_WIND_DIR': 90.0, 'SIM_WIND_TURB': 0.0, **DRAG}
#: After the last slot has passed, the vehicle is watched until it is within REACH_RADIUS_M
#: of qF or holding (in BRAKE, moved less than HOLD_SPEED_MPS x HELD_S over HELD_S), or for
#: AFTER_S at most (autopilot seconds).
HELD_S = 5.0
AFTER_S = 300.0
#: The vehicle does not fly back towards q0: from the last slot on it never gets farther from
#: qF than it was then by more than this (metres; the turbulence moves it a few metres).
BACK_M = 20.0
#: Wall-clock guard of the flight (about two minutes at the speed-up).
LIMIT_S = 420.0


@pytest.fixture
def gale_flight(ros_context, tmp_path):
    yield from flights(ros_context, tmp_path, LinkedNode)


def holding(telemetry: Telemetry) -> bool:
    """Whether the vehicle is in BRAKE and has held its place over the last HELD_S: moved
    less than HOLD_SPEED_MPS times HELD_S (the gusts shake it, it does not go anywhere)."""
    rows = np.array(telemetry.rows)
    held = rows[rows[:, 0] >= rows[-1, 0] - HELD_S]
    braked = telemetry.mode_at(('BRAKE',))
    return (braked is not None and telemetry.modes[-1][1] == 'BRAKE'
            and held[0, 0] >= braked and held[-1, 0] - held[0, 0] >= HELD_S - 0.2
            and math.dist(held[0, 1:3], held[-1, 1:3]) <= HOLD_SPEED_MPS * HELD_S)


def settled(telemetry: Telemetry, goal: np.ndarray, end_s: float) -> bool:
    """Whether the watch after the mission is over: the vehicle at qF, holding, or watched
    for AFTER_S."""
    now, east, north = telemetry.rows[-1][:3]
    return (math.hypot(east - goal[0], north - goal[1]) <= REACH_RADIUS_M
            or holding(telemetry) or now >= end_s + AFTER_S)


def refusals(f: LinkedNode) -> tuple[list[str], set[str]]:
    """The gale's refusals as the node said them: on planner_status (one message each) and
    on /diagnostics (the planner's refusal stamps)."""
    said = [m for m in f.statuses if m.startswith('refused:') and f'{REASON} refused' in m]
    stamps = {values['refused_stamp_ns'] for _, _, values in f.states_of(PLANNER)
              if values.get('refused_request') == REASON}
    return said, stamps


def test_a_gale_is_refused_once_and_the_vehicle_ends_at_qf_or_holding(gale_flight):
    f = gale_flight(parameters={**HELD_OUT, 'compute_baselines': False,
                                'flight_mode': 'stream', 'stream_fallback': 'hold'},
                    instances=INSTANCES, sitl_parameters=STILL, speedup=SPEEDUP,
                    limit_s=LIMIT_S)
    node = f.node
    goal, start = np.array(HELD_OUT['goal_m']), np.array(HELD_OUT['start_m'])
    at_clock: dict[str, float] = {}
    last: dict[str, float] = {}
    # No replan loop: the wind's replans in flight are those of the rising estimate before the
    # gale, at most one per wind_replan_mps up to the airspeed, and the gale makes none; the
    # plans flown are at most one more (the first). Checked as the flight goes, so that a loop
    # fails the test at once.
    steps = math.ceil(node.config.vehicle.airspeed_mps / node.config.node.wind_replan_mps)

    def during(mission_s: float, telemetry: Telemetry) -> None:
        progress = node.progress
        if not at_clock:
            at_clock.update(requests=node.stats.requests_made, replans=node.vehicle.wind.replans,
                            uploads=node.vehicle.uploads_verified, at=telemetry.now_s)
            for name, value in GALE.items():
                f.link.mav.param_set_send(f.link.target_system, f.link.target_component,
                                          name.encode(), value, MAV.MAV_PARAM_TYPE_REAL32)
        assert len(progress.segments) <= steps + 1, f'a replan loop: {len(progress.segments)}'
        # The last slot begins one slot before the plan in force's last slot time (the flight
        # ends half a second after that time: the same clock as LinkedNode.fly's).
        segment = progress.current
        last_slot_s = (segment.slot_times_s(segment.num_slots)[-1] - progress.mission.slot_s
                       if segment.start_s is not None and segment.first_slot
                       + segment.num_slots == progress.mission.num_slots else math.inf)
        if not last and telemetry.now_s >= last_slot_s:
            last.update(at=telemetry.now_s, uploads=node.vehicle.uploads_verified,
                        mission=progress.mission_id, requests=node.stats.requests_made)
    telemetry = f.fly(during)
    end_s = telemetry.now_s
    f.watch(telemetry, lambda: settled(telemetry, goal, end_s), 'the vehicle at qF or holding')
    progress = node.progress
    wind = node.vehicle.wind
    said, stamps = refusals(f)
    print(f'\nclock started at {at_clock["at"]:.1f} s, the gale set then; wind estimated '
          f'{wind.estimate.speed_mps:.2f} m/s from {wind.estimate.from_deg:.0f} deg (SIM_WIND '
          f'10 m/s from 90, turbulence 3); airspeed {node.config.vehicle.airspeed_mps:g} m/s')
    print(f'the gale refused {len(said)} time(s) on planner_status, {len(stamps)} on '
          f'/diagnostics:', said)
    print(f'wind replans: {wind.replans} in all, {wind.replans - at_clock["replans"]} once the '
          f'clock ran; requests in flight {node.stats.requests_made - at_clock["requests"]}; '
          f'{len(progress.segments)} plans flown, the mission {progress.mission.num_slots} '
          f'slots (planned {HELD_OUT["num_slots"]})')
    print(f'last slot began at {last["at"]:.1f} s; uploads then {last["uploads"]}, at the end '
          f'{node.vehicle.uploads_verified}; requests after it '
          f'{node.stats.requests_made - last["requests"]}')
    print('stream events:', node.vehicle.stream_events)
    rows = np.array(telemetry.rows)
    after = rows[rows[:, 0] >= last['at']]
    to_goal = np.hypot(after[:, 1] - goal[0], after[:, 2] - goal[1])
    to_start = np.hypot(after[:, 1] - start[0], after[:, 2] - start[1])
    print(f'from the last slot on: {to_goal[0]:.1f} m from qF then, {to_goal[-1]:.1f} m at '
          f'the end ({rows[-1, 0] - end_s:.1f} s after the last slot), {to_start.min():.1f} m '
          f'from q0 at the closest, {to_goal.max() - to_goal[0]:.1f} m farther from qF at '
          f'most; holding: {holding(telemetry)}; modes {telemetry.modes}')
    # One refusal, on planner_status and /diagnostics, the gale named.
    assert len(said) == 1 and len(stamps) == 1, said
    assert 'cannot hold its position' in said[0] or 'goal unreachable' in said[0]
    assert wind.refused
    assert any(level == DiagnosticStatus.WARN for level, _, _ in f.states_of(PLANNER))
    assert wind.replans - at_clock['replans'] <= steps
    assert len(progress.segments) <= steps + 1
    # Nothing restarted once the last slot has begun, and the vehicle did not turn back.
    assert node.vehicle.uploads_verified == last['uploads']
    assert progress.mission_id == last['mission']
    assert node.stats.requests_made == last['requests']
    assert to_goal.max() <= to_goal[0] + BACK_M
    # At qF, or holding.
    assert to_goal[-1] <= REACH_RADIUS_M or holding(telemetry)
