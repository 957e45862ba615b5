"""What a plan is asked for beyond its scenario and settings, as one typed value.

The optimiser (:func:`~uav_comm_planner.core.optimizer.plan`, or any planner of its signature)
takes these as keywords; :meth:`PlanOptions.keywords` gives the ones that are set, so that a
planner that knows none of them (a test's, a user's) is called as ``planner(scenario,
settings)`` with nothing it does not know.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Callable, Mapping

import numpy as np

from uav_comm_planner.errors import InvalidScenarioError


@dataclass(frozen=True)
class PlanOptions:
    """offsets: o (N,) bits per use credited to each node (a mission in flight: what the nodes
    already hold; None: none); extra_starts: initial trajectories (M, 2) metres by name (the
    plan in force, for a replan); should_stop: asked between the planner's steps, True
    cancels the plan (None: never)."""

    offsets: np.ndarray | None = None
    extra_starts: Mapping[str, np.ndarray] = field(default_factory=dict)
    should_stop: Callable[[], bool] | None = None

    def __post_init__(self) -> None:
        if self.should_stop is not None and not callable(self.should_stop):
            raise InvalidScenarioError(f'should_stop must be callable, got {self.should_stop!r}')
        object.__setattr__(self, 'extra_starts', MappingProxyType(dict(self.extra_starts)))

    def start(self, name: str) -> np.ndarray | None:
        """The extra start ``name`` (None: not given)."""
        return self.extra_starts.get(name)

    def with_starts(self, **starts: np.ndarray) -> 'PlanOptions':
        """These options with exactly ``starts`` as the extra starts (none: none)."""
        return replace(self, extra_starts=starts)

    def keywords(self) -> dict:
        """The planner's keywords for the options that are set."""
        given = {'offsets': self.offsets, 'should_stop': self.should_stop,
                 'extra_starts': dict(self.extra_starts) or None}
        return {name: value for name, value in given.items() if value is not None}


__all__ = ['PlanOptions']
