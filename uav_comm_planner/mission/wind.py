"""The wind measured in flight: the autopilot's estimates, smoothed, as the planner takes them.

Autopilots estimate the wind from their own motion (ArduPilot's WIND message, PX4's WIND_COV)
several times a second, noisy and gusty. :class:`WindEstimate` smooths the air's velocity w
(east, north, m/s: where the air moves to) exponentially in the autopilot's time,
w <- w + (1 - exp(-dt / tau)) (sample - w), dt at most a telemetry gap (``TRACK_GAP_S``:
a link down for 24 s is no evidence of the wind, and its first sample after, one gust of a
turbulent wind, would take 0.91 of the weight at tau 10 s), and gives it in the scenario's terms
(``wind_speed_mps``, ``wind_from_deg``: the direction it blows from, clockwise from north).
A plan made for a wind w_p is out of date when the estimate is farther than a threshold from
w_p (:meth:`WindEstimate.differs_from`).
"""

from __future__ import annotations

import math

import numpy as np

from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.mission.progress import TRACK_GAP_S


class WindEstimate:
    """The smoothed wind, from samples at autopilot times (``time_constant_s``: tau)."""

    def __init__(self, time_constant_s: float = 10.0) -> None:
        if not (math.isfinite(time_constant_s) and time_constant_s > 0):
            raise InvalidScenarioError(f'the wind time constant must be a positive number of '
                                       f'seconds, got {time_constant_s!r}')
        self.time_constant_s = float(time_constant_s)
        self._velocity: np.ndarray | None = None
        self._time_s: float | None = None
        #: Samples taken so far.
        self.samples = 0

    @property
    def known(self) -> bool:
        return self._velocity is not None

    @property
    def velocity_mps(self) -> np.ndarray | None:
        """The air's velocity (2,) east, north m/s; None before any sample."""
        return None if self._velocity is None else self._velocity.copy()

    def add(self, time_s: float, east_mps: float, north_mps: float) -> None:
        """One estimate of the autopilot at ``time_s``; a sample not later than the previous
        one (a restarted autopilot's clock) restarts the smoothing from it."""
        sample = np.array([east_mps, north_mps], dtype=float)
        if not np.all(np.isfinite(sample)):
            return
        self.samples += 1
        if self._velocity is None or self._time_s is None or time_s <= self._time_s:
            if self._velocity is None or self._time_s is None or time_s < self._time_s:
                self._velocity = sample
            self._time_s = time_s
            return
        step_s = min(time_s - self._time_s, TRACK_GAP_S)     # a silence is no evidence
        weight = 1.0 - math.exp(-step_s / self.time_constant_s)
        self._velocity = self._velocity + weight * (sample - self._velocity)
        self._time_s = time_s

    @property
    def speed_mps(self) -> float:
        return 0.0 if self._velocity is None else float(np.hypot(*self._velocity))

    @property
    def from_deg(self) -> float:
        """Where the wind blows from, degrees clockwise from north, in [0, 360)."""
        if self._velocity is None:
            return 0.0
        east, north = self._velocity
        return math.degrees(math.atan2(-east, -north)) % 360.0

    def for_scenario(self, scenario: Scenario) -> Scenario:
        """``scenario`` planned for this wind (unchanged before any sample)."""
        if self._velocity is None:
            return scenario
        return scenario.replace(wind_speed_mps=round(self.speed_mps, 3),
                                wind_from_deg=round(self.from_deg, 2))

    def differs_from(self, scenario: Scenario, threshold_mps: float) -> bool:
        """Whether the estimate is farther than ``threshold_mps`` from the wind ``scenario``
        was planned for."""
        if self._velocity is None:
            return False
        return float(np.hypot(*(self._velocity - scenario.wind_mps))) > threshold_mps


__all__ = ['WindEstimate']
