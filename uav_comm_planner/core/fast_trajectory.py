"""The SCA trajectory step on Clarabel directly: a sparse cone program built once per plan.

Same problem as :func:`uav_comm_planner.core.trajectory.trajectory_step_cvxpy` (letter,
problem (11)): maximise t subject to mean_m lbr_{n,m}(q) >= t for every node n and every
leg at most V delta.
With z[m] = (q[m] - c) / 1000 (kilometres, about a centre c of the scene), the bound's weight
W_{n,m} = slope_{n,m} / d^k_{n,m} (d^k in km^2) and an epigraph variable u[m] >= ||z[m]||^2,

    ||z[m] - w_n||^2 = ||z[m]||^2 - 2 w_n . z[m] + ||w_n||^2,

so every node's constraint is linear in x = (t, z (M, 2), u (M,)):

    t + (1/M) sum_m W_{n,m} (u[m] - 2 w_n . z[m]) <= C_n - ||w_n||^2 (1/M) sum_m W_{n,m},

with C_n = mean_m (value_{n,m} + W_{n,m} ||q^k[m] - w_n||^2) as in the cvxpy form; the sum
over m is split into partial sums over blocks of slots (:func:`block_slots`). The speed
limits are M + 1 second-order cones of dimension 3, and u[m] >= ||z[m]||^2 is the rotated cone
||(z[m], (u[m] - 1) / 2)|| <= (u[m] + 1) / 2 of dimension 4. Replacing ||z[m]||^2 by u[m] is
exact: u appears only with non-negative weights on the small side of each constraint, so some
optimum has u[m] = ||z[m]||^2.

With zones, K linear rows per slot (:mod:`uav_comm_planner.core.zone_rows`, the restriction
at q^k) follow, in a non-negative cone of their own. With a path budget (a warm replan's
``keep_path_length``) the speed cones bound each leg by a variable s[l] instead of V delta,
||z[l + 1] - z[l]|| <= s[l], and M + 2 linear rows come last: s[l] <= V delta, and
sum_l s[l] <= L^k, the length of the path at q^k (the same cones, a quarter fewer rows than
cones of their own for the lengths).

Only the node rows, the zone rows and the path budget change between SCA iterations
(coefficients and right-hand sides), so the sparsity pattern is fixed by the form (N, M, K,
which rows are there) and the solver is updated in place.
"""

from __future__ import annotations

from dataclasses import dataclass
import functools
import itertools
import math
import threading

import clarabel
import numpy as np

from uav_comm_planner.core.cone_layout import block_slots, cone_layout, fixed_right_hand_side
from uav_comm_planner.core.feasibility import within_speed_limit
from uav_comm_planner.core.model import flown_path
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.core.trajectory import (kilometre_rows, KM, path_length_km,
                                              surrogate_coefficients, TrajectoryStep,
                                              with_offsets, within_path_budget)
from uav_comm_planner.core.zone_rows import zone_model
from uav_comm_planner.errors import SolverError


def clarabel_settings(*, refine: bool) -> clarabel.DefaultSettings:
    """Clarabel's default 1e-8 tolerances; presolve off, because it forbids in-place updates.

    A 1e-8 gap on t, a spectral efficiency of order 1 to 40 bits, already puts each step's
    bound within 1e-9 of the reference's; asking for 1e-10 here can end in AlmostSolved.
    Iterative refinement of the KKT solves costs about a quarter of the solve time on small
    problems and is rarely needed here: Clarabel checks its residuals on the iterates, so a
    Solved status holds either way, and a step that fails without it is tried again with it
    (see :data:`ATTEMPTS`).
    Equilibration is off: Clarabel scales updated data by the factors it computed from the
    first data a solver saw, so with it a solver reused across plans (:class:`SolverCache`)
    would give answers that depend on the plans before; without it a step's answer depends
    on the step's data alone, and the same scenario always gets the same plan. The data is
    already in kilometres about the scene's centre; the iteration counts were seen to be about
    the same.
    """
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.presolve_enable = False
    settings.input_sparse_dropzeros = False
    settings.iterative_refinement_enable = refine
    settings.equilibrate_enable = False
    return settings


@dataclass(frozen=True)
class NodeRows:
    """mean_m lbr_{n,m}(z) = constant_n - (1/M) sum_m weight_{n,m} ||z[m] - w_n||^2.

    weight: W (N, M), per km^2; constant: C (N,) bits per use.
    """

    weight: np.ndarray
    constant: np.ndarray

    def bound(self, z: np.ndarray, w: np.ndarray) -> float:
        """min_n mean_m lbr_{n,m} at z (M, 2) km, nodes w (N, 2) km in the same frame."""
        spread = ((z[None, :, :] - w[:, None, :]) ** 2).sum(axis=-1)
        return float((self.constant - (self.weight * spread).mean(axis=1)).min())


#: An AlmostSolved step is kept when no leg exceeds a limit by more than this share (seen:
#: up to 1e-6 on small scenes in wind); the projection removes the excess.
ALMOST_SOLVED_SLACK = 1e-5
#: (partial sums over blocks, iterative refinement) for each try at a step, fastest first.
#: A step that does not reach Solved is tried again in the next form, which then serves
#: the rest of the plan: refinement makes the KKT solves more accurate, and the form without
#: partial sums has no degenerate e_{n,k} (blocks where every weight is zero).
ATTEMPTS = ((True, False), (True, True), (False, True))
#: The loose interior-point tolerance (duality gap, absolute and relative, and feasibility)
#: that :meth:`ClarabelTrajectoryStep.set_tolerance` offers for the steps before the last.
LOOSE_TOLERANCE = 1e-4


class SolverCache:
    """Idle Clarabel solvers by form (N, M, block size, airspeed cones, zone rows, path budget,
    refinement), reused across plans: the cone program's sparsity depends on the form only,
    and every scenario-dependent entry (the node and zone rows and the whole of b) is updated
    before a solve.

    A solver is taken out while it solves and given back after, so two threads never share
    one; at most ``per_form`` idle solvers are kept for each of the last ``forms`` forms.
    """

    def __init__(self, forms: int = 8, per_form: int = 2):
        self.forms, self.per_form = forms, per_form
        self._idle: dict[tuple, list] = {}
        self._lock = threading.Lock()

    def take(self, form: tuple):
        """An idle solver of this form as (solver, owner, tolerance), or None."""
        with self._lock:
            idle = self._idle.get(form)
            return idle.pop() if idle else None

    def give(self, form: tuple, entry: tuple) -> None:
        with self._lock:
            idle = self._idle.pop(form, [])   # re-inserted last: the most recently used form
            if len(idle) < self.per_form:
                idle.append(entry)
            self._idle[form] = idle
            while len(self._idle) > self.forms:
                del self._idle[next(iter(self._idle))]

    def clear(self) -> None:
        with self._lock:
            self._idle.clear()


#: The solvers every :class:`ClarabelTrajectoryStep` draws from.
SOLVERS = SolverCache()
_STEPPER_IDS = itertools.count()


class ClarabelTrajectoryStep:
    """SCA trajectory steps for one scenario, on one Clarabel solver updated in place.

    Call it like :func:`~uav_comm_planner.core.trajectory.trajectory_step_cvxpy`:
    ``step = stepper(q_k, p, scenario)`` with q_k (M, 2) metres and p (N, M) watts. One
    instance serves one plan on one thread. Its solver comes from ``cache`` (:data:`SOLVERS`
    by default; None builds a fresh solver for every plan) and goes back after every solve.
    With ``keep_path_length`` every step keeps the path no longer than that of its expansion
    point q^k (:attr:`~uav_comm_planner.core.scenario.SolverSettings.keep_path_length`).
    """

    def __init__(self, scenario: Scenario, cache: SolverCache | None = SOLVERS, *,
                 keep_path_length: bool = False):
        self.scenario = scenario
        self.cache = cache
        self.keep_path_length = bool(keep_path_length)
        self.tolerance: float | None = None
        self._id = next(_STEPPER_IDS)     # names this stepper's b in the cache
        corners = np.vstack([scenario.nodes, scenario.start_m, scenario.goal_m])
        # Centred kilometres keep ||z||^2 and ||w_n||^2 of the order of the scene, not its offset.
        self.centre_m = (corners.min(axis=0) + corners.max(axis=0)) / 2.0
        self.w = (scenario.nodes - self.centre_m) / KM
        m = scenario.num_slots
        # Slot m's (z_x, z_y, u) coefficients in node n's bound are W_{n,m} times these.
        self._coefficient_factors = np.concatenate(
            [-2.0 / m * self.w, np.full((scenario.num_nodes, 1), 1.0 / m)], axis=1)[:, None, :]
        self._w_squared = (self.w ** 2).sum(axis=1)
        self._node_index = list(range(scenario.num_nodes))
        self.zones = zone_model(scenario.zones)
        self.attempt = 0
        self._configure()

    def _configure(self) -> None:
        """Set up the form of :data:`ATTEMPTS` [self.attempt]; the solver is built on use."""
        blocks, self.refine = ATTEMPTS[self.attempt]
        n, m = self.scenario.num_nodes, self.scenario.num_slots
        self.layout = cone_layout(n, m, block_slots(n) if blocks else m,
                                  air_legs=self.scenario.airspeed_limited,
                                  zone_rows=0 if self.zones is None else self.zones.rows_per_slot,
                                  path_budget=self.keep_path_length)
        self.b_fixed = fixed_right_hand_side(self.scenario, self.layout, self.centre_m)
        self.objective = np.zeros(self.layout.num_columns)
        self.objective[0] = -1.0
        self._solver = None
        self._solver_tolerance = None
        self._b_is_ours = True
        self._update_positions = None

    def set_tolerance(self, tolerance: float | None) -> None:
        """Stop later steps at this duality gap and feasibility (e.g. :data:`LOOSE_TOLERANCE`);
        None restores Clarabel's 1e-8 (:func:`clarabel_settings`)."""
        self.tolerance = tolerance

    def _settings(self) -> clarabel.DefaultSettings:
        settings = clarabel_settings(refine=self.refine)
        if self.tolerance is not None:
            settings.tol_gap_abs = settings.tol_gap_rel = self.tolerance
            settings.tol_feas = self.tolerance
            settings.tol_ktratio = max(settings.tol_ktratio, self.tolerance)
        return settings

    @property
    def _form(self) -> tuple:
        layout = self.layout
        return (layout.num_nodes, layout.num_slots, layout.block_slots, layout.air_legs,
                layout.zone_rows, layout.path_budget, self.refine)

    def node_rows(self, q_k: np.ndarray, p: np.ndarray,
                  offsets: np.ndarray | None = None) -> NodeRows:
        """The bound's weights and constants, expanded at q_k (M, 2) with power p (N, M);
        offsets o (N,) bits per use, if any, add to the constants."""
        weight, constant = kilometre_rows(surrogate_coefficients(q_k, p, self.scenario))
        return NodeRows(weight=weight, constant=with_offsets(constant, offsets))

    def coefficients(self, rows: NodeRows) -> np.ndarray:
        """The changing entries of A: (N, M, 3), slot m's (z_x, z_y, u) coefficients in node
        n's bound, (1/M) W_{n,m} (-2 w_n, 1); their build order is this array's."""
        return rows.weight[:, :, None] * self._coefficient_factors

    def node_right_hand_side(self, rows: NodeRows) -> np.ndarray:
        """b of the N node rows: C_n - ||w_n||^2 (1/M) sum_m W_{n,m}."""
        return rows.constant - self._w_squared * (rows.weight.sum(axis=1) / rows.weight.shape[1])

    def zone_data(self, q_k: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """The zone rows' entries of A ((M, K, 2) build order) and b (M K,) for the
        restriction at q_k: a . q >= o is a . z >= (o - a . centre) / 1000, and Clarabel's
        s = b - A x >= 0 takes A = -a, b = -(o - a . centre) / 1000. None without zones."""
        if self.zones is None:
            return None
        rows = self.zones.rows(flown_path(q_k, self.scenario))
        b = -(rows.offsets - rows.normals @ self.centre_m) / KM
        return -rows.normals, b.ravel()

    def cone_data(self, rows: NodeRows,
                  zones: tuple[np.ndarray, np.ndarray] | None = None,
                  budget_km: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """A's entries in build order and b for these node rows (and zone rows, and the path
        budget in kilometres)."""
        values = self.layout.values.copy()
        first = self.layout.first_coefficient
        coefficients = self.coefficients(rows).ravel()
        values[first:first + len(coefficients)] = coefficients
        b = self.b_fixed.copy()
        b[:self.scenario.num_nodes] = self.node_right_hand_side(rows)
        if zones is not None:
            entries, right = zones
            values[len(values) - entries.size:] = entries.ravel()
            b[self.layout.first_zone_row:self.layout.first_zone_row + right.size] = right
        if budget_km is not None:
            b[self.layout.budget_row] = budget_km
        return values, b

    def _solve(self, rows: NodeRows, zones: tuple[np.ndarray, np.ndarray] | None = None,
               budget_km: float | None = None) -> clarabel.DefaultSolution:
        if self._solver is None and self.cache is not None:
            self._adopt(self.cache.take(self._form))
        if self._solver is None:
            values, b = self.cone_data(rows, zones, budget_km)
            p, a = self.layout.clarabel_matrices(values)
            self._solver = clarabel.DefaultSolver(
                p, self.objective.tolist(), a, b.tolist(), list(self.layout.cones),
                self._settings())
            self._solver_tolerance = self.tolerance
        else:
            if self._solver_tolerance != self.tolerance:
                self._solver.update(settings=self._settings())
                self._solver_tolerance = self.tolerance
            positions, coefficient = self.layout.node_entries
            if self._update_positions is None:
                # A list for this plan only; the cached layout keeps arrays, a fifth the size.
                self._update_positions = positions.tolist()
            changed = self.coefficients(rows).ravel()[coefficient]
            if zones is None:
                a = (self._update_positions, changed.tolist())
                b = (self._node_index, self.node_right_hand_side(rows).tolist())
            else:
                entries, right = zones
                first = self.layout.first_zone_row
                a = (self._update_positions + self.layout.zone_entries.tolist(),
                     changed.tolist() + entries.ravel().tolist())
                b = (self._node_index + list(range(first, first + right.size)),
                     self.node_right_hand_side(rows).tolist() + right.tolist())
            if budget_km is not None:
                b = (b[0] + [self.layout.budget_row], b[1] + [budget_km])
            if not self._b_is_ours:
                b = self.cone_data(rows, zones, budget_km)[1].tolist()
            self._solver.update(A=a, b=b)
        solution = self._solver.solve()
        if self.cache is not None:
            self.cache.give(self._form, (self._solver, self._id, self._solver_tolerance))
            self._solver = None
        return solution

    def _adopt(self, entry: tuple | None) -> None:
        """Take a cached (solver, owner, tolerance): its b is this scenario's only if it last
        served this stepper."""
        if entry is not None:
            self._solver, owner, self._solver_tolerance = entry
            self._b_is_ours = owner == self._id

    def __call__(self, q_k: np.ndarray, p: np.ndarray, scenario: Scenario, *,
                 offsets: np.ndarray | None = None) -> TrajectoryStep:
        """One SCA step expanded at q_k (M, 2) metres with power p (N, M) watts; with offsets
        o (N,) bits per use it maximises min_n (o_n + mean_m lbr_{n,m})."""
        if scenario is not self.scenario and scenario != self.scenario:
            raise ValueError('this trajectory stepper was built for another scenario')
        rows = self.node_rows(q_k, p, offsets)
        zones = self.zone_data(q_k)
        budget = path_length_km(q_k, scenario) if self.keep_path_length else None
        while True:
            solution = self._solve(rows, zones, budget)
            z = self._positions(solution)
            if solution.status == clarabel.SolverStatus.Solved or (
                    solution.status == clarabel.SolverStatus.AlmostSolved
                    and almost_solved_within_limits(None if z is None
                                                    else z * KM + self.centre_m,
                                                    self.scenario, budget)):
                break
            self._solver = None
            if self.attempt == len(ATTEMPTS) - 1:
                raise SolverError(
                    f'trajectory step: Clarabel returned status {solution.status}; retry with '
                    "trajectory_method='cvxpy' or check the scenario for extreme values "
                    '(positions, powers)')
            self.attempt += 1
            self._configure()
        q = z * KM + self.centre_m
        if not math.isfinite(q.sum()):     # a NaN or an infinity anywhere makes the sum one
            raise SolverError('trajectory step: Clarabel returned a non-finite trajectory')
        if budget is not None:
            q = within_path_budget(q, q_k, scenario, budget)
            z = (q - self.centre_m) / KM
        return TrajectoryStep(q=q, bound_of=functools.partial(rows.bound, z, self.w))

    def _positions(self, solution: clarabel.DefaultSolution) -> np.ndarray | None:
        """z (M, 2) km, centred, from the solution vector x = (t, z, u); None without one."""
        x = solution.x
        if x is None:
            return None
        return np.array(x[1:1 + 2 * self.scenario.num_slots]).reshape(-1, 2)


def almost_solved_within_limits(q: np.ndarray | None, scenario: Scenario,
                                budget_km: float | None = None) -> bool:
    """Whether an AlmostSolved step's q (M, 2) metres keeps every leg within the speed limits
    (and the path within ``budget_km``) to :data:`ALMOST_SOLVED_SLACK` (the one check,
    :func:`~uav_comm_planner.core.feasibility.within_speed_limit`).

    Clarabel reports AlmostSolved when its gap stalls just above the 1e-8 tolerance although
    the iterate is feasible to about its residual tolerance; such a step is kept once the
    speed limits are checked here, since Algorithm 1 then projects it onto the limits,
    recomputes its value exactly and keeps it only if the true minimum rate does not drop.
    """
    if q is None:
        return False
    return within_speed_limit(q, scenario, slack=ALMOST_SOLVED_SLACK) and (
        budget_km is None
        or path_length_km(q, scenario) <= budget_km * (1 + ALMOST_SOLVED_SLACK))


def trajectory_step_clarabel(q_k: np.ndarray, p: np.ndarray, scenario: Scenario, *,
                             offsets: np.ndarray | None = None,
                             keep_path_length: bool = False) -> TrajectoryStep:
    """One SCA step on a fresh Clarabel solver (stateless; a plan keeps one stepper instead)."""
    return ClarabelTrajectoryStep(scenario, keep_path_length=keep_path_length)(
        q_k, p, scenario, offsets=offsets)
