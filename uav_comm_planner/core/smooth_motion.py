"""A smooth reference through the plan's slot points at the slot times, within the limits.

The plan says where the UAV is at each slot time: q0 at t = 0, q[m] at m delta, qF at
(M + 1) delta. A vehicle that follows position and velocity targets needs a motion between
them. Here it is a C1 piecewise cubic (cubic Hermites of h = delta / PIECES_PER_SLOT seconds)
whose knots at the slot times are the plan's points, so it passes through every point at its
time by construction; the knots between them and every knot velocity are free (v = 0 at q0
and qF: the vehicle starts and ends at rest). On a piece of length h from p0 to p1, with
D = p1 - p0,

- the acceleration is linear in time, from a0 = (6 D - h (4 v0 + 2 v1)) / h^2 to
  a1 = (-6 D + h (2 v0 + 4 v1)) / h^2, so ||a|| <= A on the slot iff it holds at both ends;
- the jerk is constant, (a1 - a0) / h;
- the velocity is quadratic in time and linear in the knot velocities, so keeping it in a disc
  (the speed limit ||v|| <= V, or the airspeed one ||v - w|| <= V_air in wind w) at chosen
  instants of the slot is a second-order cone; it is bounded at the knots and at seven
  instants between (between those it can exceed the bound only by a small fraction, which
  :func:`bound_excess` measures at 64 instants per slot).

Each bound is a second-order cone in the free knots; among the motions that keep them,
:func:`smooth_motion` takes those of least integral of ||a||^2 (the natural cubic spline
when no bound is active), h (||a0||^2 + a0 . a1 + ||a1||^2) / 3 per piece. Every answer is
checked against the bounds with numpy before it is returned.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import cvxpy as cp
import numpy as np

from uav_comm_planner.core.conic import Certificate, solve_checked
from uav_comm_planner.errors import InfeasibleHorizonError

#: Bounds hold to this share of their value: the conic solver's accuracy, and the speed
#: between the instants where it is bounded (checked at CHECKED_PER_SLOT instants per slot).
BOUND_TOLERANCE = 1e-3
#: Where in each slot (share of its length) the speed bounds are constraints.
CONSTRAINED_S = (0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875)
CHECKED_PER_SLOT = 64
#: Cubics per slot: the plan's points are every PIECES_PER_SLOT-th knot.
PIECES_PER_SLOT = 4
_ATTEMPTS = ({}, {'tol_gap_abs': 1e-10, 'tol_gap_rel': 1e-10, 'tol_feas': 1e-10,
                  'max_iter': 500})


@dataclass(frozen=True)
class MotionBounds:
    """Limits of the reference: ground speed ``speed_mps`` (V), acceleration ``accel_mpss``
    (A), jerk ``jerk_mpsss`` (J; inf: none), and in wind ``wind_mps`` (2,) the air's velocity w
    with the airspeed ``airspeed_mps`` (None: no airspeed disc)."""

    speed_mps: float
    accel_mpss: float
    jerk_mpsss: float = math.inf
    wind_mps: tuple[float, float] = (0.0, 0.0)
    airspeed_mps: float | None = None


def hermite_ends(points: np.ndarray, velocities: np.ndarray,
                 h: float) -> tuple[np.ndarray, np.ndarray]:
    """Accelerations at the start and end of each slot (K - 1, 2) of the piecewise cubic
    through ``points`` (K, 2) with knot ``velocities`` (K, 2), slots of ``h`` seconds."""
    d = np.diff(points, axis=0)
    v0, v1 = velocities[:-1], velocities[1:]
    return ((6 * d - h * (4 * v0 + 2 * v1)) / h ** 2,
            (-6 * d + h * (2 * v0 + 4 * v1)) / h ** 2)


def _velocity_at(s: float, d, v0, v1, h: float):
    """The velocity a fraction ``s`` into each slot: 6 s (1 - s) D / h + (3 s^2 - 4 s + 1) v0
    + (3 s^2 - 2 s) v1 (numpy arrays or cvxpy expressions)."""
    return 6 * s * (1 - s) * d / h + (3 * s * s - 4 * s + 1) * v0 + (3 * s * s - 2 * s) * v1


def sampled_velocities(points: np.ndarray, velocities: np.ndarray, h: float,
                       per_slot: int = CHECKED_PER_SLOT) -> np.ndarray:
    """The velocity at ``per_slot`` + 1 evenly spaced instants of each slot, (S, K - 1, 2)."""
    d = np.diff(points, axis=0)
    return np.stack([_velocity_at(s, d, velocities[:-1], velocities[1:], h)
                     for s in np.linspace(0.0, 1.0, per_slot + 1)])


def bound_excess(points: np.ndarray, velocities: np.ndarray, h: float,
                 bounds: MotionBounds) -> dict[str, float]:
    """How far each bound is exceeded (<= 0 when it holds), relative to its value."""
    a0, a1 = hermite_ends(points, velocities, h)
    controls = sampled_velocities(points, velocities, h)
    excess = {
        'speed': float(np.linalg.norm(controls, axis=2).max()) / bounds.speed_mps - 1.0,
        'acceleration': float(max(np.linalg.norm(a0, axis=1).max(),
                                  np.linalg.norm(a1, axis=1).max())) / bounds.accel_mpss - 1.0,
    }
    if math.isfinite(bounds.jerk_mpsss):
        excess['jerk'] = float(np.linalg.norm(a1 - a0, axis=1).max()) / (
            h * bounds.jerk_mpsss) - 1.0
    if bounds.airspeed_mps is not None:
        air = np.linalg.norm(controls - np.asarray(bounds.wind_mps), axis=2).max()
        excess['airspeed'] = float(air) / bounds.airspeed_mps - 1.0
    return excess


def _motion(points: np.ndarray, h: float, bounds: MotionBounds, pieces: int,
            accel) -> tuple:
    """The piecewise cubic of :func:`smooth_motion` as cvxpy expressions: knot positions p
    (K', 2) (a numpy array when every knot is a plan point), the inner knot velocities (a
    variable (K' - 2, 2)), the accelerations a0, a1 at both ends of every piece, and the
    constraints of ``bounds`` with the acceleration bound ``accel`` (m/s/s: a number, or a
    cvxpy variable to be minimised)."""
    points = np.asarray(points, dtype=float)
    if len(points) < 2:
        raise InfeasibleHorizonError('a reference needs at least q0 and qF')
    step = h / pieces
    count = (len(points) - 1) * pieces + 1
    # Knot j is plan point j / pieces when pieces divides j, else a free point.
    fixed_rows = np.arange(0, count, pieces)
    free_rows = np.setdiff1d(np.arange(count), fixed_rows)
    place_fixed = np.zeros((count, len(points)))
    place_fixed[fixed_rows, np.arange(len(points))] = 1.0
    p = place_fixed @ points
    if len(free_rows):
        place_free = np.zeros((count, len(free_rows)))
        place_free[free_rows, np.arange(len(free_rows))] = 1.0
        free = cp.Variable((len(free_rows), 2))
        p = p + place_free @ free
    inner = cp.Variable((count - 2, 2))
    zero = np.zeros((1, 2))
    v = cp.vstack([zero, inner, zero])
    d = p[1:] - p[:-1]
    a0 = (6 * d - step * (4 * v[:-1] + 2 * v[1:])) / step ** 2
    a1 = (-6 * d + step * (2 * v[:-1] + 4 * v[1:])) / step ** 2
    constraints = [cp.norm(a0, 2, axis=1) <= accel,
                   cp.norm(a1, 2, axis=1) <= accel,
                   cp.norm(inner, 2, axis=1) <= bounds.speed_mps]
    w = np.asarray(bounds.wind_mps, dtype=float)[None, :]
    for s in CONSTRAINED_S:
        velocity = _velocity_at(s, d, v[:-1], v[1:], step)
        constraints.append(cp.norm(velocity, 2, axis=1) <= bounds.speed_mps)
        if bounds.airspeed_mps is not None:
            constraints.append(cp.norm(velocity - w, 2, axis=1) <= bounds.airspeed_mps)
    if math.isfinite(bounds.jerk_mpsss):
        constraints.append(cp.norm(a1 - a0, 2, axis=1) <= bounds.jerk_mpsss * step)
    if bounds.airspeed_mps is not None:
        constraints.append(cp.norm(inner - w, 2, axis=1) <= bounds.airspeed_mps)
    return p, inner, a0, a1, constraints


def least_acceleration(points: np.ndarray, h: float, bounds: MotionBounds, *,
                       pieces: int = PIECES_PER_SLOT) -> float:
    """The least acceleration bound A (m/s/s) under which :func:`smooth_motion` finds a
    motion through ``points`` at their slot times within the other ``bounds`` (speed,
    airspeed; jerk not bounded): min A s.t. ||a|| <= A at both ends of every piece, one
    second-order cone program. Raises :class:`~uav_comm_planner.errors.InfeasibleHorizonError`
    when no acceleration is enough (the points ask for more speed than the bounds allow)."""
    accel = cp.Variable(nonneg=True)
    unjerked = MotionBounds(bounds.speed_mps, math.inf, math.inf, bounds.wind_mps,
                            bounds.airspeed_mps)
    *_, constraints = _motion(points, h, unjerked, pieces, accel)
    problem = cp.Problem(cp.Minimize(accel), constraints)
    try:
        problem.solve(solver='CLARABEL')
    except cp.error.SolverError as exc:
        raise InfeasibleHorizonError(f'no acceleration found for the reference: {exc}') from exc
    if problem.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or accel.value is None:
        raise InfeasibleHorizonError(_why_infeasible(np.asarray(points, dtype=float), h,
                                                     unjerked))
    return float(accel.value)


def smooth_motion(points: np.ndarray, h: float, bounds: MotionBounds, *,
                  pieces: int = PIECES_PER_SLOT) -> tuple[np.ndarray, np.ndarray]:
    """Knot positions and velocities (K', 2) of the least-acceleration C1 cubic through
    ``points`` (K, 2) (q0, q[1..M], qF) at times 0, h, ..., (K - 1) h, at rest at both ends,
    within ``bounds``. Each slot is ``pieces`` cubics of h / pieces seconds: the knots at the
    slot times are the plan's points, those between them are free, which lets the motion keep
    its acceleration where one cubic per slot could not (a stop-and-go ramp). K' =
    (K - 1) pieces + 1; knot j is at time j h / pieces.

    Raises :class:`~uav_comm_planner.errors.InfeasibleHorizonError` when no such motion exists
    (the points ask for more than the bounds allow), and SolverError when the solver fails.
    """
    points = np.asarray(points, dtype=float)
    p, inner, a0, a1, constraints = _motion(points, h, bounds, pieces, bounds.accel_mpss)
    step = h / pieces
    zero = np.zeros((1, 2))
    # (||a0||^2 + a0.a1 + ||a1||^2) / 3 = (||a0 + a1 / 2||^2 + 3/4 ||a1||^2) / 3
    objective = cp.Minimize(step / 3 * (cp.sum_squares(a0 + a1 / 2)
                                        + 0.75 * cp.sum_squares(a1)))
    problem = cp.Problem(objective, constraints)

    def answer() -> tuple[np.ndarray, np.ndarray]:
        positions = p.value if isinstance(p, cp.Expression) else p
        return np.asarray(positions, dtype=float), np.vstack([zero, inner.value, zero])

    def certify() -> Certificate:
        positions, velocities = answer()
        worst = max(bound_excess(positions, velocities, step, bounds).values())
        return Certificate(max(worst, 0.0), BOUND_TOLERANCE)
    try:
        problem.solve(solver='CLARABEL')
    except cp.error.SolverError:
        pass
    if problem.status in (cp.INFEASIBLE, cp.INFEASIBLE_INACCURATE):
        raise InfeasibleHorizonError(_why_infeasible(points, h, bounds))
    if problem.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or not certify().holds:
        solve_checked(problem, 'reference', 'CLARABEL', _ATTEMPTS, certify)
    return answer()


def _why_infeasible(points: np.ndarray, h: float, bounds: MotionBounds) -> str:
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1) / h
    return (f'no smooth motion passes the {len(points)} plan points at their slot times '
            f'within speed {bounds.speed_mps:g} m/s, acceleration {bounds.accel_mpss:g} '
            f'm/s/s' + (f', jerk {bounds.jerk_mpsss:g} m/s/s/s'
                        if math.isfinite(bounds.jerk_mpsss) else '')
            + (f' and airspeed {bounds.airspeed_mps:g} m/s' if bounds.airspeed_mps else '')
            + f' (fastest slot {steps.max():.3g} m/s over {h:g} s slots)')


def hermite_state(points: np.ndarray, velocities: np.ndarray, h: float,
                  t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity and acceleration (len(t), 2) of the piecewise cubic at times ``t``
    (seconds from q0; before 0 at rest at q0, after the end at rest at the last point)."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    last = len(points) - 1
    clipped = np.clip(t, 0.0, last * h)
    k = np.minimum((clipped // h).astype(int), last - 1)
    s = (clipped - k * h)[:, None] / h
    p0, p1, v0, v1 = points[k], points[k + 1], velocities[k], velocities[k + 1]
    position = ((2 * s ** 3 - 3 * s ** 2 + 1) * p0 + (s ** 3 - 2 * s ** 2 + s) * h * v0
                + (-2 * s ** 3 + 3 * s ** 2) * p1 + (s ** 3 - s ** 2) * h * v1)
    velocity = ((6 * s ** 2 - 6 * s) * p0 + (3 * s ** 2 - 4 * s + 1) * h * v0
                + (-6 * s ** 2 + 6 * s) * p1 + (3 * s ** 2 - 2 * s) * h * v1) / h
    accel = ((12 * s - 6) * p0 + (6 * s - 4) * h * v0 + (-12 * s + 6) * p1
             + (6 * s - 2) * h * v1) / h ** 2
    outside = ((t < 0) | (t > last * h))[:, None]
    return position, np.where(outside, 0.0, velocity), np.where(outside, 0.0, accel)


__all__ = ['BOUND_TOLERANCE', 'MotionBounds', 'bound_excess', 'hermite_ends', 'hermite_state',
           'least_acceleration', 'sampled_velocities', 'smooth_motion']
