"""The channel and throughput model against a plain, slot-by-slot reading of the letter."""

import math

import numpy as np
import pytest

from uav_comm_planner import paper_scenario
from uav_comm_planner.core.initial import straight_line
from uav_comm_planner.core.model import average_rates, leg_lengths, min_rate, snr_per_watt, speeds


def rates_by_the_letter(q, p, scenario):
    """Eq. (2)-(3), time-weighted: R_n = (1/T) sum_m delta (B/N) log2(1 + p g / (B/N sigma^2))."""
    sigma2 = 10 ** ((scenario.noise_psd_dbm_per_hz - 30) / 10)
    n_nodes = len(scenario.ground_nodes_m)
    rates = []
    for n, (xn, yn) in enumerate(scenario.ground_nodes_m):
        total = 0.0
        for m, (x, y) in enumerate(q):
            g = scenario.reference_gain / ((x - xn) ** 2 + (y - yn) ** 2
                                           + scenario.altitude_m ** 2)
            snr = p[n][m] * g / (scenario.bandwidth_hz / n_nodes * sigma2)
            total += scenario.slot_s * scenario.bandwidth_hz / n_nodes * math.log2(1 + snr)
        rates.append(total / scenario.horizon_s)
    return rates


@pytest.mark.parametrize('case', ['I', 'II'])
def test_rates_match_the_letters_formula(case):
    scenario = paper_scenario(case, bandwidth_hz=1e3, horizon_s=25.0)
    rng = np.random.default_rng(7)
    q = straight_line(scenario) + rng.normal(scale=30.0, size=(scenario.num_slots, 2))
    p = rng.uniform(0.0, 0.2, size=(scenario.num_nodes, scenario.num_slots))
    p[0, :10] = 0.0
    np.testing.assert_allclose(average_rates(q, p, scenario), rates_by_the_letter(q, p, scenario),
                               rtol=1e-12)
    assert min_rate(q, p, scenario) == pytest.approx(min(rates_by_the_letter(q, p, scenario)))


def test_rates_do_not_change_when_only_the_slot_length_changes():
    scenario = paper_scenario('I')
    slower = scenario.replace(horizon_s=100.0, max_speed_mps=50.0)
    q = straight_line(scenario)
    p = np.full((3, 50), 0.03)
    assert slower.slot_s == 2.0
    np.testing.assert_allclose(average_rates(q, p, slower), average_rates(q, p, scenario))


def test_snr_per_watt_at_the_letters_numbers():
    scenario = paper_scenario('I')
    # Straight above node 2 at 100 m: a = N beta0 / (H^2 B sigma^2) = 3e-3 / (1e4 * 10^-19.9).
    a = snr_per_watt(np.array([[1000.0, 200.0]]), scenario)
    assert a[1, 0] == pytest.approx(3e-3 / 1e4 / 10 ** -19.9, rel=1e-12)
    assert a[1, 0] > a[0, 0] and a[1, 0] > a[2, 0]


def test_legs_include_launch_and_landing():
    scenario = paper_scenario('I', num_slots=3, horizon_s=30.0)
    q = np.array([[300.0, 400.0], [300.0, 400.0], [1000.0, 400.0]])
    np.testing.assert_allclose(leg_lengths(q, scenario),
                               [500.0, 0.0, 700.0, math.hypot(1000.0, 400.0)])
    np.testing.assert_allclose(speeds(q, scenario), leg_lengths(q, scenario) / 10.0)
