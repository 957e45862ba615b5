"""An upper bound of the max-min throughput over every flyable trajectory: a Lagrangian dual
of the max-min problem, maximised over the trajectories by dynamic programming on a grid.

Claim. For node weights lambda (N,) >= 0 summing to 1 and a price nu > 0 per watt, let

    phi_n(a) = max_{p >= 0} [lambda_n / M log2(1 + p a) - nu p]
             = (lambda_n / (M ln 2)) ln(k_n a / nu) - k_n + nu / a  if k_n a > nu, else 0,

with k_n = lambda_n / (M ln 2) (attained at p = k_n / nu - 1 / a), and G(q) = sum_n phi_n(a_n(q))
with a_n(q) = N beta0 / (B sigma^2 (H^2 + ||q - w_n||^2)). Then every plan (q, p) with
sum p <= P_T and legs of at most V delta (q[0] = q0, q[M + 1] = qF) has

    min_n mean_m log2(1 + p_n[m] a_n[m]) <= nu P_T + max_{flyable q} sum_{m=1}^{M} G(q[m]).

Proof. min_n E_n <= sum_n lambda_n E_n, since lambda is a distribution; adding
nu (P_T - sum p) >= 0 and splitting the sums by slot gives nu P_T plus, for each slot m,
sum_n [lambda_n / M log2(1 + p_n[m] a_n[m]) - nu p_n[m]] <= G(q[m]) term by term. So the
max-min value (any plan's, the optimum's included) is at most nu P_T + sum_m G(q[m]) at its own
trajectory, hence at most the maximum over flyable trajectories.

The maximum over trajectories is bounded from above on a grid of square cells of side h over a
box that holds the nodes, q0 and qF and a margin: a cell's value U(c) = sum_n phi_n(a_n) with
a_n taken at the cell's point nearest to w_n, at least G anywhere in the cell, because phi_n
grows with a_n and a_n shrinks with the distance. Every point outside the box is one state,
"outside", with U_out = sum_n phi_n at w_n's distance to the box's edge. A leg of length at
most V delta joins two cells only if their nearest points are within V delta (cell offsets
(i, j) with max(|i| - 1, 0)^2 + max(|j| - 1, 0)^2 <= (V delta / h)^2), and joins "outside" only
to cells within V delta of the edge. Every flyable trajectory maps to a path of cells and
"outside" states allowed by these rules whose sum of U is at least sum_m G(q[m]), so the largest
such sum, found by dynamic programming backwards from qF (:func:`trajectory_bound`), bounds
the maximum. The airspeed limit in wind, keep-out zones and any other limit on the path only
shrink the flyable set, so the bound holds with them too.

Any (lambda, nu) gives a bound; :func:`dual_upper_bound` starts from the Lagrange multipliers
of a plan's own power step (where, on the plan's trajectory, the bound equals the plan's value)
and lowers it over nu by a golden-section search, the dual function being convex.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from scipy import ndimage

from uav_comm_planner.core.model import LN2, snr_at, snr_scale, spectral_efficiency_to_rate
from uav_comm_planner.core.scenario import Scenario

#: Cells per leg: the grid's side is h = V delta / CELLS_PER_LEG (and at most H / 2).
CELLS_PER_LEG = 4
#: At most this many cells in the grid: h grows to keep within it.
MAX_CELLS = 10_000
#: The margin of the box around the nodes, in altitudes H.
MARGIN_ALTITUDES = 4.0
#: Golden-section steps of the search over log nu.
NU_STEPS = 6


@dataclass(frozen=True)
class Grid:
    """Cells of side ``cell_m`` whose corners start at ``origin`` (2,), ``shape`` (nx, ny)."""

    origin: np.ndarray
    cell_m: float
    shape: tuple[int, int]

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        ix, iy = (np.arange(k) for k in self.shape)
        return (self.origin[0] + (ix + 0.5) * self.cell_m,
                self.origin[1] + (iy + 0.5) * self.cell_m)

    def squared_gaps(self, point: np.ndarray) -> np.ndarray:
        """(nx, ny): the squared distance from ``point`` to each cell's nearest point."""
        cx, cy = self.centres()
        half = self.cell_m / 2.0
        gx = np.maximum(np.abs(cx - point[0]) - half, 0.0)
        gy = np.maximum(np.abs(cy - point[1]) - half, 0.0)
        return gx[:, None] ** 2 + gy[None, :] ** 2

    def edge_distance(self, point: np.ndarray) -> float:
        """The distance from ``point`` (inside the box) to the box's edge."""
        upper = self.origin + self.cell_m * np.asarray(self.shape)
        return float(min(point[0] - self.origin[0], point[1] - self.origin[1],
                         upper[0] - point[0], upper[1] - point[1]))


def grid_for(scenario: Scenario) -> Grid:
    """The box around the nodes, q0 and qF with :data:`MARGIN_ALTITUDES` H to spare, in cells
    of side V delta / :data:`CELLS_PER_LEG` (at most H / 2; larger if that takes more than
    :data:`MAX_CELLS` cells)."""
    points = np.vstack([scenario.nodes, scenario.start_m, scenario.goal_m])
    margin = MARGIN_ALTITUDES * scenario.altitude_m
    low, high = points.min(axis=0) - margin, points.max(axis=0) + margin
    cell = min(scenario.max_step_m / CELLS_PER_LEG, scenario.altitude_m / 2.0)
    area = float(np.prod(high - low))
    cell = max(cell, math.sqrt(area / MAX_CELLS))
    shape = tuple(int(k) for k in np.ceil((high - low) / cell))
    return Grid(origin=low, cell_m=cell, shape=shape)


def _footprint_rows(reach_cells: float) -> list[tuple[int, int]]:
    """(row offset j, half-width) of the cell offsets a leg allows:
    max(|i| - 1, 0)^2 + max(|j| - 1, 0)^2 <= reach^2.

    :func:`_geometry` caps the reach at nx + ny + 2 cells: every row |j| < ny then reaches
    across the whole grid (half-width above nx) and the rows |j| >= ny fall off it, so the
    dilation is the same as with the leg's own reach, which a slot of hours makes billions of
    cells (a footprint of as many rows)."""
    rows = []
    span = int(math.floor(reach_cells)) + 1
    for j in range(-span, span + 1):
        rest = reach_cells ** 2 - max(abs(j) - 1, 0) ** 2
        if rest >= 0:
            rows.append((j, int(math.floor(math.sqrt(rest))) + 1))
    return rows


def _dilate(values: np.ndarray, rows: list[tuple[int, int]]) -> np.ndarray:
    """max over the allowed offsets: out[x, y] = max values[x + i, y + j] (-inf off the grid)."""
    out = np.full_like(values, -np.inf)
    filtered: dict[int, np.ndarray] = {}
    ny = values.shape[1]
    for j, half in rows:
        if abs(j) >= ny:
            continue
        if half not in filtered:
            filtered[half] = ndimage.maximum_filter1d(values, size=2 * half + 1, axis=0,
                                                      mode='constant', cval=-np.inf)
        row = filtered[half]
        if j >= 0:
            np.maximum(out[:, :ny - j], row[:, j:], out=out[:, :ny - j])
        else:
            np.maximum(out[:, -j:], row[:, :ny + j], out=out[:, -j:])
    return out


def _phi(a: np.ndarray, k: float, nu: float) -> np.ndarray:
    """max_{p >= 0} k ln(1 + p a) - nu p, elementwise."""
    ratio = k * a / nu
    with np.errstate(divide='ignore', invalid='ignore'):
        value = k * np.log(ratio) - k + nu / a
    return np.where(ratio > 1.0, value, 0.0)


@dataclass(frozen=True)
class _Geometry:
    grid: Grid
    snr: np.ndarray           # (N, nx, ny): a_n at each cell's point nearest to w_n, per watt
    snr_outside: np.ndarray   # (N,): a_n at w_n's distance to the box's edge
    rows: list[tuple[int, int]]
    border: np.ndarray        # (nx, ny) bool: cells within a leg of the box's edge
    first: np.ndarray         # (nx, ny) bool: cells a first leg from q0 reaches
    last: np.ndarray          # (nx, ny) bool: cells a last leg to qF leaves from
    first_outside: bool
    last_outside: bool


def _geometry(scenario: Scenario) -> _Geometry:
    grid = grid_for(scenario)
    scale, h2 = snr_scale(scenario), scenario.altitude_m ** 2
    reach = scenario.max_step_m
    if scenario.channel_model.is_letter:
        snr = np.stack([scale / (h2 + grid.squared_gaps(w)) for w in scenario.nodes])
        snr_outside = np.array([scale / (h2 + grid.edge_distance(w) ** 2)
                                for w in scenario.nodes])
    else:    # every channel's gain falls with the horizontal distance
        snr = np.stack([snr_at(grid.squared_gaps(w), scenario) for w in scenario.nodes])
        snr_outside = np.array([snr_at(grid.edge_distance(w) ** 2, scenario)
                                for w in scenario.nodes])
    cx, cy = grid.centres()
    half = grid.cell_m / 2.0
    upper = grid.origin + grid.cell_m * np.asarray(grid.shape)
    edge_gap = np.minimum.reduce([
        np.broadcast_to((cx - half - grid.origin[0])[:, None], grid.shape),
        np.broadcast_to((upper[0] - cx - half)[:, None], grid.shape),
        np.broadcast_to((cy - half - grid.origin[1])[None, :], grid.shape),
        np.broadcast_to((upper[1] - cy - half)[None, :], grid.shape)])
    start, goal = np.asarray(scenario.start_m, float), np.asarray(scenario.goal_m, float)
    return _Geometry(
        grid=grid, snr=snr, snr_outside=snr_outside,
        rows=_footprint_rows(min(reach / grid.cell_m, sum(grid.shape) + 2.0)),
        border=edge_gap <= reach,
        first=grid.squared_gaps(start) <= reach ** 2, last=grid.squared_gaps(goal) <= reach ** 2,
        first_outside=grid.edge_distance(start) <= reach,
        last_outside=grid.edge_distance(goal) <= reach)


def trajectory_bound(geometry: _Geometry, weights: np.ndarray, nu: float,
                     num_slots: int) -> float:
    """An upper bound of max over flyable q of sum_m G(q[m]) (module docstring), by dynamic
    programming over the cells and "outside", backwards from qF.

    A step of the programme is monotone and adds c to every state when c is added to every
    state. So if one step raised every state by at most r, every later step does too, and
    the states after k more steps are at most the present ones plus k r: once the rise is the
    same for every state (to :data:`RISE_SPREAD` of it, the value then grows by the best
    cell's value a slot), the remaining slots are added at once. The bound holds whenever
    this stops, and a long horizon (M = 100 000) costs as much as the first hundred slots."""
    ks = weights / (num_slots * LN2)
    cell_value = np.zeros(geometry.grid.shape)
    outside_value = 0.0
    for k, snr, snr_out in zip(ks, geometry.snr, geometry.snr_outside):
        if k > 0.0:
            cell_value += _phi(snr, k, nu)
            outside_value += float(_phi(np.array(snr_out), k, nu))
    cells = np.where(geometry.last, cell_value, -np.inf)
    outside = outside_value if geometry.last_outside else -math.inf
    remaining = num_slots - 1
    while remaining > 0:
        border_best = float(np.max(cells, where=geometry.border, initial=-np.inf))
        following = _dilate(cells, geometry.rows)
        following[geometry.border] = np.maximum(following[geometry.border], outside)
        stepped = cell_value + following
        stepped_outside = outside_value + max(outside, border_best)
        remaining -= 1
        rise = _uniform_rise(cells, outside, stepped, stepped_outside)
        cells, outside = stepped, stepped_outside
        if rise is not None and remaining:
            cells, outside = cells + remaining * rise, outside + remaining * rise
            break
    best = float(np.max(cells, where=geometry.first, initial=-np.inf))
    if geometry.first_outside:
        best = max(best, outside)
    return best


#: A step's rise counts as the same for every state when its spread is within this share
#: of the largest (the extrapolated bound is then at most this share above the exact one).
RISE_SPREAD = 1e-9


def _uniform_rise(cells: np.ndarray, outside: float, stepped: np.ndarray,
                  stepped_outside: float) -> float | None:
    """The largest rise of a state from ``cells``, ``outside`` to ``stepped``,
    ``stepped_outside``, if every reachable state rose by it to :data:`RISE_SPREAD`; None while
    the states reached still change or the rises differ."""
    before = np.append(cells.ravel(), outside)
    after = np.append(stepped.ravel(), stepped_outside)
    finite = np.isfinite(before)
    if not finite.any() or not np.array_equal(finite, np.isfinite(after)):
        return None
    rises = after[finite] - before[finite]
    top, bottom = float(rises.max()), float(rises.min())
    return top if top - bottom <= RISE_SPREAD * abs(top) else None


def power_multipliers(p: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, float]:
    """Node weights lambda (N,) and price nu of a max-min power schedule p (N, M) on SNR per
    watt a (N, M): the water levels mu_n = p + 1/a on the active slots, lambda_n proportional
    to mu_n, nu = 1 / (M ln 2 sum_n mu_n) (the water-filling's optimality conditions)."""
    active = p > 0.0
    levels = np.where(active, p + 1.0 / a, 0.0)
    counts = active.sum(axis=1)
    mu = np.where(counts > 0, levels.sum(axis=1) / np.maximum(counts, 1), 0.0)
    if not mu.sum() > 0.0:
        mu = np.ones(p.shape[0])
    weights = mu / mu.sum()
    return weights, 1.0 / (p.shape[1] * LN2 * mu.sum())


def dual_upper_bound(scenario: Scenario, p: np.ndarray, a: np.ndarray) -> float:
    """An upper bound of the max-min throughput of ``scenario`` over every plan, bit/s (module
    docstring): the node weights of the power schedule p (N, M) on SNR per watt a (N, M), any
    plan's (the better the plan, the tighter the bound), and the best price nu found by a
    golden-section search over log nu in [nu0 / 8, 8 nu0] around the schedule's own nu0."""
    weights, nu0 = power_multipliers(np.asarray(p, float), np.asarray(a, float))
    geometry = _geometry(scenario)
    m, budget = scenario.num_slots, scenario.power_budget_w

    def bits(log_nu: float) -> float:
        nu = math.exp(log_nu)
        return nu * budget + trajectory_bound(geometry, weights, nu, m)

    low, high = math.log(nu0) - math.log(8.0), math.log(nu0) + math.log(8.0)
    golden = (math.sqrt(5.0) - 1.0) / 2.0
    x1, x2 = high - golden * (high - low), low + golden * (high - low)
    f1, f2 = bits(x1), bits(x2)
    best = min(f1, f2, bits(math.log(nu0)))
    for _ in range(NU_STEPS):
        if f1 <= f2:
            high, x2, f2 = x2, x1, f1
            x1 = high - golden * (high - low)
            f1 = bits(x1)
        else:
            low, x1, f1 = x1, x2, f2
            x2 = low + golden * (high - low)
            f2 = bits(x2)
        best = min(best, f1, f2)
    return float(spectral_efficiency_to_rate(np.float64(best), scenario))


__all__ = ['dual_upper_bound', 'Grid', 'grid_for', 'power_multipliers', 'trajectory_bound']
