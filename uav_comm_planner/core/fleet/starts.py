"""Where the fleet's alternating loop starts: K trajectories (K, M, 2) metres that keep the
speed limits and the separation.

* :func:`partition`: the nodes split into K groups, each the nodes nearest UAV k's straight
  path q0_k -> qF_k (a UAV left with none takes the node nearest its path from the largest
  group), so that each UAV starts on a tour of its own; the work scales with K groups of about
  N / K nodes.
* :func:`separate`: the push-apart before the SCA, the least change (in the sum of squared
  distances) of the trajectories that keeps the speed limits and the separation, some
  trajectories held fixed; with zones or an energy budget, each moved UAV also keeps its
  zones' restriction and its energy budget's (the single UAV's blocks at the trajectory given,
  :func:`~uav_comm_planner.core.fleet.step.vehicle_blocks`), and an answer is kept only if
  every UAV keeps its zones' margin and its budget exactly (:func:`keeps_blocks`). Its
  separation rows are linearised at the trajectories given, with
  the straight lines' direction where two UAVs coincide; each row implies d_min whatever its
  direction (:mod:`.separation`), so an answer is separated exactly. None when no answer is
  found with those directions.
"""

from __future__ import annotations

from typing import Sequence
import warnings

import cvxpy as cp
import numpy as np

from uav_comm_planner.core.detour import straight_start
from uav_comm_planner.core.feasibility import project_onto_speed_limit, within_speed_limit
from uav_comm_planner.core.fleet.scenario import FleetScenario
from uav_comm_planner.core.fleet.separation import (keeps_separation, SEPARATION_CUSHION_M,
                                                    unit_directions)
from uav_comm_planner.core.fleet.step import fleet_frames, vehicle_blocks, vehicle_paths
from uav_comm_planner.core.optimizer import ZoneKeeper
from uav_comm_planner.core.sca.block import Expansion
from uav_comm_planner.core.sca.program import start_filter
from uav_comm_planner.core.sca.surrogate import KM


def segment_distances(points: np.ndarray, starts: np.ndarray, goals: np.ndarray) -> np.ndarray:
    """The distance of each point (N, 2) from each segment start_k -> goal_k: (N, K) metres."""
    along = goals - starts                                        # (K, 2)
    length2 = (along ** 2).sum(axis=1)
    offset = points[:, None, :] - starts[None, :, :]             # (N, K, 2)
    share = np.where(length2 > 0.0, (offset * along).sum(axis=-1) / np.maximum(length2, 1e-300),
                     0.0)
    nearest = starts + np.clip(share, 0.0, 1.0)[..., None] * along
    return np.linalg.norm(points[:, None, :] - nearest, axis=-1)


def partition(fleet: FleetScenario) -> list[list[int]]:
    """K groups of node indices (module docstring); every group non-empty when N >= K."""
    distance = segment_distances(fleet.scenario.nodes, np.array(fleet.starts_m),
                                 np.array(fleet.goals_m))
    owner = distance.argmin(axis=1)
    for k in range(fleet.num_uavs):
        counts = np.bincount(owner, minlength=fleet.num_uavs)
        if counts[k] or counts.max() < 2:
            continue
        largest = int(counts.argmax())
        members = np.flatnonzero(owner == largest)
        owner[members[int(distance[members, k].argmin())]] = k
    return [np.flatnonzero(owner == k).tolist() for k in range(fleet.num_uavs)]


def straight_lines(fleet: FleetScenario) -> np.ndarray:
    """Every UAV's straight line q0_k -> qF_k at uniform speed, or with zones its shortest
    path around them (:func:`~uav_comm_planner.core.detour.straight_start`): (K, M, 2)
    metres."""
    return np.stack([straight_start(vehicle) for vehicle in fleet.vehicles])


def keeps_blocks(q: np.ndarray, fleet: FleetScenario) -> bool:
    """Whether every UAV's trajectory of q (K, M, 2) metres, projected onto its speed limits,
    keeps its zones' margin (every leg, as the single UAV's starts must) and its energy budget
    (:func:`~uav_comm_planner.core.sca.program.start_filter`)."""
    for q_k, vehicle in zip(q, fleet.vehicles):
        if vehicle.zones is not None and not vehicle.zones.empty \
                and not ZoneKeeper(vehicle).keeps(q_k):
            return False
        if not start_filter(vehicle)(q_k):
            return False
    return True


def sideways_directions(z: np.ndarray, pairs: tuple[tuple[int, int], ...], d_km: float,
                        side: float) -> np.ndarray:
    """Directions that turn one way round each pair's meeting: r[m] + side d_min n, r[m] =
    z_j[m] - z_k[m] and n the unit normal (left of) r's overall change r[M] - r[1]. Where
    two lines cross, r passes near 0 and its own direction flips between two slots, asking a
    UAV to jump across the other; shifted by d_min sideways it turns round 0 on one side
    instead (``side`` +1 or -1)."""
    directions = []
    for j, k in pairs:
        r = z[j] - z[k]
        change = r[-1] - r[0]
        if not np.linalg.norm(change) > 0.0:
            change = r[0] if np.linalg.norm(r[0]) > 0.0 else np.array([1.0, 0.0])
        normal = np.array([-change[1], change[0]]) / np.linalg.norm(change)
        directions.append(r + side * d_km * normal)
    return np.stack(directions)


def _pushed(z0: np.ndarray, directions: np.ndarray, fleet: FleetScenario, frames: list,
            fixed: Sequence[int], solver: str) -> np.ndarray | None:
    """The least change of z0 (K, M, 2) km keeping the speed limits and the separation rows
    along ``directions`` (P, M, 2); None when the solver finds none."""
    length = np.linalg.norm(directions, axis=-1, keepdims=True)
    units = np.where(length > 0.0, directions / np.maximum(length, 1e-300), [1.0, 0.0])
    z = [cp.Constant(z0[k]) if k in fixed else cp.Variable(z0[k].shape)
         for k in range(fleet.num_uavs)]
    constraints = []
    for k, (frame, v) in enumerate(zip(frames, vehicle_paths(frames, z, cp.Variable()))):
        if k in fixed:
            continue
        expansion = Expansion(frame.metres(z0[k]), None)
        for block in vehicle_blocks(frame):
            constraints += block.constraints(v, block.at(expansion))
    for (j, k), direction in zip(fleet.pairs, units):
        constraints.append(cp.sum(cp.multiply(direction, z[j] - z[k]), axis=1)
                           >= (fleet.min_separation_m + 2 * SEPARATION_CUSHION_M) / KM)
    moved = sum(cp.sum_squares(z[k] - z0[k]) for k in range(fleet.num_uavs) if k not in fixed)
    problem = cp.Problem(cp.Minimize(moved), constraints)
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings('ignore', message='Solution may be inaccurate')
            problem.solve(solver=solver)
    except cp.error.SolverError:
        return None
    if problem.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
        return None
    return np.stack([z0[k] if k in fixed else z[k].value for k in range(fleet.num_uavs)])


def separate(q: np.ndarray, fleet: FleetScenario, *, fixed: Sequence[int] = (),
             solver: str = 'CLARABEL') -> np.ndarray | None:
    """The push-apart (module docstring): q (K, M, 2) metres changed least to keep the speed
    limits and d_min, the UAVs in ``fixed`` unchanged; q itself when it keeps both. The rows'
    directions are tried in turn: q's own differences, then turned round each meeting on one
    side, then on the other (:func:`sideways_directions`)."""
    q = np.asarray(q, dtype=float)
    flyable = all(within_speed_limit(q_k, vehicle, slack=0.0)
                  for q_k, vehicle in zip(q, fleet.vehicles))
    if flyable and keeps_separation(q, fleet) and keeps_blocks(q, fleet):
        return q
    frames = fleet_frames(fleet)
    if not fleet.pairs:
        answer = np.stack([project_onto_speed_limit(q_k, frame.scenario)
                           for q_k, frame in zip(q, frames)])
        return answer if keeps_blocks(answer, fleet) else None
    z0 = np.stack([frame.km(q_k) for frame, q_k in zip(frames, q)])
    lines = np.stack([frame.km(line) for frame, line in zip(frames, straight_lines(fleet))])
    pairs = fleet.pairs
    own = unit_directions(z0, pairs, np.stack([lines[j] - lines[k] for j, k in pairs]))
    d_km = fleet.min_separation_m / KM
    for directions in (own, sideways_directions(z0, pairs, d_km, 1.0),
                       sideways_directions(z0, pairs, d_km, -1.0)):
        z = _pushed(z0, directions, fleet, frames, fixed, solver)
        if z is None:
            continue
        answer = np.stack([q[k] if k in fixed else project_onto_speed_limit(
            frame.metres(z[k]), frame.scenario) for k, frame in enumerate(frames)])
        if keeps_separation(answer, fleet) and keeps_blocks(answer, fleet):
            return answer
    return None


__all__ = ['keeps_blocks', 'partition', 'segment_distances', 'separate',
           'sideways_directions', 'straight_lines']
