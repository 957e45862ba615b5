"""Altitude as a variable: a per-slot altitude h[m] within a range and a climb limit, planned
jointly with the horizontal trajectory and the power.

Node n's SNR per watt in slot m is a_n[m] = snr_scale g(rho, h[m]) / beta0, rho the horizontal
distance ||q[m] - w_n|| (:mod:`uav_comm_planner.core.channel`). With free space the gain only
falls with the altitude, so the best is the lowest; with a line-of-sight probability a higher
UAV sees more line of sight from farther, a trade-off.

The trajectory step's bound, about (rho_k, h_k), is separable:

    lbr(rho, h) = [C - A rho - B rho^2] + R_h (h - h_k) - D (h - h_k)^2,

the first part :func:`~uav_comm_planner.core.sca.channel_bound.coefficients_at` at h_k (tight,
concave in q, below R(., h_k)), R_h = dR/dh at (rho_k, h_k), and D the altitude's curvature
bound: the largest [C - A rho - B rho^2 + R_h (h - h_k) - R(rho, h)] / (h - h_k)^2 over a grid of
rho (from the node out to 1000 h_k and about rho_k) and of h within the range, times
:data:`ALTITUDE_MARGIN`. It equals R and its gradient at (rho_k, h_k), and is concave in (q, h).
The step maximises min_n mean_m lbr subject to the speed limits, h[m] in the range and
|h[m] - h[m-1]| <= climb delta (q0's and qF's altitudes are free within the range, so the first
and last slots have no climb limit towards them); Algorithm 1 keeps a step only if the true
minimum rate does not drop, so the objective never decreases.

Algorithm 1 starts from the best plan at one altitude for the whole flight (:func:`plan` at a
golden-section search over the range, its ends included), so the 3D plan is never below it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
import math
import time

import cvxpy as cp
import numpy as np

from uav_comm_planner.core.altitude_limits import AltitudeLimits, limits_of
from uav_comm_planner.core.conic import CLARABEL_ATTEMPTS, solve_usable
from uav_comm_planner.core.feasibility import project_onto_speed_limit
from uav_comm_planner.core.model import (snr_scale, spectral_efficiencies,
                                         spectral_efficiency_to_rate,
                                         squared_horizontal_distances)
from uav_comm_planner.core.numbers import real_number
from uav_comm_planner.core.optimizer import plan, PlanResult
from uav_comm_planner.core.power import waterfilling_power
from uav_comm_planner.core.sca.block import Frame, Variables
from uav_comm_planner.core.sca.channel_bound import coefficients_at
from uav_comm_planner.core.sca.legs import LegLimits
from uav_comm_planner.core.sca.surrogate import KM
from uav_comm_planner.core.scenario import Scenario, SolverSettings
from uav_comm_planner.errors import InvalidScenarioError

#: D is this times the grid's largest ratio.
ALTITUDE_MARGIN = 1.1
#: The altitude grid: points across the range, and offsets about h_k (shares of the range).
_RANGE_POINTS = 61
_NEAR_H = np.geomspace(1e-5, 0.2, 24)
#: The grid of rho, in altitudes, and about rho_k.
_FAR_RHO = np.concatenate([[0.0], np.geomspace(1e-3, 1e3, 90),
                           1.0 / np.tan(np.radians(np.arange(1.0, 90.0, 1.0)))])
_NEAR_RHO = np.geomspace(1e-4, 2.0, 20)
#: Rows of (N, M) handled at once.
_CHUNK = 32
#: The golden-section search's steps over the range (its interval shrinks to 0.618^steps).
SEARCH_STEPS = 16


def snr_per_watt_3d(q: np.ndarray, h: np.ndarray, scenario: Scenario) -> np.ndarray:
    """a_n[m] (N, M) per watt at q (M, 2) metres and altitudes h (M,) metres."""
    s = squared_horizontal_distances(q, scenario)
    return snr_scale(scenario) * scenario.channel_model.gain(s, np.asarray(h, float)[None, :])


def rates_3d(q: np.ndarray, h: np.ndarray, p: np.ndarray, scenario: Scenario) -> np.ndarray:
    """R_n (N,) bit/s at q (M, 2), h (M,) metres and power p (N, M) watts."""
    return spectral_efficiency_to_rate(
        spectral_efficiencies(snr_per_watt_3d(q, h, scenario), p), scenario)


@dataclass(frozen=True)
class AltitudeBound:
    """lbr_{n,m} = constant - linear rho - weight rho^2 + h_linear h - h_weight h^2, each
    (N, M): bits, per m, per m^2, per m, per m^2 (module docstring)."""

    constant: np.ndarray
    linear: np.ndarray
    weight: np.ndarray
    h_linear: np.ndarray
    h_weight: np.ndarray

    def at(self, q: np.ndarray, h: np.ndarray, scenario: Scenario) -> np.ndarray:
        """lbr (N, M) at q (M, 2), h (M,) metres."""
        rho = np.sqrt(squared_horizontal_distances(q, scenario))
        h = np.asarray(h, dtype=float)[None, :]
        return (self.constant - self.linear * rho - self.weight * rho * rho
                + self.h_linear * h - self.h_weight * h * h)


def _altitude_curvature(channel, limits: AltitudeLimits, part: dict) -> np.ndarray:
    """D (rows,) for rows of (rho_k, h_k, c, the rho part's coefficients, R_h)."""
    low, high = limits.range_m
    rho_k, h_k = part['rho_k'], part['h_k']
    rho = np.concatenate([h_k[:, None] * _FAR_RHO[None, :],
                          rho_k[:, None] + h_k[:, None] * np.concatenate(
                              [-_NEAR_RHO, _NEAR_RHO])[None, :]], axis=1)
    rho = np.maximum(rho, 0.0)                                            # (rows, G)
    span = max(high - low, 1e-9)
    h = np.concatenate([np.broadcast_to(np.linspace(low, high, _RANGE_POINTS),
                                        (len(h_k), _RANGE_POINTS)),
                        h_k[:, None] + span * np.concatenate([-_NEAR_H, _NEAR_H])[None, :]],
                       axis=1)
    h = np.clip(h, low, high)                                             # (rows, K)
    rate, _ = channel.rate_and_slope(rho[:, :, None], h[:, None, :], part['c'][:, None, None])
    rho_part = (part['constant'][:, None] - part['linear'][:, None] * rho
                - part['weight'][:, None] * rho * rho)[:, :, None]
    dh = h[:, None, :] - h_k[:, None, None]
    apart = np.abs(dh) > 1e-9 * span
    numerator = rho_part + part['slope_h'][:, None, None] * dh - rate
    ratio = np.where(apart, numerator / np.where(apart, dh * dh, 1.0), 0.0)
    return np.maximum(ratio.max(axis=(1, 2)), 0.0)


def altitude_bound(q_k: np.ndarray, h_k: np.ndarray, p: np.ndarray, scenario: Scenario,
                   limits: AltitudeLimits) -> AltitudeBound:
    """The step's bound at q^k (M, 2), h^k (M,) metres for power p (N, M) watts."""
    channel = scenario.channel_model
    rho_k = np.sqrt(squared_horizontal_distances(q_k, scenario))
    heights = np.broadcast_to(np.asarray(h_k, dtype=float)[None, :], rho_k.shape)
    c = np.asarray(p, dtype=float) * snr_scale(scenario)
    coef = coefficients_at(channel, rho_k, heights, c)
    _, _, slope_h = channel.rate_gradient(rho_k, heights, c)
    rows = dict(rho_k=rho_k.ravel(), h_k=np.ascontiguousarray(heights).ravel(), c=c.ravel(),
                constant=coef.constant.ravel(), linear=coef.linear.ravel(),
                weight=coef.weight.ravel(), slope_h=slope_h.ravel())
    curvature = np.zeros(rho_k.size)
    for first in range(0, rho_k.size, _CHUNK):
        part = {key: value[first:first + _CHUNK] for key, value in rows.items()}
        curvature[first:first + _CHUNK] = _altitude_curvature(channel, limits, part)
    d = ALTITUDE_MARGIN * curvature.reshape(rho_k.shape)
    return AltitudeBound(constant=coef.constant - slope_h * heights - d * heights * heights,
                         linear=coef.linear, weight=coef.weight,
                         h_linear=slope_h + 2.0 * d * heights, h_weight=d)


def altitude_step(q_k: np.ndarray, h_k: np.ndarray, p: np.ndarray, scenario: Scenario,
                  limits: AltitudeLimits) -> tuple[np.ndarray, np.ndarray]:
    """One SCA step (module docstring): the maximiser (q (M, 2), h (M,) metres), in
    kilometres about the scene's centre for the solver."""
    bound = altitude_bound(q_k, h_k, p, scenario, limits)
    frame = Frame.of(scenario)
    v = Variables.of(frame)
    m = scenario.num_slots
    h = cp.Variable(m)
    w = frame.nodes
    constraints = LegLimits(frame).constraints(v, None)
    for n in range(scenario.num_nodes):
        squared = cp.sum(cp.square(v.z - w[n][None, :]), axis=1)
        distance = cp.norm(v.z - w[n][None, :], 2, axis=1)
        constraints.append(
            bound.constant[n].mean()
            - (bound.weight[n] * KM ** 2) @ squared / m - (bound.linear[n] * KM) @ distance / m
            + (bound.h_linear[n] * KM) @ h / m - (bound.h_weight[n] * KM ** 2) @ cp.square(h) / m
            >= v.t)
    low, high = limits.range_m
    constraints += [h >= low / KM, h <= high / KM]
    if m > 1:
        constraints.append(cp.abs(cp.diff(h)) <= limits.max_climb_mps * scenario.slot_s / KM)
    problem = cp.Problem(cp.Maximize(v.t), constraints)
    solve_usable(problem, 'altitude step', attempts=CLARABEL_ATTEMPTS)
    heights = np.clip(np.asarray(h.value) * KM, low, high)
    return frame.metres(np.asarray(v.z.value)), heights


@dataclass(frozen=True)
class AltitudePlan:
    """A plan with altitudes: trajectory q (M, 2) metres, altitudes h (M,) metres, power
    p (N, M) watts, rates R_n (N,) bit/s, min_throughput; history: the true min rate after
    every step (never decreasing); fixed: the best plan at one altitude, ``fixed_altitude_m``,
    that Algorithm 1 started from."""

    scenario: Scenario
    limits: AltitudeLimits
    trajectory: np.ndarray
    altitudes: np.ndarray
    power: np.ndarray
    rates: np.ndarray
    min_throughput: float
    history: tuple[float, ...]
    fixed: PlanResult
    fixed_altitude_m: float
    converged: bool
    solve_time_s: float

    @property
    def times(self) -> np.ndarray:
        return self.scenario.times_s


def best_fixed_altitude(scenario: Scenario, limits: AltitudeLimits,
                        settings: SolverSettings) -> tuple[float, PlanResult]:
    """The altitude in the range whose plan (:func:`plan`) is best, by a golden-section search
    of :data:`SEARCH_STEPS` steps, the range's ends included; (altitude m, its plan)."""
    low, high = limits.range_m
    plans: dict[float, PlanResult] = {}
    settings = dataclasses.replace(settings, compute_baselines=False)    # the plans alone

    def value(h: float) -> float:
        if h not in plans:
            plans[h] = plan(scenario.replace(altitude_m=h), settings)
        return plans[h].min_throughput

    ratio = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = low, high
    if high > low:
        x1, x2 = b - ratio * (b - a), a + ratio * (b - a)
        for _ in range(SEARCH_STEPS):
            if value(x1) >= value(x2):
                b, x2 = x2, x1
                x1 = b - ratio * (b - a)
            else:
                a, x1 = x1, x2
                x2 = a + ratio * (b - a)
        value(x1)
    value(high)
    value(low)
    best = max(plans, key=lambda h: plans[h].min_throughput)
    return best, plans[best]


def plan_with_altitude(scenario: Scenario, limits: AltitudeLimits | None = None,
                       settings: SolverSettings | None = None, *,
                       start_altitude_m: float | None = None) -> AltitudePlan:
    """Trajectory, altitudes and power (module docstring); ``scenario.altitude_m`` is not used.
    ``limits`` None takes the scenario's own (``altitude_range_m``, ``max_climb_mps``); given,
    they are the ones planned, and the result's scenario carries them, so that its JSON plans
    the same again. Algorithm 1 starts from the plan at ``start_altitude_m`` (None: the best
    fixed altitude, :func:`best_fixed_altitude`). Zones and an energy budget are not kept by
    the altitude step: refused."""
    if limits is None:
        limits = limits_of(scenario)
        if limits is None:
            raise InvalidScenarioError('a plan with altitudes needs limits or a scenario with '
                                       'altitude_range_m')
    if not isinstance(limits, AltitudeLimits):
        raise InvalidScenarioError(f'limits must be AltitudeLimits, got {type(limits).__name__}')
    scenario = scenario.replace(altitude_range_m=limits.range_m,
                                max_climb_mps=limits.max_climb_mps)
    if scenario.zones is not None or scenario.energy_budget_wh is not None:
        raise InvalidScenarioError('a plan with altitudes keeps the speed limits only: give no '
                                   'zones and no energy budget')
    settings = settings or SolverSettings()
    started = time.perf_counter()
    if start_altitude_m is None:
        fixed_altitude, fixed = best_fixed_altitude(scenario, limits, settings)
    else:
        fixed_altitude = real_number('start_altitude_m', start_altitude_m, 'metres')
        if not limits.range_m[0] <= fixed_altitude <= limits.range_m[1]:
            raise InvalidScenarioError(f'start_altitude_m {fixed_altitude:g} m is outside the '
                                       f'range {limits.range_m}')
        fixed = plan(scenario.replace(altitude_m=fixed_altitude), settings)
    q, p = fixed.trajectory, fixed.power
    h = np.full(scenario.num_slots, fixed_altitude)
    value = float(rates_3d(q, h, p, scenario).min())
    history = [value]
    converged = False
    for _ in range(settings.max_outer_iterations):
        before = value
        p_new = waterfilling_power(snr_per_watt_3d(q, h, scenario), scenario.power_budget_w).p
        new = float(rates_3d(q, h, p_new, scenario).min())
        if new >= value:         # the exact power step: it loses only to round-off
            p, value = p_new, new
        history.append(value)
        for _ in range(settings.max_inner_iterations):
            q_new, h_new = altitude_step(q, h, p, scenario, limits)
            q_new = project_onto_speed_limit(q_new, scenario)
            new = float(rates_3d(q_new, h_new, p, scenario).min())
            if new < value or not limits.holds(h_new, scenario.slot_s):
                break
            gain, q, h, value = new - value, q_new, h_new, new
            history.append(value)
            if gain <= _tolerance(settings, value):
                break
        if value - before <= _tolerance(settings, value):
            converged = True
            break
    rates = rates_3d(q, h, p, scenario)
    return AltitudePlan(scenario=scenario, limits=limits, trajectory=q, altitudes=h, power=p,
                        rates=rates, min_throughput=float(rates.min()), history=tuple(history),
                        fixed=fixed, fixed_altitude_m=fixed_altitude, converged=converged,
                        solve_time_s=time.perf_counter() - started)


def _tolerance(settings: SolverSettings, value: float) -> float:
    return max(settings.tolerance_bps, settings.relative_tolerance * abs(value))


__all__ = ['ALTITUDE_MARGIN', 'altitude_bound', 'altitude_step', 'AltitudeBound',
           'AltitudeLimits', 'AltitudePlan', 'best_fixed_altitude', 'plan_with_altitude',
           'rates_3d', 'snr_per_watt_3d']
