"""Whether a plan's slots are fine enough for its channel to be stated at the waypoints.

The planner evaluates the rate at the waypoints q[1..M] only, one per slot. The channel
beta0 / (||q - w_n||^2 + H^2) changes over distances of the order of the altitude H, so when
consecutive positions (q0, q[1..M], qF) lie farther apart than about H the waypoints no longer
stand for the flight between them, and the stated throughput misstates what the nodes receive
while the UAV flies its legs. The letter's case I at 10 m/s in 3 slots of 133 s puts its
waypoints up to 809 m apart (8.1 H) and states 13.02 bit/s; flown leg by leg with the same power
the nodes receive 4.3 % less, and 100 slots (legs of 0.4 H) state 11.19 bit/s.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from uav_comm_planner.core.model import average_rates, flown_path, leg_lengths
from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.core.scenario import Scenario

#: Longest leg between consecutive positions that the waypoints stand for, as a share of H.
MAX_LEG_ALTITUDE_SHARE = 1.0
#: Points per leg at which :func:`along_legs_min_throughput` evaluates the rate.
SAMPLES_PER_LEG = 32


@dataclass(frozen=True)
class CoarseSlots:
    """A plan whose longest leg exceeds :data:`MAX_LEG_ALTITUDE_SHARE` H, with the numbers.

    stated_bps: the plan's min throughput (at the waypoints); along_legs_bps: the same power
    schedule's min throughput along the legs flown (:func:`along_legs_min_throughput`);
    suggested_slots: the fewest slots of the whole mission whose legs, at the speed limit,
    stay within the share of H.
    """

    num_slots: int
    longest_leg_m: float
    altitude_m: float
    stated_bps: float
    along_legs_bps: float
    suggested_slots: int

    @property
    def leg_share(self) -> float:
        """The longest leg as a share of the altitude H."""
        return self.longest_leg_m / self.altitude_m

    def message(self) -> str:
        """One line with the numbers and the fix."""
        change = 100.0 * (self.along_legs_bps / self.stated_bps - 1.0)
        return (f'slots too coarse for the channel: the {self.num_slots} waypoints are up to '
                f'{self.longest_leg_m:.0f} m apart, {self.leg_share:.2g} times the altitude '
                f'H = {self.altitude_m:g} m (at most {MAX_LEG_ALTITUDE_SHARE:g} H for the rate at '
                f'a waypoint to stand for its leg), so the stated min throughput '
                f'{self.stated_bps:.4g} bit/s misstates what the nodes receive (flown leg by leg '
                f'with the same power: {self.along_legs_bps:.4g} bit/s, {change:+.1f} %); set '
                f'num_slots to at least {self.suggested_slots}')


def along_legs_min_throughput(result: PlanResult,
                              samples_per_leg: int = SAMPLES_PER_LEG) -> float:
    """min_n R_n, bit/s, of the plan's power schedule along the legs it flies.

    Slot m's power p_n[m] is sent while the UAV flies from q[m-1] to q[m] (q[0] = q0) at
    uniform speed; each leg is sampled at ``samples_per_leg`` evenly spaced midpoints, so the
    value tends to the continuous-time average as the samples grow. Offsets of a plan made in
    flight count as in the plan.
    """
    scenario = result.scenario
    path = flown_path(result.trajectory, scenario)[:scenario.num_slots + 1]
    fractions = (np.arange(samples_per_leg) + 0.5) / samples_per_leg
    legs = np.diff(path, axis=0)
    points = (path[:-1, None, :] + fractions[None, :, None] * legs[:, None, :]).reshape(-1, 2)
    power = np.repeat(result.power, samples_per_leg, axis=1)
    return float(average_rates(points, power, scenario, offsets=result.offsets).min())


def coarse_slots(result: PlanResult, mission: Scenario | None = None) -> CoarseSlots | None:
    """The numbers of a plan whose slots are too coarse for its channel, else None.

    ``mission`` is the whole mission's scenario when ``result`` plans only its rest (its
    horizon and speed give the suggested number of slots); by default the plan's own.
    """
    scenario = result.scenario
    mission = mission or scenario
    longest = float(leg_lengths(result.trajectory, scenario).max())
    allowed = MAX_LEG_ALTITUDE_SHARE * scenario.altitude_m
    # A relative margin: the letter's legs of exactly V delta = H are within the share.
    if longest <= allowed * (1.0 + 1e-6):
        return None
    suggested = math.ceil(mission.max_speed_mps * mission.horizon_s / allowed - 1e-9)
    return CoarseSlots(num_slots=scenario.num_slots, longest_leg_m=longest,
                       altitude_m=scenario.altitude_m, stated_bps=result.min_throughput,
                       along_legs_bps=along_legs_min_throughput(result),
                       suggested_slots=max(suggested, mission.num_slots + 1))


__all__ = ['CoarseSlots', 'MAX_LEG_ALTITUDE_SHARE', 'SAMPLES_PER_LEG',
           'along_legs_min_throughput', 'coarse_slots']
