"""Positions that cannot be true: every ``uav_pose`` and telemetry sample passes one
finite-and-plausible check before it reaches the mission clock, and none ends the node."""

from __future__ import annotations

import math
import time

from helpers import SLOT_S
import numpy as np
import pytest
from std_srvs.srv import Trigger

from uav_comm_planner.mission.plausible import (CONFIRMING_SAMPLES, POSITION_NOISE_M,
                                                PositionGate, reach_m, SPEED_MARGIN)
from uav_comm_planner.ros.flight import REFUSAL_REPORT_S

pytestmark = pytest.mark.filterwarnings('ignore::DeprecationWarning')


@pytest.mark.parametrize('sample, height, message', [
    ((0.0, math.nan, 0.0), None, 'is not finite'),
    ((0.0, 0.0, math.inf), None, 'is not finite'),
    ((math.inf, 0.0, 0.0), None, 'is not finite'),
    ((0.0, 1e308, 0.0), None, 'beyond the coordinate range'),
    ((0.0, -1e308, 5.0), None, 'beyond the coordinate range'),
    ((0.0, 0.0, 1.0e7 + 1), None, 'beyond the coordinate range'),
    ((0.0, 0.0, 0.0), math.nan, 'is not finite'),
    ((0.0, 0.0, 0.0), 1e9, 'height 1e+09 m is beyond'),
])
def test_a_sample_that_is_no_position_is_refused_even_first(sample, height, message):
    gate = PositionGate()
    assert message in gate.check(sample, 10.0, height)
    assert gate.accepted is None


def test_a_sample_farther_than_the_uav_flies_is_refused_and_a_lasting_jump_confirmed():
    gate = PositionGate()
    assert gate.check((0.0, 0.0, 0.0), 10.0) is None
    assert reach_m(10.0, 1.0) == SPEED_MARGIN * 10.0 + POSITION_NOISE_M
    assert gate.check((1.0, reach_m(10.0, 1.0) - 1e-6, 0.0), 10.0) is None
    assert 'before the last sample' in gate.check((0.5, 0.0, 0.0), 10.0)
    assert 'farther than the UAV flies' in gate.check((2.0, 5000.0, 0.0), 10.0)
    assert gate.accepted[0] == 1.0
    # The estimate really jumped: samples in a row that agree with each other confirm it.
    for k in range(1, CONFIRMING_SAMPLES - 1):
        assert gate.check((2.0 + 0.1 * k, 5000.0, 0.0), 10.0) is not None
    assert gate.check((2.0 + 0.1 * CONFIRMING_SAMPLES, 5000.0, 0.0), 10.0) is None
    assert gate.accepted[1] == 5000.0


def test_alternating_glitches_are_never_confirmed():
    gate = PositionGate()
    assert gate.check((0.0, 0.0, 0.0), 10.0) is None
    for k in range(200):
        x = 5.0e6 if k % 2 else -5.0e6
        assert gate.check((0.05 * (k + 1), x, 0.0), 10.0) is not None
    assert gate.accepted == (0.0, 0.0, 0.0)


def send_and_spin(h, x: float, y: float) -> None:
    h.send_pose(x, y)
    for _ in range(3):
        h.executor.spin_once(timeout_sec=0.01)


def test_a_pose_stream_of_plus_minus_1e308_is_refused_and_the_node_flies_on(harness):
    h = harness()
    h.published(1)
    assert h.call('start', Trigger.Request()).success
    errors = h.node.stats.error_count
    began = time.monotonic()
    sent = 0
    while time.monotonic() - began < 1.5:      # the stream at 20 Hz, shorter
        send_and_spin(h, 1e308 if sent % 2 else -1e308, 0.0)
        sent += 1
        time.sleep(0.05)
    h.spin_until(lambda: h.node.flight.positions_refused >= sent // 2, 'refusals')
    # One line per report, at most one report a second, each with the count refused.
    reports = h.node.stats.error_count - errors
    assert 1 <= reports <= 1.5 / REFUSAL_REPORT_S + 1
    assert 'beyond the coordinate range' in h.node.stats.last_error
    assert len(h.node.flight.track.samples) == 0
    # Then a real position: taken, and the rest of the mission replanned from it.
    published = h.node.stats.plans_published
    h.node.flight._last_pose_replan_s = -math.inf
    h.send_pose(500.0, 500.0)
    h.spin_until(lambda: h.node.stats.plans_published > published, 'replan from (500, 500)')
    assert tuple(h.node.flight.track.latest[1:]) == (500.0, 500.0)
    assert h.node.current_plan.request.mission.in_flight.position_m == (500.0, 500.0)
    assert np.all(np.isfinite(h.node.current_plan.result.trajectory))


def test_telemetry_samples_pass_the_same_check_and_none_ends_the_node(harness, monkeypatch):
    h = harness()
    h.published(1)
    assert h.call('start', Trigger.Request()).success
    flight = h.node.flight
    flight.on_position(1.0, 0.0, 0.0, source='vehicle', height_m=math.nan)
    flight.on_position(1.0, 1e300, 0.0, source='vehicle', height_m=100.0)
    assert flight.positions_refused == 2 and len(flight.track.samples) == 0
    # An error further on (here, a receding replan's flown slots) is a refusal, not an exit.
    from uav_comm_planner.errors import InvalidScenarioError

    def broken(*args, **kwargs):
        raise InvalidScenarioError('flown slots: power and positions must be finite')
    monkeypatch.setattr(flight.progress, 'flown_slots', broken)
    flight._last_pose_replan_s = -math.inf
    errors = h.node.stats.error_count
    flight.on_position(h.node.clock_s() + SLOT_S, 500.0, 500.0, source='vehicle')
    assert h.node.stats.error_count == errors + 1
    assert 'must be finite' in h.node.stats.last_error
    assert h.call('replan', Trigger.Request()).success
