"""Trajectories that start Algorithm 1 or serve as its baselines: (M, 2) metres each."""

from __future__ import annotations

import numpy as np

from uav_comm_planner.scenario import Scenario


def straight_line(scenario: Scenario) -> np.ndarray:
    """q0 -> qF along a straight line at uniform speed: q[m] = q0 + m (qF - q0) / (M + 1)."""
    fraction = np.arange(1, scenario.num_slots + 1) / (scenario.num_slots + 1)
    start = np.asarray(scenario.start_m)
    return start + fraction[:, None] * (np.asarray(scenario.goal_m) - start)


def static_point(scenario: Scenario) -> np.ndarray:
    """A static access point above the nodes' centroid for the whole horizon.

    This baseline ignores the launch and landing points, as in the letter's comparison.
    """
    centroid = scenario.nodes.mean(axis=0)
    return np.repeat(centroid[None, :], scenario.num_slots, axis=0)
