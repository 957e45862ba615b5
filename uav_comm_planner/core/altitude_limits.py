"""The altitudes a plan may use (:class:`AltitudeLimits`: a range and a climb limit), and how
a :class:`~uav_comm_planner.core.scenario.Scenario` carries them: ``altitude_range_m`` [MIN, MAX]
and ``max_climb_mps``, checked here so that a scenario file, the command line's flags and
:func:`~uav_comm_planner.core.altitude.plan_with_altitude` refuse the same values alike."""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Protocol

import numpy as np

from uav_comm_planner.core.numbers import real_number
from uav_comm_planner.errors import InvalidScenarioError

#: The climb rate when none is given: ArduCopter's WPNAV_SPEED_UP default, 2.5 m/s.
DEFAULT_CLIMB_MPS = 2.5


class Scenario(Protocol):
    """What this module reads of a :class:`~uav_comm_planner.core.scenario.Scenario` (which
    imports it, so it cannot import that)."""

    altitude_range_m: tuple[float, float] | None
    max_climb_mps: float | None


@dataclass(frozen=True)
class AltitudeLimits:
    """The altitudes a plan may use: ``range_m`` (lowest, highest) metres above the nodes,
    and ``max_climb_mps``, the fastest climb or descent."""

    range_m: tuple[float, float]
    max_climb_mps: float = DEFAULT_CLIMB_MPS

    def __post_init__(self) -> None:
        if isinstance(self.range_m, (str, bytes)) or len(self.range_m) != 2:
            raise InvalidScenarioError(
                f'the altitude range must be a pair (lowest, highest) metres, got '
                f'{self.range_m!r}')
        low, high = (real_number('altitude range', v, 'metres') for v in self.range_m)
        if not (math.isfinite(low) and math.isfinite(high) and 0.0 < low <= high):
            raise InvalidScenarioError(
                f'the altitude range must be finite with 0 < lowest <= highest, got '
                f'({low:g}, {high:g}) m')
        climb = real_number('max_climb_mps', self.max_climb_mps, 'm/s')
        if not (math.isfinite(climb) and climb > 0.0):
            raise InvalidScenarioError(f'max_climb_mps must be positive and finite, got '
                                       f'{self.max_climb_mps!r}')
        object.__setattr__(self, 'range_m', (low, high))
        object.__setattr__(self, 'max_climb_mps', climb)

    def holds(self, h: np.ndarray, slot_s: float, slack_m: float = 1e-6) -> bool:
        """Whether altitudes h (M,) metres keep the range and the climb limit (to slack)."""
        low, high = self.range_m
        climbs = np.abs(np.diff(h))
        return bool(h.min() >= low - slack_m and h.max() <= high + slack_m
                    and (climbs.max(initial=0.0) <= self.max_climb_mps * slot_s + slack_m))


def check_scenario_altitudes(scenario: Scenario) -> None:
    """A scenario's ``altitude_range_m`` (None, or [MIN, MAX] metres) and ``max_climb_mps``
    (None: the planner's default, or m/s), checked as :class:`AltitudeLimits` checks them and
    held as a tuple and a float; a climb limit without a range is refused."""
    if scenario.altitude_range_m is None:
        if scenario.max_climb_mps is not None:
            raise InvalidScenarioError('max_climb_mps needs altitude_range_m [MIN, MAX] metres')
        return
    climb = DEFAULT_CLIMB_MPS if scenario.max_climb_mps is None else scenario.max_climb_mps
    limits = AltitudeLimits(scenario.altitude_range_m, climb)
    object.__setattr__(scenario, 'altitude_range_m', limits.range_m)
    if scenario.max_climb_mps is not None:
        object.__setattr__(scenario, 'max_climb_mps', limits.max_climb_mps)


def limits_of(scenario: Scenario,
              default_climb_mps: float = DEFAULT_CLIMB_MPS) -> AltitudeLimits | None:
    """The :class:`AltitudeLimits` ``scenario`` asks for, None when it flies one altitude;
    its climb rate ``default_climb_mps`` unless the scenario gives ``max_climb_mps``."""
    if scenario.altitude_range_m is None:
        return None
    climb = default_climb_mps if scenario.max_climb_mps is None else scenario.max_climb_mps
    return AltitudeLimits(scenario.altitude_range_m, climb)


__all__ = ['AltitudeLimits', 'check_scenario_altitudes', 'DEFAULT_CLIMB_MPS', 'limits_of']
