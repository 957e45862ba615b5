"""Random drops: ground nodes uniform in a square or a disc, and the scenario flown over them.

The benchmark, the Monte Carlo study and the tests draw their random scenarios here, so that
one seed gives the same nodes whichever of them draws it.
"""

from __future__ import annotations

import numpy as np

from uav_comm_planner.core.scenario import paper_scenario, Scenario
from uav_comm_planner.errors import InvalidScenarioError

AREAS = ('square', 'disc')


def random_nodes(rng: np.random.Generator, num_nodes: int, side_m: float, *,
                 area: str = 'square') -> np.ndarray:
    """w (N, 2) metres, uniform in the side x side square [0, side]^2 or in the disc inscribed
    in it (centre (side/2, side/2), radius r = side/2: radius r sqrt(u), angle 2 pi v)."""
    if area == 'square':
        return rng.uniform(0.0, side_m, size=(num_nodes, 2))
    if area == 'disc':
        # One (u, v) pair per node, so that N nodes are the first N of a larger drop.
        u, v = rng.uniform(size=(num_nodes, 2)).T
        radius, angle = 0.5 * side_m * np.sqrt(u), 2.0 * np.pi * v
        return 0.5 * side_m + np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    raise InvalidScenarioError(f'unknown area {area!r}; choose one of {AREAS}')


def random_scenario(num_nodes: int, num_slots: int, seed: int | np.random.Generator, *,
                    side_m: float, horizon_s: float | None = None, area: str = 'square',
                    **radio: object) -> Scenario:
    """Nodes uniform in a side x side square (or the disc in it), flown from (0, 0) to
    (side, side) at 100 m/s.

    The horizon defaults to M seconds (delta = 1 s, as in the letter), always long enough to
    reach the goal. ``radio`` overrides the letter's other settings (B, beta0, ..., and the
    start and goal). ``seed`` is an integer or a generator to draw from.
    """
    rng = np.random.default_rng(seed)
    settings = dict(ground_nodes_m=random_nodes(rng, num_nodes, side_m, area=area).tolist(),
                    horizon_s=float(num_slots if horizon_s is None else horizon_s),
                    num_slots=num_slots, start_m=(0.0, 0.0), goal_m=(side_m, side_m))
    settings.update(radio)
    return paper_scenario('I', **settings)
