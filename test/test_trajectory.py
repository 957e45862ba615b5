"""The SCA bound of the trajectory step, checked against the letter's own formula."""

import math

import numpy as np
import pytest

from uav_comm_planner import paper_scenario
from uav_comm_planner.core.initial import straight_line
from uav_comm_planner.core.model import leg_lengths, snr_per_watt
from uav_comm_planner.core.power import waterfilling_power
from uav_comm_planner.core.sca.reference import trajectory_step_cvxpy
from uav_comm_planner.core.sca.surrogate import sca_lower_bound
from uav_comm_planner.errors import SolverError


def letter_bound(q, q_k, p, scenario):
    """lbr of eq. (10), written as the letter does: gamma beta0 and d^k, in metres."""
    sigma2 = 10 ** ((scenario.noise_psd_dbm_per_hz - 30) / 10)
    n_nodes = scenario.num_nodes
    out = np.zeros((n_nodes, len(q)))
    for n, (xn, yn) in enumerate(scenario.ground_nodes_m):
        for m in range(len(q)):
            gamma_beta0 = n_nodes * p[n, m] / (scenario.bandwidth_hz * sigma2) \
                * scenario.reference_gain
            xk, yk = q_k[m]
            d_k = (xk - xn) ** 2 + (yk - yn) ** 2 + scenario.altitude_m ** 2
            dx, dy = q[m][0] - xk, q[m][1] - yk
            f = dx ** 2 + dy ** 2 + 2 * (xk - xn) * dx + 2 * (yk - yn) * dy
            out[n, m] = math.log2(1 + gamma_beta0 / d_k) \
                - gamma_beta0 / (math.log(2) * d_k * (gamma_beta0 + d_k)) * f
    return out


def true_bits(q, p, scenario):
    return np.log2(1.0 + p * snr_per_watt(q, scenario))


@pytest.fixture(params=[('I', 5.0), ('II', 5.0), ('I', 1e-9)], ids=['I', 'II', 'I-low-snr'])
def expansion(request):
    case, budget = request.param
    scenario = paper_scenario(case, power_budget_w=budget)
    q_k = straight_line(scenario)
    p = waterfilling_power(snr_per_watt(q_k, scenario), budget).p
    return scenario, q_k, p


def test_bound_equals_the_letters_formula_and_touches_at_the_expansion_point(expansion):
    scenario, q_k, p = expansion
    rng = np.random.default_rng(11)
    q = q_k + rng.normal(scale=300.0, size=q_k.shape)
    np.testing.assert_allclose(sca_lower_bound(q, q_k, p, scenario),
                               letter_bound(q, q_k, p, scenario), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(sca_lower_bound(q_k, q_k, p, scenario),
                               true_bits(q_k, p, scenario), rtol=1e-12)


def test_bound_is_below_the_true_rate_everywhere(expansion):
    scenario, q_k, p = expansion
    rng = np.random.default_rng(3)
    for scale in (1.0, 50.0, 500.0, 3000.0):
        q = q_k + rng.normal(scale=scale, size=q_k.shape)
        gap = true_bits(q, p, scenario) - sca_lower_bound(q, q_k, p, scenario)
        assert gap.min() >= -1e-9 * true_bits(q, p, scenario).max()


def test_step_keeps_the_speed_limits_and_raises_the_true_minimum(expansion):
    scenario, q_k, p = expansion
    step = trajectory_step_cvxpy(q_k, p, scenario)
    assert leg_lengths(step.q, scenario).max() <= scenario.max_step_m * (1 + 1e-7)
    before = true_bits(q_k, p, scenario).mean(axis=1).min()
    after = true_bits(step.q, p, scenario).mean(axis=1).min()
    assert step.bound >= before - 1e-7 * before
    assert after >= step.bound - 1e-9 * step.bound
    assert after > before


def test_solver_status_is_checked(monkeypatch, expansion):
    import cvxpy as cp
    scenario, q_k, p = expansion

    def infeasible(self, *args, **kwargs):
        self._status = cp.INFEASIBLE

    monkeypatch.setattr(cp.Problem, 'solve', infeasible)
    monkeypatch.setattr(cp.Problem, 'status', property(lambda self: self._status))
    with pytest.raises(SolverError, match="CLARABEL returned status 'infeasible'"):
        trajectory_step_cvxpy(q_k, p, scenario)


def test_the_reference_step_is_certified_by_its_duality_gap(monkeypatch):
    """Each cvxpy step is accepted on a duality gap far below its tolerance; the same bound at a
    point moved off the optimum, or past a speed limit, refuses it."""
    from uav_comm_planner.core.sca import reference
    from uav_comm_planner.core.sca.block import Expansion, Frame
    from uav_comm_planner.core.sca.program import step_blocks

    scenario = paper_scenario('I')
    q_k = straight_line(scenario)
    p = waterfilling_power(snr_per_watt(q_k, scenario), scenario.power_budget_w).p
    seen = {}
    solve = reference.solve_checked

    def spy(problem, step, solver, attempts, check):
        certificate = solve(problem, step, solver, attempts, check)
        variables = {v.shape: v.value for v in problem.variables()}
        seen.update(certificate=certificate, z=variables[(scenario.num_slots, 2)],
                    duals=[c.dual_value for c in problem.constraints])
        return certificate

    monkeypatch.setattr(reference, 'solve_checked', spy)
    step = trajectory_step_cvxpy(q_k, p, scenario)
    assert seen['certificate'].gap < 1e-8

    frame = Frame.of(scenario)
    blocks = step_blocks(frame)
    data = [block.at(Expansion(q_k, p)) for block in blocks]
    n = scenario.num_nodes
    duals = [seen['duals'][:n], seen['duals'][n:]]
    z = seen['z']
    np.testing.assert_allclose(frame.metres(z), step.q)
    assert reference.certify(blocks, z, data, duals).gap < 1e-8
    # The straight line is feasible and worse than the optimum: its gap is at least the
    # difference of the two values (weak duality makes the bound hold at any feasible point).
    line = frame.km(q_k)
    values = [float(sca_lower_bound(frame.metres(x), q_k, p, scenario).mean(axis=1).min())
              for x in (z, line)]
    assert values[0] > values[1]
    assert reference.certify(blocks, line, data, duals).gap * max(1, abs(values[1])) \
        >= values[0] - values[1] - 1e-12
    too_fast = z.copy()
    too_fast[0] += 2 * scenario.max_step_m / 1000.0
    assert reference.certify(blocks, too_fast, data, duals) is None
