"""Wu 2018's shared band on a drawn six-node layout: two UAVs with and without power control
against one UAV, and the single UAV's bound; a table and a figure.

Wu, Zeng and Zhang's setting (IEEE TWC 2018, Section VI): 2 km x 2 km, H = 100 m, sigma^2 =
-110 dBm, beta0 = -60 dB, an average power of 0.1 W (P_T = 0.1 M W over the horizon here),
V = 50 m/s, d_min = 100 m, T = 90 s (M = 90 slots of 1 s). The paper gives only two users'
positions; the six here are drawn by hand over the square. Each plan starts from the
orthogonal fleet's plan (:func:`~uav_comm_planner.core.fleet.plan_fleet`) with P_T / M in every
slot; with power control it continues from the plan without. The bound: one UAV gives node n
at most the share tau_n of the time and the energy E_n, so eta_n <= tau_n log2(1 + E_n
gamma_max / (tau_n M)) (Jensen, gamma_max the gain from straight above), and the least node
is at most the value at tau = 1 / N, E = P_T / N (the function is jointly concave).

``python -m devtools.shared_band_study [--figure docs/fleet_shared_band.png]``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Sequence

from uav_comm_planner.core.fleet import FleetScenario, plan_fleet
from uav_comm_planner.core.fleet.shared_band import plan_shared_band, SharedBandPlan
from uav_comm_planner.core.model import flown_path
from uav_comm_planner.core.scenario import paper_scenario, Scenario

NODES_M = ((300.0, 500.0), (700.0, 1600.0), (1000.0, 900.0), (1400.0, 300.0),
           (1700.0, 1500.0), (500.0, 1100.0))
SLOTS = 90
AVERAGE_POWER_W = 0.1


def wu_scenario(slots: int = SLOTS) -> Scenario:
    """The setting of the module docstring (its start and goal those of the single UAV)."""
    return paper_scenario('I', ground_nodes_m=NODES_M, altitude_m=100.0, max_speed_mps=50.0,
                          horizon_s=float(slots), num_slots=slots, start_m=(0.0, 1000.0),
                          goal_m=(2000.0, 1000.0), noise_psd_dbm_per_hz=-110.0,
                          reference_gain=1e-6, power_budget_w=AVERAGE_POWER_W * slots)


def single_uav_bound(scenario: Scenario) -> float:
    """(1/N) log2(1 + N P_T gamma_max / M), bits per second per hertz (module docstring)."""
    n = scenario.num_nodes
    best = scenario.reference_gain / (scenario.bandwidth_hz * scenario.noise_psd_w_per_hz
                                      * scenario.altitude_m ** 2)
    return math.log2(1 + n * scenario.power_budget_w * best / scenario.num_slots) / n


def study(slots: int = SLOTS) -> dict[str, SharedBandPlan | float]:
    """The plans and the bound by name."""
    base = wu_scenario(slots)
    two = FleetScenario(base, ((0.0, 800.0), (0.0, 1200.0)), ((2000.0, 800.0),
                                                              (2000.0, 1200.0)), 100.0)
    one = FleetScenario(base, (base.start_m,), (base.goal_m,), 0.0)
    without = plan_shared_band(two, plan_fleet(two).trajectories, power_control=False)
    with_control = plan_shared_band(two, without.trajectories, power=without.power)
    single = plan_shared_band(one, plan_fleet(one).trajectories)
    return {'two UAVs, power control': with_control, 'two UAVs, no power control': without,
            'one UAV, power control': single, 'one UAV, bound': single_uav_bound(base)}


def draw(results: dict, path: str) -> None:
    """The methods' minimum throughputs, and the two UAVs' paths with power control."""
    from uav_comm_planner.tools.plots import _pyplot, save_figure
    plt = _pyplot()
    figure, (ax_bar, ax_path) = plt.subplots(1, 2, figsize=(12, 5), layout='constrained')
    names = list(results)
    values = [r if isinstance(r, float) else r.min_throughput for r in results.values()]
    ax_bar.barh(names[::-1], values[::-1], color=['grey', 'tab:green', 'tab:orange',
                                                  'tab:blue'])
    for y, value in enumerate(values[::-1]):
        ax_bar.annotate(f'{value:.4f}', (value, y), xytext=(3, 0), textcoords='offset points',
                        va='center', fontsize=9)
    ax_bar.set(xlabel='min average throughput (bit/s/Hz)', title='shared band (Wu 2018)')
    plan = results['two UAVs, power control']
    for k, (q_k, vehicle) in enumerate(zip(plan.trajectories, plan.fleet.vehicles)):
        path_xy = flown_path(q_k, vehicle)
        ax_path.plot(path_xy[:, 0], path_xy[:, 1], '.-', markersize=3, label=f'UAV {k + 1}')
    nodes = plan.fleet.scenario.nodes
    ax_path.plot(nodes[:, 0], nodes[:, 1], '^', color='tab:red', markersize=9, label='nodes')
    ax_path.set(xlabel='x (m)', ylabel='y (m)', title='two UAVs with power control')
    ax_path.set_aspect('equal', adjustable='datalim')
    ax_path.legend(fontsize=8)
    save_figure(figure, path)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='python -m devtools.shared_band_study',
                                     description=__doc__.splitlines()[0])
    parser.add_argument('--figure', metavar='FILE.png', help='draw the table and the paths')
    parser.add_argument('--slots', type=int, default=SLOTS, help='M, slots of 1 s')
    args = parser.parse_args(argv)
    began = time.perf_counter()
    results = study(args.slots)
    for name, result in results.items():
        value = result if isinstance(result, float) else result.min_throughput
        print(f'{name:<30}{value:>10.4f} bit/s/Hz')
    print(f'({time.perf_counter() - began:.0f} s)')
    if args.figure:
        draw(results, args.figure)
        print(f'wrote {args.figure}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
