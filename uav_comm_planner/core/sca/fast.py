"""The SCA trajectory step on Clarabel directly: the blocks' cone program, built once per
form and updated in place.

Same problem as :func:`~uav_comm_planner.core.sca.reference.trajectory_step_cvxpy`, from the
same blocks (:func:`~uav_comm_planner.core.sca.program.step_blocks`): Clarabel solves
min -t subject to s = b - A x in the blocks' cones (:class:`~uav_comm_planner.core.sca.program.
ConeProgram`). Only the blocks' changing entries and rows of b change between SCA steps, so
the sparsity pattern is fixed by the form and the solver is updated in place; idle solvers
are kept by form across plans (:class:`SolverCache`).
"""

from __future__ import annotations

import functools
import itertools
import math
import threading
from typing import Sequence

import clarabel
import numpy as np

from uav_comm_planner.core.sca.block import BlockFactory, Expansion, Frame
from uav_comm_planner.core.sca.program import cone_program, step_blocks
from uav_comm_planner.core.sca.surrogate import KM, TrajectoryStep
from uav_comm_planner.core.sca.zones import NEAREST_PIECES
from uav_comm_planner.core.scenario import Scenario
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


#: An AlmostSolved step is kept when no block is broken by more than this share (seen: up to
#: 1e-6 on small scenes in wind); Algorithm 1's projection removes the excess.
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
    """Idle Clarabel solvers by form (the cone program's blocks' forms and the refinement),
    reused across plans: the cone program's sparsity depends on the form only, and every
    scenario-dependent entry (the changing entries and the whole of b) is updated before a
    solve.

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

    Call it like :func:`~uav_comm_planner.core.sca.reference.trajectory_step_cvxpy`:
    ``step = stepper(q_k, p, scenario)`` with q_k (M, 2) metres and p (N, M) watts. One
    instance serves one plan on one thread. Its solver comes from ``cache`` (:data:`SOLVERS`
    by default; None builds a fresh solver for every plan) and goes back after every solve.
    With ``keep_path_length`` every step keeps the path no longer than that of its expansion
    point q^k (:attr:`~uav_comm_planner.core.scenario.SolverSettings.keep_path_length`);
    ``blocks`` adds constraints (:class:`~uav_comm_planner.core.sca.block.Block` factories).
    """

    def __init__(self, scenario: Scenario, cache: SolverCache | None = SOLVERS, *,
                 keep_path_length: bool = False, blocks: Sequence[BlockFactory] = ()):
        self.scenario = scenario
        self.cache = cache
        self.keep_path_length = bool(keep_path_length)
        self.extra_blocks = tuple(blocks)
        self.tolerance: float | None = None
        self._id = next(_STEPPER_IDS)     # names this stepper's b in the cache
        self.frame = Frame.of(scenario)
        self.centre_m = self.frame.centre_m
        self.attempt = 0
        self.zone_pieces: int | None = NEAREST_PIECES
        self.zone_also: np.ndarray | None = None
        self._configure()

    def _configure(self) -> None:
        """Set up the form of :data:`ATTEMPTS` [self.attempt]; the solver is built on use."""
        partial_sums, self.refine = ATTEMPTS[self.attempt]
        self.blocks = step_blocks(self.frame, keep_path_length=self.keep_path_length,
                                  partial_sums=partial_sums, extra=self.extra_blocks,
                                  zone_pieces=self.zone_pieces, zone_also=self.zone_also)
        self.program = cone_program(self.blocks)
        self.b_fixed = np.concatenate([block.right_hand_side() for block in self.blocks])
        self.objective = np.zeros(self.program.num_columns)
        self.objective[0] = -1.0
        self._solver = None
        self._solver_tolerance = None
        self._b_is_ours = True
        self._positions_list = None

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
        return (self.program.num_slots, self.program.forms, self.refine)

    def changes(self, data: Sequence) -> tuple[np.ndarray, np.ndarray]:
        """The changing entries' values and the changing rows' b at this step, every block's
        in block order (:attr:`ConeProgram.changing`, :attr:`ConeProgram.changing_rows`)."""
        parts = [block.update(block_data) for block, block_data in zip(self.blocks, data)]
        return (np.concatenate([part[0] for part in parts]),
                np.concatenate([part[1] for part in parts]))

    def cone_data(self, data: Sequence) -> tuple[np.ndarray, np.ndarray]:
        """A's entries in build order and b at this step (the blocks' :meth:`at` data)."""
        entries, right = self.changes(data)
        values = self.program.values.copy()
        values[self.program.changing_build] = entries
        b = self.b_fixed.copy()
        b[self.program.changing_rows] = right
        return values, b

    def _solve(self, data: Sequence) -> clarabel.DefaultSolution:
        if self._solver is None and self.cache is not None:
            self._adopt(self.cache.take(self._form))
        if self._solver is None:
            values, b = self.cone_data(data)
            p, a = self.program.clarabel_matrices(values)
            self._solver = clarabel.DefaultSolver(
                p, self.objective.tolist(), a, b.tolist(), list(self.program.cones),
                self._settings())
            self._solver_tolerance = self.tolerance
        else:
            if self._solver_tolerance != self.tolerance:
                self._solver.update(settings=self._settings())
                self._solver_tolerance = self.tolerance
            if self._positions_list is None:
                # Lists for this plan only; the cached program keeps arrays.
                self._positions_list = (self.program.changing.tolist(),
                                        self.program.changing_rows.tolist())
            entries, right = self.changes(data)
            if self._b_is_ours:
                b = (self._positions_list[1], right.tolist())
            else:
                b = self.b_fixed.copy()
                b[self.program.changing_rows] = right
                b = b.tolist()
                self._b_is_ours = True
            self._solver.update(A=(self._positions_list[0], entries.tolist()), b=b)
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
        expansion = Expansion(np.asarray(q_k, dtype=float), p, offsets)
        while True:
            data = [block.at(expansion) for block in self.blocks]
            solution = self._solve(data)
            z = self._positions(solution)
            if solution.status == clarabel.SolverStatus.Solved or (
                    solution.status == clarabel.SolverStatus.AlmostSolved
                    and self.within_blocks(None if z is None else self.frame.metres(z), data)):
                if self._complete(self.frame.metres(z), data):
                    break
                continue
            self._solver = None
            if self.attempt == len(ATTEMPTS) - 1:
                raise SolverError(
                    f'trajectory step: Clarabel returned status {solution.status}; retry with '
                    "trajectory_method='cvxpy' or check the scenario for extreme values "
                    '(positions, powers)')
            self.attempt += 1
            self._configure()
        q = self.frame.metres(z)
        if not math.isfinite(q.sum()):     # a NaN or an infinity anywhere makes the sum one
            raise SolverError('trajectory step: Clarabel returned a non-finite trajectory')
        for block, block_data in zip(self.blocks, data):
            q = block.repair(q, block_data)
        return TrajectoryStep(q=q, bound_of=functools.partial(
            data[0].bound, self.frame.km(q), self.frame.nodes))

    def _complete(self, q: np.ndarray, data: Sequence) -> bool:
        """Whether q (M, 2) metres keeps what the blocks left out of the step; if not, the
        zones' rows come from twice the pieces from then on, for this step those nearest q^k
        or q too (the step is solved again, until an answer keeps them all), so the step's
        answer is always the whole problem's."""
        if all(block.complete(q, block_data) for block, block_data in zip(self.blocks, data)):
            if self.zone_also is not None:
                self.zone_also = None
                self._configure()
            return True
        self.zone_pieces = 2 * self.zone_pieces
        self.zone_also = q
        self._configure()
        return False

    def within_blocks(self, q: np.ndarray | None, data: Sequence) -> bool:
        """Whether an AlmostSolved step's q (M, 2) metres keeps every block to
        :data:`ALMOST_SOLVED_SLACK`.

        Clarabel reports AlmostSolved when its gap stalls just above the 1e-8 tolerance
        although the iterate is feasible to about its residual tolerance; such a step is kept
        once every block is checked here, since Algorithm 1 then projects it onto the limits,
        recomputes its value exactly and keeps it only if the true minimum rate does not drop.
        """
        if q is None or not np.all(np.isfinite(q)):
            return False
        return all(block.holds(q, block_data, ALMOST_SOLVED_SLACK)
                   for block, block_data in zip(self.blocks, data))

    def _positions(self, solution: clarabel.DefaultSolution) -> np.ndarray | None:
        """z (M, 2) km, centred, from the solution vector x = (t, z, ...); None without one."""
        x = solution.x
        if x is None:
            return None
        return np.array(x[1:1 + 2 * self.scenario.num_slots]).reshape(-1, 2)


def trajectory_step_clarabel(q_k: np.ndarray, p: np.ndarray, scenario: Scenario, *,
                             offsets: np.ndarray | None = None,
                             keep_path_length: bool = False,
                             blocks: Sequence[BlockFactory] = ()) -> TrajectoryStep:
    """One SCA step on a fresh Clarabel solver (stateless; a plan keeps one stepper instead)."""
    return ClarabelTrajectoryStep(scenario, keep_path_length=keep_path_length, blocks=blocks)(
        q_k, p, scenario, offsets=offsets)


__all__ = ['ALMOST_SOLVED_SLACK', 'ATTEMPTS', 'clarabel_settings', 'ClarabelTrajectoryStep',
           'KM', 'LOOSE_TOLERANCE', 'SolverCache', 'SOLVERS', 'trajectory_step_clarabel']
