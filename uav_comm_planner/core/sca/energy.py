"""The energy block: the horizon's propulsion energy within the scenario's budget.

Leg l (q0 -> q[1], ..., q[M] -> qF, each flown over one slot delta) has the airspeed vector
v_l - w, v_l = leg_l / delta; in units of the airframe's induced velocity v0,
a_l = (leg_l / delta - w) / v0 and V_l = ||a_l||. Its power (Zeng, Xu and Zhang 2019, eq. (12),
:class:`~uav_comm_planner.core.propulsion.Airframe`) is

    P0 (1 + 3 v0^2 V^2 / U_tip^2) + Pi y + k v0^3 V^3,   y^2 = sqrt(1 + V^4 / 4) - V^2 / 2,

k = d0 rho s A / 2. The induced term is not convex in the trajectory; Zeng's slack form is:
y >= 0 with y^2 + V^2 >= 1 / y^2, whose left side is convex in (y, a) and is replaced by its
tangent at the expansion point (y_k, a_k), a global lower bound:

    2 y_k y - y_k^2 + 2 a_k . a - ||a_k||^2 >= 1 / y^2.

That implies the original (so the planned energy is at most the convexified one), holds with
equality at q^k (y_k^2 + V_k^2 = 1 / y_k^2), and keeps the step convex and never below its
expansion point. The budget: delta sum_l [P0 + 3 P0 v0^2 u_l / U^2 + Pi y_l + k v0^3 c_l] <= E
with u_l >= V_l^2 and c_l >= V_l^3.

Cone program, per leg (columns V, u, c, y, h, r): V >= ||a|| (a cone of dimension 3; a is
affine in z), u >= V^2 and r >= h^2 (rotated cones ((u + 1) / 2, V, (u - 1) / 2)),
c V >= u^2 (so c >= V^3) and h y >= 1 (so r >= h^2 >= 1 / y^2), each a cone of dimension 3;
then the tangent rows (changing with q^k) and the budget row, non-negative. The energy is
counted in units of the horizon at hover power, (M + 1) delta (P0 + Pi).

Dual certificate: with kappa the budget's multiplier, L gains kappa (E - E_hat(z)), E_hat the
convexified energy minimised over the slacks (convex in z, so L stays concave), whose gradient
follows y's root of 2 y_k y^3 + beta y^2 = 1, beta = 2 a_k . a - ||a_k||^2 - y_k^2.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import clarabel
import cvxpy as cp
import numpy as np

from uav_comm_planner.core.energy import horizon_energy_j, JOULES_PER_WH
from uav_comm_planner.core.propulsion import Airframe
from uav_comm_planner.core.sca.block import (Block, Columns, DualBound, Entries, Expansion,
                                             Frame, Variables)
from uav_comm_planner.core.sca.legs import leg_entries, leg_right_hand_side
from uav_comm_planner.core.sca.surrogate import KM

#: Columns per leg: V, u, c, y, h, r.
_V, _U, _C, _Y, _H, _R = range(6)
#: Bisections of the slack y's root in the certificate (to round-off on (0, 1]).
ROOT_BISECTIONS = 80
#: An answer's energy may exceed the budget by this share and be repaired (a solver's
#: tolerance); beyond it the answer breaks the block.
ENERGY_SLACK = 1e-7


def induced_slack(speed: np.ndarray) -> np.ndarray:
    """y(V) with y^2 = sqrt(1 + V^4 / 4) - V^2 / 2 (V in units of v0), written without
    cancellation: y = 1 / sqrt(sqrt(1 + V^4 / 4) + V^2 / 2)."""
    half = np.asarray(speed, dtype=float) ** 2 / 2.0
    return 1.0 / np.sqrt(np.sqrt(1.0 + half ** 2) + half)


@dataclass(frozen=True)
class EnergyPoint:
    """The expansion point's airspeeds a_k (M + 1, 2) and slacks y_k (M + 1,), in units of
    v0, and q^k (M, 2) metres."""

    q_k: np.ndarray
    a_k: np.ndarray
    y_k: np.ndarray


class EnergyBudget(Block):
    """The horizon's propulsion energy at most ``scenario.energy_budget_wh`` (module
    docstring); build it only for a scenario with an airframe and an energy budget."""

    def __init__(self, frame: Frame):
        super().__init__(frame)
        scenario = frame.scenario
        if scenario.airframe is None or scenario.energy_budget_wh is None:
            raise ValueError('EnergyBudget needs a scenario with an airframe and a budget')
        self.airframe: Airframe = scenario.airframe
        self.num_slots = scenario.num_slots
        self.legs = self.num_slots + 1
        self.delta = scenario.slot_s
        v0 = self.airframe.induced_velocity_mps
        self.v0 = v0
        # a_l = scale (z[l + 1] - z[l]) - w / v0, z in kilometres.
        self.scale = KM / (self.delta * v0)
        self.wind = scenario.wind_mps / v0
        self.budget_j = scenario.energy_budget_wh * JOULES_PER_WH
        self.unit_j = self.legs * self.delta * self.airframe.hover_power_w
        airframe = self.airframe
        self.coefficients = np.array([
            3.0 * airframe.blade_profile_power_w * v0 ** 2 / airframe.tip_speed_mps ** 2,
            airframe.induced_power_w, airframe.parasite_coefficient * v0 ** 3]) \
            * self.delta / self.unit_j                      # on u, y and c
        self.budget = (self.budget_j - self.legs * self.delta
                       * airframe.blade_profile_power_w) / self.unit_j
        self.num_columns = 6 * self.legs
        self.changing_rows = 15 * self.legs + np.arange(self.legs)
        # The tangent rows' z entries, as the legs' (-1 on z[l + 1], +1 on z[l]), one row a leg.
        tangent_z = leg_entries(Columns(self.num_slots, 0), 0)
        self._tangent_signs = tangent_z.values
        self._tangent_legs = (tangent_z.rows - 1) // 3
        self._tangent_coordinates = np.arange(len(tangent_z.rows)) % 2
        # Changing: the tangent rows' y and z entries, after the cones' (the airspeed cones'
        # L + 4 M entries, then 3, 5, 4 and 3 a leg).
        before = self.legs + 4 * self.num_slots + 15 * self.legs
        self.changing_entries = before + np.arange(self.legs + 4 * self.num_slots)

    @property
    def form(self) -> tuple:
        return ('energy', self.num_slots, self.scale, tuple(self.coefficients))

    def cones(self) -> tuple:
        return ((clarabel.SecondOrderConeT(3),) * (5 * self.legs)
                + (clarabel.NonnegativeConeT(self.legs + 1),))

    def _column(self, columns: Columns, kind: int) -> np.ndarray:
        return columns.first + 6 * np.arange(self.legs) + kind

    def pattern(self, columns: Columns) -> Entries:
        legs = self.legs
        col = {kind: self._column(columns, kind) for kind in range(6)}
        three = 3 * np.arange(legs)

        def cone(first: int, entries: Sequence[tuple[int, int, float]]) -> Entries:
            # entries: (row within the cone, column kind, value) per leg.
            return Entries(rows=np.concatenate([first + three + row for row, _, _ in entries]),
                           cols=np.concatenate([col[kind] for _, kind, _ in entries]),
                           values=np.concatenate([np.full(legs, value)
                                                  for _, _, value in entries]))

        airspeed = leg_entries(columns, 0)
        parts = [
            # (V, a): V >= ||a||, a = scale (z[l + 1] - z[l]) + b.
            Entries(rows=np.concatenate([three, airspeed.rows]),
                    cols=np.concatenate([col[_V], airspeed.cols]),
                    values=np.concatenate([-np.ones(legs), self.scale * airspeed.values])),
            # ((u + 1) / 2, V, (u - 1) / 2): u >= V^2.
            cone(3 * legs, [(0, _U, -0.5), (1, _V, -1.0), (2, _U, -0.5)]),
            # ((c + V) / 2, u, (c - V) / 2): c V >= u^2.
            cone(6 * legs, [(0, _C, -0.5), (0, _V, -0.5), (1, _U, -1.0), (2, _C, -0.5),
                            (2, _V, 0.5)]),
            # ((h + y) / 2, 1, (h - y) / 2): h y >= 1.
            cone(9 * legs, [(0, _H, -0.5), (0, _Y, -0.5), (2, _H, -0.5), (2, _Y, 0.5)]),
            # ((r + 1) / 2, h, (r - 1) / 2): r >= h^2.
            cone(12 * legs, [(0, _R, -0.5), (1, _H, -1.0), (2, _R, -0.5)]),
        ]
        # The tangent rows: -2 y_k on y, the z entries of 2 a_k . a (changing), +1 on r.
        tangent_z = leg_entries(columns, 0)
        parts.append(Entries(
            rows=np.concatenate([15 * legs + np.arange(legs), 15 * legs + self._tangent_legs,
                                 15 * legs + np.arange(legs)]),
            cols=np.concatenate([col[_Y], tangent_z.cols, col[_R]]),
            values=np.concatenate([np.zeros(legs), np.zeros(len(self._tangent_legs)),
                                   np.ones(legs)])))
        # The budget row: sum of the coefficients on u, y, c.
        parts.append(Entries(
            rows=np.full(3 * legs, 16 * legs),
            cols=np.concatenate([col[_U], col[_Y], col[_C]]),
            values=np.repeat(self.coefficients, legs)))
        return Entries.join(*parts)

    def right_hand_side(self) -> np.ndarray:
        legs = self.legs
        airspeed = self.scale * leg_right_hand_side(self.frame, 0.0,
                                                    self.wind / self.scale)
        rotated = np.tile([0.5, 0.0, -0.5], legs)
        unit = np.tile([0.0, 1.0, 0.0], legs)
        return np.concatenate([airspeed, rotated, np.zeros(3 * legs), unit, rotated,
                               np.zeros(legs), [self.budget]])

    def airspeeds(self, z: np.ndarray) -> np.ndarray:
        """a (M + 1, 2), in units of v0, of the path with slot points z (M, 2) km."""
        return self.scale * self.frame.legs(z) - self.wind

    def at(self, expansion: Expansion) -> EnergyPoint:
        a_k = self.airspeeds(self.frame.km(expansion.q_k))
        return EnergyPoint(q_k=expansion.q_k, a_k=a_k,
                           y_k=induced_slack(np.linalg.norm(a_k, axis=1)))

    def _tangent_constants(self, point: EnergyPoint) -> np.ndarray:
        """b of the tangent rows: the constant part of 2 y_k y + 2 a_k . a - r - y_k^2 -
        ||a_k||^2 >= 0 (a's constant part: the ends and the wind)."""
        constant = self.scale * self.frame.legs(np.zeros((self.num_slots, 2))) - self.wind
        return (2.0 * (point.a_k * constant).sum(axis=1) - point.y_k ** 2
                - (point.a_k ** 2).sum(axis=1))

    def update(self, point: EnergyPoint) -> tuple[np.ndarray, np.ndarray]:
        z_values = (2.0 * self.scale
                    * point.a_k[self._tangent_legs, self._tangent_coordinates]
                    * self._tangent_signs)
        return (np.concatenate([-2.0 * point.y_k, z_values]),
                self._tangent_constants(point))

    def constraints(self, v: Variables, point: EnergyPoint) -> list[cp.Constraint]:
        a = self.scale * v.legs - self.wind[None, :]
        speed = cp.norm(a, 2, axis=1)
        y = cp.Variable(self.legs, nonneg=True)
        tangent = (2.0 * cp.multiply(point.y_k, y) - point.y_k ** 2
                   + 2.0 * cp.sum(cp.multiply(point.a_k, a), axis=1)
                   - (point.a_k ** 2).sum(axis=1))
        blade, induced, parasite = self.coefficients
        energy = (blade * cp.sum_squares(speed) + induced * cp.sum(y)
                  + parasite * cp.sum(cp.power(speed, 3)))
        return [energy <= self.budget, tangent >= cp.power(y, -2)]

    def slack_root(self, point: EnergyPoint, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The least y >= 0 with 2 y_k y - y_k^2 + 2 a_k . a - ||a_k||^2 >= 1 / y^2 per leg, and
        beta = 2 a_k . a - ||a_k||^2 - y_k^2 (y is the root of 2 y_k y^3 + beta y^2 = 1)."""
        beta = 2.0 * (point.a_k * a).sum(axis=1) - (point.a_k ** 2).sum(axis=1) - point.y_k ** 2
        low = np.zeros_like(beta)
        high = np.maximum(np.abs(beta) / point.y_k, (1.0 / point.y_k) ** (1.0 / 3.0)) + 1.0
        for _ in range(ROOT_BISECTIONS):
            middle = 0.5 * (low + high)
            above = 2.0 * point.y_k * middle ** 3 + beta * middle ** 2 >= 1.0
            high = np.where(above, middle, high)
            low = np.where(above, low, middle)
        return high, beta

    def convexified(self, z: np.ndarray, point: EnergyPoint) -> tuple[float, np.ndarray]:
        """E_hat(z) in the budget's units, and its gradient in a (M + 1, 2)."""
        a = self.airspeeds(z)
        speed = np.linalg.norm(a, axis=1)
        y, beta = self.slack_root(point, a)
        blade, induced, parasite = self.coefficients
        energy = float(blade * (speed ** 2).sum() + induced * y.sum()
                       + parasite * (speed ** 3).sum())
        dy_dbeta = -y / (6.0 * point.y_k * y + 2.0 * beta)
        gradient = (2.0 * blade * a + 3.0 * parasite * speed[:, None] * a
                    + induced * (dy_dbeta * 2.0)[:, None] * point.a_k)
        return energy, gradient

    def certificate(self, z: np.ndarray, point: EnergyPoint, duals: Sequence,
                    bound: DualBound) -> DualBound | None:
        energy, gradient = self.convexified(z, point)
        if energy > self.budget + ENERGY_SLACK * (abs(self.budget) + 1.0):
            return None
        kappa = max(float(np.asarray(duals[0], dtype=float).reshape(-1)[0]), 0.0)
        # d a_l / d z[m]: +scale for the leg ending at z[m] (l = m), -scale for the next.
        slots = self.scale * (gradient[:-1] - gradient[1:])
        return bound.plus(kappa * (self.budget - energy), -kappa * slots)

    def energy_j(self, q: np.ndarray) -> float:
        """The true propulsion energy of q (M, 2) metres, J."""
        return horizon_energy_j(q, self.frame.scenario, self.airframe)

    def holds(self, q: np.ndarray, point: EnergyPoint, slack: float) -> bool:
        return self.energy_j(q) <= self.budget_j * (1.0 + slack)

    def admits(self, q: np.ndarray) -> bool:
        return self.energy_j(q) <= self.budget_j

    def repair(self, q: np.ndarray, point: EnergyPoint) -> np.ndarray:
        """q when its true energy keeps the budget; else the blend (1 - lam) q^k + lam q with
        the largest lam found by bisection that keeps it (q^k keeps it)."""
        if self.energy_j(q) <= self.budget_j:
            return q
        low, high = 0.0, 1.0
        for _ in range(40):
            middle = 0.5 * (low + high)
            if self.energy_j((1.0 - middle) * point.q_k + middle * q) <= self.budget_j:
                low = middle
            else:
                high = middle
        return (1.0 - low) * point.q_k + low * q


__all__ = ['EnergyBudget', 'EnergyPoint', 'induced_slack']
