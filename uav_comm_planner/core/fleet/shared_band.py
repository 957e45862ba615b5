"""Wu 2018's shared band: K UAVs on one band B, each serving at most one node per slot, the other
UAVs' signals interfering.

Notation as Wu, Zeng and Zhang (IEEE TWC 2018): gamma_{k,n}[m] = beta0 / (B sigma^2
(H^2 + ||q_k[m] - w_n||^2)) per watt (the whole band: no B/N), p_k[m] UAV k's power in slot m
(sum_m p_k[m] <= P_T, the letter's budget, so P_T / M is Wu's average power), and the schedule
alpha_{k,n}[m] in [0, 1] (relaxed from {0, 1}: time sharing within a slot) with
sum_n alpha_{k,n}[m] <= 1 (a UAV serves one node) and sum_k alpha_{k,n}[m] <= 1 (a node hears
one UAV). Node n's throughput, bits per second per hertz:

    eta_n = (1/M) sum_m sum_k alpha_{k,n}[m] log2(1 + p_k[m] gamma_{k,n}[m]
                                                   / (1 + sum_{j != k} p_j[m] gamma_{j,n}[m])).

Max-min of eta over alpha, p and q by block coordinate ascent, each block a convex problem
whose optimum never lowers the objective:

- **schedule** (p, q fixed): a linear program, exact;
- **power** (alpha, q fixed): R = log2(1 + sum_j p_j gamma_j) - log2(1 + sum_{j != k} p_j gamma_j);
  the first term is concave in p, the second is replaced by its tangent at the current p (an
  upper bound of a concave function): a concave lower bound, tight at the current point;
- **trajectory** (alpha, p fixed): with x_j = ||q_j - w_n||^2, F(x) = log2(1 + sum_j p_j g / (H^2
  + x_j)) is convex in x (its Hessian is diag(2 a_j / (H^2 + x_j)^3) (1 + h) / (1 + h)^2 minus a
  rank-one term that Cauchy-Schwarz bounds by half of it), so its tangent is a global lower
  bound, linear in x_j, hence concave in q; the interference term G(x) = log2(1 + sum_{j != k}
  ...) decreases in x, and with slacks S_{j,n}[m] <= ||q_j - w_n||^2 (whose right side is
  replaced by its tangent, a lower bound: a restriction) -G(S) <= -G(x) and -G is concave in S
  (a log-sum-exp of -log(H^2 + S)); with the separation rows and the speed limits of the
  orthogonal fleet (:mod:`.separation`, the leg block).

Without power control every UAV sends P_T / M in every slot and the power block is skipped.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import cvxpy as cp
import numpy as np

from uav_comm_planner.core.conic import solve_usable
from uav_comm_planner.core.feasibility import project_onto_speed_limit
from uav_comm_planner.core.fleet.scenario import FleetScenario
from uav_comm_planner.core.fleet.separation import keeps_separation, separation_rows
from uav_comm_planner.core.fleet.step import fleet_frames
from uav_comm_planner.core.sca.block import Variables
from uav_comm_planner.core.sca.legs import LegLimits
from uav_comm_planner.core.sca.surrogate import KM
from uav_comm_planner.errors import InvalidScenarioError

#: Below this a schedule entry is left out of the power and trajectory blocks (its term is
#: worth nothing to the objective).
SCHEDULED = 1e-9
#: log(p gamma) for a UAV that sends nothing: its interference is exp(-700), nil.
_SILENT_LOG = -700.0
_LN2 = math.log(2.0)


def gains(q: np.ndarray, fleet: FleetScenario) -> np.ndarray:
    """gamma (K, N, M) per watt over the whole band, for q (K, M, 2) metres."""
    s = fleet.scenario
    w = s.nodes
    d = ((q[:, None, :, :] - w[None, :, None, :]) ** 2).sum(axis=-1) + s.altitude_m ** 2
    return s.reference_gain / (s.bandwidth_hz * s.noise_psd_w_per_hz * d)


def link_rates(p: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """R_{k,n}[m] (K, N, M) bits per second per hertz: UAV k to node n, the others
    interfering; p (K, M) watts."""
    received = p[:, None, :] * gamma                          # (K, N, M)
    interference = received.sum(axis=0, keepdims=True) - received
    return np.log1p(received / (1.0 + interference)) / _LN2


def node_throughputs(alpha: np.ndarray, p: np.ndarray, q: np.ndarray,
                     fleet: FleetScenario) -> np.ndarray:
    """eta_n (N,) bits per second per hertz."""
    return (alpha * link_rates(p, gains(q, fleet))).sum(axis=0).mean(axis=1)


def schedule_block(rates: np.ndarray) -> np.ndarray:
    """The max-min schedule alpha (K, N, M) for link rates (K, N, M): a linear program."""
    k, n, m = rates.shape
    alpha = cp.Variable((k, n * m), nonneg=True)
    t = cp.Variable()
    flat = rates.reshape(k, n * m)
    served = cp.sum(cp.multiply(alpha, flat), axis=0)          # (N M,), node-major
    per_node = cp.hstack([cp.sum(served[i * m:(i + 1) * m]) / m for i in range(n)])
    per_uav = [cp.sum(cp.reshape(alpha[j], (n, m), order='C'), axis=0) <= 1 for j in range(k)]
    problem = cp.Problem(cp.Maximize(t), [per_node >= t, cp.sum(alpha, axis=0) <= 1,
                                          alpha <= 1, *per_uav])
    solve_usable(problem, 'shared band, schedule')
    return np.clip(alpha.value, 0.0, 1.0).reshape(k, n, m)


def power_block(alpha: np.ndarray, p: np.ndarray, gamma: np.ndarray,
                budget_w: float) -> np.ndarray:
    """The power step (module docstring): p (K, M) watts, from the current p."""
    k, n, m = gamma.shape
    x = cp.Variable((k, m), nonneg=True)
    t = cp.Variable()
    # 1 + sum_j p_j gamma_j, for every (n, m): (N, M) affine expressions.
    total = 1 + sum(cp.multiply(gamma[j], cp.reshape(x[j], (1, m), order='C'))
                    for j in range(k))
    weight = alpha.sum(axis=0)                                  # (N, M)
    received = p[:, None, :] * gamma
    others = 1.0 + received.sum(axis=0, keepdims=True) - received   # (K, N, M) at p^r
    # Tangent of log2(others) at p^r: its value plus sum_{j != k} gamma_j (x_j - p_j) / others.
    tangent = 0
    for j in range(k):
        share = (alpha * gamma[j][None] / others)               # (K, N, M)
        share[j] = 0.0
        step = cp.reshape(x[j] - p[j], (1, m), order='C')
        tangent = tangent + cp.multiply(share.sum(axis=0), step)
    constant = (alpha * np.log(others)).sum(axis=0)            # (N, M)
    rows = (cp.sum(cp.multiply(weight, cp.log(total)) - tangent, axis=1) - constant.sum(axis=1))
    problem = cp.Problem(cp.Maximize(t), [rows / (m * _LN2) >= t,
                                          cp.sum(x, axis=1) <= budget_w])
    solve_usable(problem, 'shared band, power')
    return np.maximum(x.value, 0.0)


def _interference(alpha: np.ndarray, p: np.ndarray, gamma_km: np.ndarray, height_km2: float,
                  slack: list) -> cp.Expression:
    """sum_m sum_k alpha_{k,n}[m] G_{k,n}[m](S) per node (N,), nats: G the interference term's
    log-sum-exp in the slacks S (km^2), over the scheduled entries."""
    k_count, n, m = alpha.shape
    if k_count == 1:
        return np.zeros(n)
    # log(p_j gamma_j) in km^2 units: p_j gamma_j (H^2 + x) = p_j beta0 / (B sigma^2).
    log_a = np.log(np.maximum(p[:, None, :] * gamma_km, np.exp(_SILENT_LOG)))
    total = 0
    for k in range(k_count):
        nodes, slots = np.nonzero(alpha[k] > SCHEDULED)
        if not len(nodes):
            continue
        flat = nodes * m + slots
        terms = [np.zeros(len(flat))]
        terms += [log_a[j, nodes, slots] - cp.log(height_km2 + slack[j][flat])
                  for j in range(k_count) if j != k]
        interference = cp.log_sum_exp(cp.vstack(terms), axis=0)
        weights = np.zeros((n, len(flat)))
        weights[nodes, np.arange(len(flat))] = alpha[k, nodes, slots]
        total = total + weights @ interference
    return total


def trajectory_block(alpha: np.ndarray, p: np.ndarray, q: np.ndarray,
                     fleet: FleetScenario) -> np.ndarray:
    """The trajectory step (module docstring): q (K, M, 2) metres, from the current q; the
    answer keeps the speed limits and d_min (projected, and checked by the caller)."""
    s = fleet.scenario
    k_count, n, m = alpha.shape
    frames = fleet_frames(fleet)
    z_r = np.stack([frame.km(q_k) for frame, q_k in zip(frames, q)])        # (K, M, 2)
    w = frames[0].nodes
    height_km2 = (s.altitude_m / KM) ** 2
    x_r = ((z_r[:, None] - w[None, :, None]) ** 2).sum(axis=-1)             # (K, N, M)
    # p_j gamma_j = a_j / (H^2 + x_j), with a_j in km^2 units.
    a = p[:, None, :] * gains(q, fleet) * (height_km2 + x_r)
    share = a / (height_km2 + x_r)
    signal = 1.0 + share.sum(axis=0)                                          # (N, M)
    weight = alpha.sum(axis=0)                                                # (N, M)
    # F's tangent: F(x^r) - sum_j c_j (x_j - x_j^r), c_j = (a_j / (H^2 + x_j^r)^2) / signal.
    slope = weight[None] * (a / (height_km2 + x_r) ** 2) / signal[None]      # (K, N, M)
    constant = (weight * np.log(signal)).sum(axis=1) + (slope * x_r).sum(axis=(0, 2))
    t = cp.Variable()
    z = [cp.Variable((m, 2)) for _ in range(k_count)]
    slack = [cp.Variable(n * m) for _ in range(k_count)]
    spread = 0
    constraints = []
    for j, (frame, z_j) in enumerate(zip(frames, z)):
        spread = spread + cp.hstack([slope[j, i] @ cp.sum(cp.square(z_j - w[i][None, :]), axis=1)
                                     for i in range(n)])
        tangent = cp.hstack([
            x_r[j, i] + 2 * cp.sum(cp.multiply(z_r[j] - w[i][None, :], z_j - z_r[j]), axis=1)
            for i in range(n)])
        constraints.append(slack[j] <= tangent)
        path = cp.vstack([frame.start[None, :], z_j, frame.goal[None, :]])
        constraints += LegLimits(frame).constraints(Variables(z_j, t, path[1:] - path[:-1]),
                                                    None)
    rows = separation_rows(z_r, fleet, scale=KM)
    for (j, k), direction, rhs in zip(fleet.pairs, rows.direction, rows.rhs):
        constraints.append(cp.sum(cp.multiply(direction, z[j] - z[k]), axis=1) >= rhs)
    interference = _interference(alpha, p, gains(q, fleet) * (height_km2 + x_r), height_km2,
                                 slack)
    bound = (constant - spread - interference) / (m * _LN2)
    problem = cp.Problem(cp.Maximize(t), constraints + [bound >= t])
    solve_usable(problem, 'shared band, trajectory')
    return np.stack([project_onto_speed_limit(frame.metres(z_j.value), frame.scenario)
                     for frame, z_j in zip(frames, z)])


@dataclass(frozen=True)
class SharedBandPlan:
    """A shared-band plan: trajectories q (K, M, 2) metres, power p (K, M) watts, schedule
    alpha (K, N, M), throughputs eta (N,) bits per second per hertz and their minimum, the
    history of the minimum after every block, and whether the power was controlled."""

    fleet: FleetScenario
    trajectories: np.ndarray
    power: np.ndarray
    schedule: np.ndarray
    throughputs: np.ndarray
    min_throughput: float
    history: tuple[tuple[str, float], ...]
    power_control: bool


def _uniform_power(fleet: FleetScenario) -> np.ndarray:
    s = fleet.scenario
    return np.full((fleet.num_uavs, s.num_slots), s.power_budget_w / s.num_slots)


def check_shared_band(fleet: FleetScenario) -> None:
    """Refuse (InvalidScenarioError) a fleet with zones or an energy budget: the shared band's
    trajectory block keeps the speed limits and the separation only."""
    s = fleet.scenario
    if (s.zones is not None and not s.zones.empty) or any(
            vehicle.energy_budget_wh is not None for vehicle in fleet.vehicles):
        raise InvalidScenarioError(
            'the shared band is planned without zones or an energy budget: its trajectory '
            'block has the speed limits and the separation only (plan on orthogonal channels)')


def plan_shared_band(fleet: FleetScenario, trajectories: np.ndarray, *,
                     power_control: bool = True, power: np.ndarray | None = None,
                     max_rounds: int = 40, relative_tolerance: float = 1e-4) -> SharedBandPlan:
    """Block coordinate ascent (module docstring) from ``trajectories`` (K, M, 2) metres (within
    the speed limits and d_min apart, such as an orthogonal fleet plan's) and ``power`` (K, M)
    watts (None: P_T / M every slot); without ``power_control`` the power stays as given. Each
    block's answer is kept only when it keeps d_min and does not lower min_n eta_n; a round
    that gains at most ``relative_tolerance`` of the value ends the loop."""
    s = fleet.scenario
    check_shared_band(fleet)
    q = np.asarray(trajectories, dtype=float)
    if q.shape != (fleet.num_uavs, s.num_slots, 2) or not keeps_separation(q, fleet):
        raise InvalidScenarioError(
            f'the shared band starts from {fleet.num_uavs} trajectories of {s.num_slots} slots '
            f'kept {fleet.min_separation_m:g} m apart')
    p = _uniform_power(fleet) if power is None else np.asarray(power, dtype=float).copy()
    if p.shape != (fleet.num_uavs, s.num_slots) or p.min() < 0 or \
            np.any(p.sum(axis=1) > s.power_budget_w * (1 + 1e-12)):
        raise InvalidScenarioError('power must be (K, M) watts >= 0, each UAV within P_T')
    alpha = schedule_block(link_rates(p, gains(q, fleet)))
    value = float(node_throughputs(alpha, p, q, fleet).min())
    history = [('schedule', value)]
    for _ in range(max_rounds):
        before = value
        if power_control:
            candidate = power_block(alpha, p, gains(q, fleet), s.power_budget_w)
            candidate *= np.minimum(1.0, s.power_budget_w / candidate.sum(axis=1))[:, None]
            new = float(node_throughputs(alpha, candidate, q, fleet).min())
            if new >= value:
                p, value = candidate, new
                history.append(('power', value))
        candidate = trajectory_block(alpha, p, q, fleet)
        new = float(node_throughputs(alpha, p, candidate, fleet).min())
        if keeps_separation(candidate, fleet) and new >= value:
            q, value = candidate, new
            history.append(('trajectory', value))
        candidate = schedule_block(link_rates(p, gains(q, fleet)))
        new = float(node_throughputs(candidate, p, q, fleet).min())
        if new >= value:
            alpha, value = candidate, new
            history.append(('schedule', value))
        if value - before <= relative_tolerance * abs(value):
            break
    throughputs = node_throughputs(alpha, p, q, fleet)
    return SharedBandPlan(fleet, q, p, alpha, throughputs, float(throughputs.min()),
                          tuple(history), power_control)


__all__ = ['check_shared_band', 'gains', 'link_rates', 'node_throughputs', 'plan_shared_band',
           'power_block', 'schedule_block', 'SharedBandPlan', 'trajectory_block']
