"""A block of the SCA trajectory step: one family of constraints, stated once.

The step works in kilometres about a centre c of the scene, z[m] = (q[m] - c) / 1000
(:class:`Frame`), and maximises a bound t subject to every block. A block says, in one class:

- **its constraints for cvxpy** (:meth:`Block.constraints`), from which the reference step
  (:mod:`~uav_comm_planner.core.sca.reference`) builds its problem afresh;
- **its rows of the cone program** s = b - A x in a product of cones (the fast step,
  :mod:`~uav_comm_planner.core.sca.fast`): its cones in row order (:meth:`Block.cones`), its
  own columns of x (:attr:`Block.num_columns`), the pattern of its entries of A, which depends
  on its :attr:`Block.form` only, b for the scenario (:meth:`Block.right_hand_side`), and which
  entries and rows of b change from step to step (:attr:`Block.changing_entries`,
  :attr:`Block.changing_rows`, :meth:`Block.update`). Rows and columns are numbered within
  the block; :class:`~uav_comm_planner.core.sca.program.ConeProgram` places them;
- **its part of the dual certificate** of an answer (:meth:`Block.certificate`): a Lagrangian
  term and its supergradient in z, added to a :class:`DualBound`;
- **its check** of an answer that a solver left within its tolerance (:meth:`Block.holds`),
  and an optional repair (:meth:`Block.repair`).

Per step, :meth:`Block.at` works out what the block needs at the expansion point (for the
node rates, the SCA bound's coefficients) once, for every one of the above.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Any, Callable, Sequence

import cvxpy as cp
import numpy as np

from uav_comm_planner.core.sca.surrogate import KM
from uav_comm_planner.core.scenario import Scenario


@dataclass(frozen=True)
class Frame:
    """Centred kilometres for ``scenario``: z = (q - centre_m) / 1000.

    Centred, ||z||^2 and ||w_n||^2 are of the order of the scene, not of its offset from the
    origin of the planning frame.
    """

    scenario: Scenario
    centre_m: np.ndarray

    @classmethod
    def of(cls, scenario: Scenario) -> 'Frame':
        """The frame centred on the box around the nodes, q0 and qF."""
        corners = np.vstack([scenario.nodes, scenario.start_m, scenario.goal_m])
        return cls(scenario, (corners.min(axis=0) + corners.max(axis=0)) / 2.0)

    def km(self, points_m: np.ndarray) -> np.ndarray:
        """Points (..., 2) metres in this frame, kilometres."""
        return (np.asarray(points_m, dtype=float) - self.centre_m) / KM

    def metres(self, z: np.ndarray) -> np.ndarray:
        """z (..., 2) kilometres in this frame, metres in the planning frame."""
        return np.asarray(z, dtype=float) * KM + self.centre_m

    @property
    def start(self) -> np.ndarray:
        """q0, (2,) km."""
        return self.km(self.scenario.start_m)

    @property
    def goal(self) -> np.ndarray:
        """qF, (2,) km."""
        return self.km(self.scenario.goal_m)

    @property
    def nodes(self) -> np.ndarray:
        """w, (N, 2) km."""
        return self.km(self.scenario.nodes)

    def legs(self, z: np.ndarray) -> np.ndarray:
        """The M + 1 legs of the path q0, z[1..M], qF: (M + 1, 2) km."""
        return np.diff(np.vstack([self.start, z, self.goal]), axis=0)


@dataclass(frozen=True)
class Expansion:
    """The point a step expands about: q_k (M, 2) metres, the power p (N, M) watts, and the
    offsets o (N,) bits per use (None: none)."""

    q_k: np.ndarray
    p: np.ndarray
    offsets: np.ndarray | None = None


@dataclass(frozen=True)
class Variables:
    """The reference step's cvxpy variables: z (M, 2) km and t, with the path's legs."""

    z: cp.Variable
    t: cp.Variable
    legs: cp.Expression

    @classmethod
    def of(cls, frame: Frame) -> 'Variables':
        z = cp.Variable((frame.scenario.num_slots, 2))
        path = cp.vstack([frame.start[None, :], z, frame.goal[None, :]])
        return cls(z=z, t=cp.Variable(), legs=path[1:] - path[:-1])


@dataclass(frozen=True)
class Columns:
    """Where the variables sit in x: t in column 0, z[m] in 1 + 2 m and 2 + 2 m, then each
    block's own columns, this block's from ``first``; ``shared`` names the first column of
    variables that earlier blocks share with later ones (:attr:`Block.shares`)."""

    num_slots: int
    first: int
    shared: dict = field(default_factory=dict)

    @property
    def z(self) -> np.ndarray:
        """(M, 2): the columns of z[m]_x and z[m]_y."""
        return 1 + np.arange(2 * self.num_slots).reshape(-1, 2)


@dataclass(frozen=True)
class Entries:
    """Entries of A: rows (within the block), columns (of x), values; in the block's order."""

    rows: np.ndarray
    cols: np.ndarray
    values: np.ndarray

    @classmethod
    def join(cls, *parts: 'Entries') -> 'Entries':
        """The parts one after another (their rows already within the block)."""
        return cls(*(np.concatenate(arrays) for arrays in
                     zip(*((p.rows, p.cols, p.values) for p in parts))))


@dataclass(frozen=True)
class DualBound:
    """Weak duality for the step at an answer z (M, 2) km.

    The step maximises min_n f_n(z) (each f_n strongly concave in z[m]) subject to the blocks.
    For multipliers lambda >= 0 summing to 1 on the nodes and >= 0 on every other constraint,
    the optimum is at most max_z L(z), L = sum_n lambda_n f_n + the blocks' terms. L is
    concave, and strongly so in each z[m] with modulus mu_m (``modulus``), so
    max_z L <= L(z) + sum_m ||g_m||^2 / (2 mu_m) with g (``gradient``) a supergradient of L
    at z. ``value`` is min_n f_n(z), ``lagrangian`` is L(z).
    """

    value: float
    lagrangian: float
    gradient: np.ndarray
    modulus: np.ndarray

    def plus(self, lagrangian: float, gradient: np.ndarray) -> 'DualBound':
        """With one more term of L and its supergradient (M, 2)."""
        return DualBound(self.value, self.lagrangian + lagrangian, self.gradient + gradient,
                         self.modulus)

    def ascent(self, gradient: np.ndarray | None = None) -> float:
        """sum_m ||g_m||^2 / (2 mu_m) for g = ``gradient`` (this bound's own by default)."""
        g = self.gradient if gradient is None else gradient
        squared = (g ** 2).sum(axis=1)
        if np.any((self.modulus <= 0.0) & (squared > 0.0)):
            return math.inf
        return float(np.divide(squared, 2.0 * self.modulus, out=np.zeros_like(squared),
                               where=self.modulus > 0.0).sum())

    @property
    def total(self) -> float:
        """The upper bound on the step's optimum, L(z) + the ascent."""
        return self.lagrangian + self.ascent()

    @property
    def gap(self) -> float:
        """How far z may be from the optimum, relative to max(1, |value|)."""
        return (self.total - self.value) / max(1.0, abs(self.value))


class Block:
    """One family of constraints of the SCA trajectory step (module docstring).

    Subclasses are built for one scenario's :class:`Frame` and set :attr:`form` (hashable: what
    fixes the pattern of their entries of A, never the scenario's numbers, which go into b or
    into the changing entries), :attr:`num_columns`, :attr:`changing_entries` and
    :attr:`changing_rows`. A block's changing entries and rows are given by :meth:`update` at
    every step.
    """

    #: Columns of x of the block's own (after t and z).
    num_columns: int = 0
    #: Indices, in :meth:`pattern`'s order, of the entries :meth:`update` gives every step.
    changing_entries: np.ndarray = np.zeros(0, dtype=int)
    #: Rows, within the block, whose b :meth:`update` gives every step.
    changing_rows: np.ndarray = np.zeros(0, dtype=int)
    #: Names of the block's own columns that later blocks may use, with their offset among
    #: them (:attr:`Columns.shared`), e.g. the legs' lengths for the path budget.
    shares: dict = {}

    def __init__(self, frame: Frame):
        self.frame = frame

    @property
    def form(self) -> tuple:
        raise NotImplementedError

    def cones(self) -> tuple:
        """The block's rows' cones (``clarabel`` cone objects), in row order."""
        raise NotImplementedError

    def pattern(self, columns: Columns) -> Entries:
        """The block's entries of A; changing ones may hold any value here."""
        raise NotImplementedError

    def right_hand_side(self) -> np.ndarray:
        """b of the block's rows for the scenario (changing rows: any value)."""
        raise NotImplementedError

    def at(self, expansion: Expansion) -> Any:
        """What the block needs at this expansion point; ``None`` by default."""
        return None

    def update(self, data: Any) -> tuple[np.ndarray, np.ndarray]:
        """The changing entries' values and the changing rows' b at this step."""
        return np.zeros(0), np.zeros(0)

    def constraints(self, v: Variables, data: Any) -> list[cp.Constraint]:
        """The block for cvxpy."""
        raise NotImplementedError

    def certificate(self, z: np.ndarray, data: Any, duals: Sequence[Any],
                    bound: DualBound) -> DualBound | None:
        """``bound`` with the block's term, from the duals of :meth:`constraints` in their
        order; None when z breaks the block (beyond a solver's tolerance)."""
        raise NotImplementedError

    def holds(self, q: np.ndarray, data: Any, slack: float) -> bool:
        """Whether q (M, 2) metres keeps the block to within the share ``slack``."""
        return True

    def admits(self, q: np.ndarray) -> bool:
        """Whether Algorithm 1 may start from q (M, 2) metres: the block holds there (True by
        default, for blocks that hold at every expansion point by construction, like the
        zones' restriction or the path budget). A start it does not admit is left out."""
        return True

    def complete(self, q: np.ndarray, data: Any) -> bool:
        """Whether a solver's answer q (M, 2) metres keeps the constraints the block left out
        of the step (True by default: a block imposes all of them)."""
        return True

    def repair(self, q: np.ndarray, data: Any) -> np.ndarray:
        """A solver's answer q (M, 2) metres moved to keep the block exactly (q by default)."""
        return q

    @property
    def num_rows(self) -> int:
        return int(sum(cone.dim for cone in self.cones()))


#: A block that is not built in (a user's constraint): made for each scenario's frame.
BlockFactory = Callable[[Frame], Block]

__all__ = ['Block', 'BlockFactory', 'Columns', 'DualBound', 'Entries', 'Expansion', 'Frame',
           'Variables']
