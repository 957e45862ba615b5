"""Several UAVs planned together (Wu, Zeng, Zhang, IEEE TWC 2018), on orthogonal channels.

UAV k = 1..K flies q_k[m] (M, 2) metres from its own q0_k to its own qF_k, with its own band
B and budget P_T, serving every node by OFDMA with B/N per node as the letter's single UAV
does; node n's throughput is the sum over the UAVs,
R_n = (B/N) sum_k mean_m log2(1 + p_{k,n}[m] a_{k,n}[m]). :func:`plan_fleet` maximises
min_n R_n over every trajectory and power schedule, with every pair of UAVs at least d_min
apart in every slot, by alternating the joint power step (:mod:`.power`) and an SCA step over
all K trajectories (:mod:`.step`), whose separation rows are linearised at the current point
(:mod:`.separation`).
"""

from uav_comm_planner.core.fleet.model import fleet_rates, pairwise_distances
from uav_comm_planner.core.fleet.planner import FleetPlan, FleetSettings, plan_fleet
from uav_comm_planner.core.fleet.scenario import FleetScenario

__all__ = ['fleet_rates', 'FleetPlan', 'FleetScenario', 'FleetSettings', 'pairwise_distances',
           'plan_fleet']
