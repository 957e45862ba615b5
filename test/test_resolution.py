"""Slots too coarse for the channel: the legs against the altitude, and the rate along them
against an independent computation."""

from __future__ import annotations

import numpy as np
import pytest

from uav_comm_planner.core.optimizer import plan
from uav_comm_planner.core.scenario import paper_scenario
from uav_comm_planner.mission.resolution import (along_legs_min_throughput, coarse_slots,
                                                 MAX_LEG_ALTITUDE_SHARE)


def test_the_rate_along_the_legs_is_the_power_sent_between_waypoints():
    """One sample per leg is its midpoint: slot m's power at (q[m-1] + q[m]) / 2."""
    result = plan(paper_scenario('I', num_slots=8, horizon_s=40.0, max_speed_mps=100.0))
    scenario = result.scenario
    path = np.vstack([scenario.start_m, result.trajectory])
    middles = (path[:-1] + path[1:]) / 2.0
    w = np.asarray(scenario.ground_nodes_m)
    gain = scenario.reference_gain / (
        ((middles[None, :, :] - w[:, None, :]) ** 2).sum(axis=2) + scenario.altitude_m ** 2)
    noise_w = 10 ** (scenario.noise_psd_dbm_per_hz / 10) / 1000 * scenario.bandwidth_hz
    snr = result.power * scenario.num_nodes * gain / noise_w
    rates = scenario.bandwidth_hz / scenario.num_nodes * np.log2(1 + snr).mean(axis=1)
    assert along_legs_min_throughput(result, samples_per_leg=1) == pytest.approx(rates.min(),
                                                                                 rel=1e-12)
    # More samples tend to the continuous average.
    assert along_legs_min_throughput(result, 32) == pytest.approx(
        along_legs_min_throughput(result, 512), rel=1e-4)


def test_the_letter_s_legs_of_h_pass_and_coarser_slots_are_flagged_with_their_numbers():
    letter = plan(paper_scenario('I'))          # legs of V delta = 100 m = H
    assert coarse_slots(letter) is None
    coarse = plan(paper_scenario('I', num_slots=5, horizon_s=50.0))
    found = coarse_slots(coarse)
    assert found is not None and found.longest_leg_m > MAX_LEG_ALTITUDE_SHARE * 100.0
    assert found.num_slots == 5 and found.stated_bps == coarse.min_throughput
    # 100 m/s over 50 s in legs of at most 100 m.
    assert found.suggested_slots == 50
    assert found.along_legs_bps == along_legs_min_throughput(coarse)
    assert found.along_legs_bps < found.stated_bps
    assert f'{found.leg_share:.2g} times the altitude H = 100 m' in found.message()
