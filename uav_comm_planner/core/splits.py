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

from typing import Any, Callable

import numpy as np

from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.core.tours import fly_draw

#: A split must gain more than this share of the value of the split it replaces.
MIN_GAIN = 1e-9


def searched_split(hovers: np.ndarray,
                   value_of: Callable[[np.ndarray], float]) -> tuple[np.ndarray, float]:
    """The split (integers, one per stop in tour order) reached from ``hovers`` by moves of
    slots to a neighbouring stop that raise ``value_of`` (module docstring), and its value."""
    best = np.asarray(hovers, dtype=int).copy()
    value = value_of(best)
    stops = len(best)
    step = max(1, int(best.sum()) // 8)
    while step >= 1 and stops >= 2:
        while True:
            moves = []
            for giver in np.flatnonzero(best >= step):
                for taker in (giver - 1, giver + 1):
                    if 0 <= taker < stops:
                        moved = best.copy()
                        moved[giver] -= step
                        moved[taker] += step
                        moves.append(moved)
            values = [value_of(moved) for moved in moves]
            if not values or max(values) <= value + MIN_GAIN * abs(value):
                break
            k = int(np.argmax(values))
            best, value = moves[k], values[k]
        step //= 2
    return best, value


def resplit(scenario: Scenario, draw: tuple, screen: Callable[[np.ndarray], Any]
            ) -> np.ndarray | None:
    """The tour of ``draw`` (:func:`~uav_comm_planner.core.tours.tour_draws`) flown with its
    split searched (:func:`searched_split`), each split valued by the min throughput of
    ``screen`` (one power step) on its tour: q (M, 2) metres, or None when no split gains."""
    tour, hovers = draw

    def value_of(split: np.ndarray) -> float:
        return screen(fly_draw(scenario, (tour, split))).min_throughput

    split, _ = searched_split(hovers, value_of)
    return None if np.array_equal(split, hovers) else fly_draw(scenario, (tour, split))


__all__ = ['MIN_GAIN', 'resplit', 'searched_split']
