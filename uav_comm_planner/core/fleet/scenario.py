"""A fleet's planning problem: the letter's scenario flown by K UAVs, each its own ends."""

from __future__ import annotations

from dataclasses import dataclass
import functools
import itertools
import math
from typing import Sequence

import numpy as np

from uav_comm_planner.core.numbers import real_number
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.errors import InvalidScenarioError

#: The most UAVs a fleet plan takes: the trajectory step grows with K^2 separation rows.
MAX_UAVS = 8
#: d_min when none is given, metres: Wu, Zeng and Zhang's (IEEE TWC 2018) separation, at the
#: letter's scale (nodes kilometres apart, H = 100 m) a cost of a fraction of a percent of the
#: min throughput, and far above what a multirotor's GPS and tracking errors take (metres).
#: Without it the joint plan lets two UAVs meet over a node they both serve.
DEFAULT_SEPARATION_M = 100.0


def _points(name: str, value: Sequence) -> tuple[tuple[float, float], ...]:
    """``value`` as a tuple of finite (x, y) pairs (each checked again by :class:`Scenario`)."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
        raise InvalidScenarioError(f'{name} must be a sequence of (x, y) pairs, got {value!r}')
    points = []
    for i, point in enumerate(value):
        if isinstance(point, (str, bytes)) or not isinstance(point, (Sequence, np.ndarray)) \
                or len(point) != 2:
            raise InvalidScenarioError(f'{name} {i + 1} must be a pair (x, y), got {point!r}')
        points.append(tuple(real_number(name, v) for v in point))
    return tuple(points)


@dataclass(frozen=True)
class FleetScenario:
    """K UAVs over the nodes of ``scenario`` (Wu 2018, orthogonal channels).

    scenario: the nodes, altitude, speed limit, horizon, slots, band B, noise, beta0 and the
    budget P_T that every UAV has (each its own band and its own budget), and the speed
    limits, wind, zones and airframe with its energy budget of every UAV (each UAV's horizon
    energy within ``energy_budget_wh``, its own battery's); its start and goal are not used.
    starts_m, goals_m: q0_k and qF_k, K pairs each, metres.
    min_separation_m: d_min, the least horizontal distance between any two UAVs at every slot
    q_j[m], q_k[m] (m = 1..M; the ends, which are given, must keep it too), by default
    :data:`DEFAULT_SEPARATION_M`; 0 lets them meet. All UAVs fly at the same altitude H, so
    d_min is their distance.
    energy_budgets_wh: each UAV's own budget, K numbers (None: ``scenario.energy_budget_wh``
    for every UAV), for UAVs whose batteries differ; needs the scenario's airframe.
    """

    scenario: Scenario
    starts_m: tuple[tuple[float, float], ...]
    goals_m: tuple[tuple[float, float], ...]
    min_separation_m: float = DEFAULT_SEPARATION_M
    energy_budgets_wh: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.scenario, Scenario):
            raise InvalidScenarioError(
                f'a fleet needs a Scenario, got {type(self.scenario).__name__}')
        starts, goals = _points('start', self.starts_m), _points('goal', self.goals_m)
        if not 1 <= len(starts) <= MAX_UAVS:
            raise InvalidScenarioError(
                f'a fleet has 1 to {MAX_UAVS} UAVs, got {len(starts)} starts')
        if len(goals) != len(starts):
            raise InvalidScenarioError(
                f'one goal per UAV: {len(starts)} starts but {len(goals)} goals')
        object.__setattr__(self, 'starts_m', starts)
        object.__setattr__(self, 'goals_m', goals)
        separation = real_number('min_separation_m', self.min_separation_m)
        if not (math.isfinite(separation) and separation >= 0.0):
            raise InvalidScenarioError(
                f'min_separation_m must be >= 0 and finite, got {self.min_separation_m!r}')
        object.__setattr__(self, 'min_separation_m', separation)
        object.__setattr__(self, 'energy_budgets_wh', self._budgets(len(starts)))
        self.vehicles                  # each UAV's ends valid and its goal reachable
        close = ends_too_close(starts, goals, separation)
        if close:
            raise InvalidScenarioError(f'{close}: move them apart or lower min_separation_m')

    def _budgets(self, count: int) -> tuple[float, ...] | None:
        """``energy_budgets_wh`` checked: None, or ``count`` numbers with an airframe (each
        checked again, against the horizon's least energy, by its UAV's :class:`Scenario`)."""
        budgets = self.energy_budgets_wh
        if budgets is None:
            return None
        if isinstance(budgets, (str, bytes)) or not isinstance(budgets, (Sequence, np.ndarray)):
            raise InvalidScenarioError(
                f'energy_budgets_wh must be {count} numbers (one per UAV), got {budgets!r}')
        budgets = tuple(real_number('energy_budgets_wh', value) for value in budgets)
        if len(budgets) != count:
            raise InvalidScenarioError(
                f'energy_budgets_wh: one per UAV, {count} UAVs but {len(budgets)} budgets')
        if self.scenario.airframe is None:
            raise InvalidScenarioError('energy_budgets_wh needs an airframe (its propulsion '
                                       'model): give the scenario one')
        return budgets

    @property
    def num_uavs(self) -> int:
        """K."""
        return len(self.starts_m)

    def vehicle(self, k: int) -> Scenario:
        """UAV k's own scenario (0-based): the shared one with q0_k and qF_k."""
        return self.vehicles[k]

    @functools.cached_property
    def vehicles(self) -> tuple[Scenario, ...]:
        """Every UAV's scenario, in order (each validated: its ends, its goal reachable, its
        energy budget)."""
        budgets = self.energy_budgets_wh or (self.scenario.energy_budget_wh,) * self.num_uavs
        return tuple(self.scenario.replace(start_m=start, goal_m=goal, energy_budget_wh=budget)
                     for start, goal, budget in zip(self.starts_m, self.goals_m, budgets))

    @property
    def pairs(self) -> tuple[tuple[int, int], ...]:
        """The pairs (j, k), j < k, that must keep d_min (none when d_min is 0)."""
        if self.min_separation_m == 0.0:
            return ()
        return tuple(itertools.combinations(range(self.num_uavs), 2))


def ends_too_close(starts: Sequence, goals: Sequence, separation_m: float) -> str:
    """Which two UAVs' starts (or goals) are closer than ``separation_m``, and how far apart,
    said in a few words; empty when every pair keeps it."""
    for name, ends in (('starts', starts), ('goals', goals)):
        for j, k in itertools.combinations(range(len(ends)), 2):
            apart = math.dist(ends[j], ends[k])
            if apart < separation_m:
                return (f'{name} of UAV {j + 1} and UAV {k + 1} are {apart:.1f} m apart, less '
                        f'than the separation {separation_m:g} m')
    return ''


__all__ = ['DEFAULT_SEPARATION_M', 'ends_too_close', 'FleetScenario', 'MAX_UAVS']
