"""Hover splits searched: a tour's spare slots moved between neighbouring stops while one power
step on the tour says the plan gets better, before Algorithm 1 continues from it.

Why: Algorithm 1 moves hover time from one node to another only slowly (a hover moved shifts
every slot point between the two nodes by a slot), so the split a start begins with largely
decides where it converges. Two starts with the same visiting order and other splits end
apart: on the benchmark's low-SNR drop 1000 the 17 screened tours with its best order
converged from 806 to 848 kbit/s. The value of a split is read off the tour itself, flown
(:func:`~uav_comm_planner.core.initial.fly_legs`) and given its optimal power, one
water-filling step (about 0.1 ms): no trajectory step.

:func:`searched_split` climbs from a split: every move of ``step`` slots from a stop to the
stop before or after it on the tour is tried, the best that gains is taken until none does,
then ``step`` is halved, from an eighth of the spare slots down to one: it ends at a split that
no move of one slot to a neighbouring stop improves (a local optimum; chains of such moves
carry hover time along the tour). Moves between any two stops found splits about as good on
the benchmark's low-SNR drops, for many more values (4827 instead of 604 for N = 20).
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from uav_comm_planner.core.initial import TourFlier
from uav_comm_planner.core.model import snr_per_watt
from uav_comm_planner.core.scenario import Scenario

#: A split must gain more than this share of the value of the split it replaces.
MIN_GAIN = 1e-9


def searched_split(hovers: np.ndarray, value_of: Callable[[np.ndarray], float], *,
                   values_of: Callable[[np.ndarray], np.ndarray] | None = None
                   ) -> tuple[np.ndarray, float]:
    """The split (integers, one per stop in tour order) reached from ``hovers`` by moves of
    slots to a neighbouring stop that raise ``value_of`` (module docstring), and its value.
    ``values_of``, if given, values every move of one round at once (splits (K, stops) to
    values (K,)), as ``value_of`` would each."""
    best = np.asarray(hovers, dtype=int).copy()
    value = value_of(best)
    stops = len(best)
    step = max(1, int(best.sum()) // 8)
    while step >= 1 and stops >= 2:
        while True:
            moves = _moves(best, step)
            if not len(moves):
                break
            values = (values_of(moves) if values_of is not None else
                      np.array([value_of(moved) for moved in moves]))
            k = int(np.argmax(values))
            if values[k] <= value + MIN_GAIN * abs(value):
                break
            best, value = moves[k], float(values[k])
        step //= 2
    return best, value


def _moves(split: np.ndarray, step: int) -> np.ndarray:
    """Every split one move of ``step`` slots from a stop to the stop before or after it
    makes from ``split``, (K, stops), in the order: givers in tour order, the stop before
    first."""
    stops = len(split)
    givers = np.flatnonzero(split >= step)
    givers = np.repeat(givers, 2)
    takers = givers + np.tile([-1, 1], len(givers) // 2)
    inside = (takers >= 0) & (takers < stops)
    givers, takers = givers[inside], takers[inside]
    moves = np.repeat(split[None, :], len(givers), axis=0)
    rows = np.arange(len(givers))
    moves[rows, givers] -= step
    moves[rows, takers] += step
    return moves


def _all_active(log_sum: np.ndarray, inverse_sum: float, least: np.ndarray, slots: int,
                power_budget_w: float) -> float | None:
    """The closed form of the all-active power step from its sums (node n's
    sum_m log2 a_n[m] (N,), sum_{n,m} 1/a_n[m], node n's min_m a_n[m] (N,), M): the max-min
    efficiency, bits per use, or None when not every slot would be active (or P_T is below a
    thousandth of sum 1/a, where the closed form loses digits).

    With every slot active node n's efficiency is log2 mu_n + mean_m log2 a_n[m], equal for
    all n, and the budget gives mu_n = (P_T + sum 1/a) / (M sum_k G_min / G_k) G_min / G_n
    (G_n the geometric mean of a_n, :func:`~uav_comm_planner.core.power.waterfilling_power`);
    the slots are all active when mu_n min_m a_n[m] >= 1."""
    bits = float(_all_active_rows(np.asarray(log_sum)[None, :], np.array([inverse_sum]), least,
                                  slots, power_budget_w)[0])
    return None if math.isnan(bits) else bits


def _all_active_rows(log_sums: np.ndarray, inverse_sums: np.ndarray, least: np.ndarray,
                     slots: int, power_budget_w: float) -> np.ndarray:
    """:func:`_all_active` for K splits at once (log sums (K, N), inverse sums (K,)): the
    efficiencies (K,), NaN where the closed form does not apply."""
    mean_log = log_sums / slots
    lowest = mean_log.min(axis=1)
    inverse_g = np.exp2(lowest[:, None] - mean_log)
    level = (power_budget_w + inverse_sums) / (slots * inverse_g.sum(axis=1))
    applies = (((level[:, None] * inverse_g * least).min(axis=1) >= 1.0)
               & (power_budget_w >= 1e-3 * inverse_sums))
    with np.errstate(invalid='ignore', divide='ignore'):
        return np.where(applies, np.log2(level) + lowest, np.nan)


def resplit(scenario: Scenario, draw: tuple, value_of: Callable[[np.ndarray], float], *,
            power_budget_w: float | None = None) -> np.ndarray | None:
    """The tour of ``draw`` (:func:`~uav_comm_planner.core.tours.tour_draws`) flown with its
    split searched (:func:`searched_split`): q (M, 2) metres, or None when no split gains (or
    the tour visits no node).

    Each split is valued by ``value_of``, the max-min efficiency of one power step (bits per
    use) on the SNR per watt a (N, M) of its tour; the SNR per watt of every point the tour
    can fly to is worked out once, and each split picks its slots' columns. With
    ``power_budget_w`` (the letter's problem, water-filling: no offsets) a split is valued in
    closed form whenever every slot is active (the usual case at high SNR): a split's slots
    are those of no hover plus h_k more at stop k, so the sums the closed form needs are
    those of no hover plus h_k times stop k's, a few operations per node, where ``value_of``
    takes a few per slot; it agrees with the power step to round-off.
    """
    tour, hovers = draw
    if not tour[0]:
        return None
    flier = TourFlier(tour)
    a_rows = snr_per_watt(flier.rows, scenario)

    def value_of_a(split: np.ndarray) -> float:
        return value_of(a_rows[:, flier.slot_rows(split)])

    if power_budget_w is None:
        split, _ = searched_split(hovers, value_of_a)
    else:
        values_of = _closed_form(flier, a_rows, hovers, scenario.num_slots, power_budget_w,
                                 value_of_a)
        split, _ = searched_split(hovers, lambda one: float(values_of(one[None, :])[0]),
                                  values_of=values_of)
    return None if np.array_equal(split, hovers) else flier(split)


def _closed_form(flier: TourFlier, a_rows: np.ndarray, hovers: np.ndarray, num_slots: int,
                 power_budget_w: float, value_of_a: Callable[[np.ndarray], float]
                 ) -> Callable[[np.ndarray], np.ndarray]:
    """The values (K,) of K splits (K, stops), each by water-filling's closed form where
    every slot is active, else by ``value_of_a`` (:func:`resplit`)."""
    a_base = a_rows[:, flier.slot_rows(np.zeros_like(hovers))]
    a_stops = a_rows[:, flier.picked[flier.hover_at[:-1]]]        # (N, stops)
    log_base, log_stops = np.log2(a_base).sum(axis=1), np.log2(a_stops)
    inverse_base, inverse_stops = float((1.0 / a_base).sum()), (1.0 / a_stops).sum(axis=0)
    # No split's least a_n[m] is below this, so the closed form is only taken where it
    # holds (a stop is the last point of the leg to it, to round-off).
    least = np.minimum(a_base.min(axis=1, initial=np.inf), a_stops.min(axis=1))

    def values_of_splits(splits: np.ndarray) -> np.ndarray:
        values = _all_active_rows(log_base + splits @ log_stops.T,
                                  inverse_base + splits @ inverse_stops, least,
                                  num_slots, power_budget_w)
        for k in np.flatnonzero(np.isnan(values)):
            values[k] = value_of_a(splits[k])
        return values

    return values_of_splits


__all__ = ['MIN_GAIN', 'resplit', 'searched_split']
