"""The node with a fence at the vertex bound (four 1000-vertex stars, 4000 vertices): it answers
parameter requests while a plan round the stars runs on its worker, a ``fence_margin_m`` change
is answered there too and stops that plan at its next step (the next plan keeps the new
margin), and a fence past the bound (twenty 1000-vertex polygons) stops the start in one line
naming the bound, before any polygon is built."""

from __future__ import annotations

import json
import threading
import time

from helpers import build_no_polygon, DEADLINE_S, keep_out_plan_file, NODES_B
import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter

from devtools.zone_probes import star, STAR_CENTRES
from uav_comm_planner import plan
from uav_comm_planner.core.zones import MAX_TOTAL_VERTICES, Zones
from uav_comm_planner.errors import InvalidScenarioError
from uav_comm_planner.ros.node import PlannerNode
from uav_comm_planner.vehicle.fence import fence_from_zones
from uav_comm_planner.vehicle.geodesy import DEFAULT_HOME, Home

pytestmark = pytest.mark.filterwarnings('ignore::DeprecationWarning')

HOME = Home(*DEFAULT_HOME)
HOME_PARAMETERS = {'home_latitude_deg': HOME.latitude_deg,
                   'home_longitude_deg': HOME.longitude_deg, 'home_altitude_m': HOME.altitude_m}
#: Round the straight line q0 (0, 0) -> qF (2000, 0), clear of NODES_B.
FOUR_STARS = Zones(keep_out=tuple(star(1000, centre, 150.0, 100.0) for centre in STAR_CENTRES))


def write_fence(folder, zones: Zones):
    path = folder / 'fence.plan'
    path.write_text(json.dumps({'fileType': 'Plan', 'version': 1,
                                'geoFence': fence_from_zones(zones, HOME).plan_section()}))
    return path


class HeldFirstPlan:
    """A planner whose first plan is the real one round the zones, held at its first ask of
    ``should_stop`` until a newer request supersedes it: a plan provably in progress on the
    worker while the executor is asked."""

    def __init__(self) -> None:
        self.running = threading.Event()
        self.finished_first = threading.Event()
        self.margins: list[float] = []

    def __call__(self, scenario, settings, *, should_stop):
        first = not self.running.is_set()
        self.margins.append(scenario.zones.margin_m)
        if not first:
            return plan(scenario, settings, should_stop=should_stop)

        def held() -> bool:
            self.running.set()
            deadline = time.monotonic() + DEADLINE_S
            while not should_stop() and time.monotonic() < deadline:
                time.sleep(0.01)
            return should_stop()
        try:
            return plan(scenario, settings, should_stop=held)
        finally:
            self.finished_first.set()


def set_parameter(h, name: str, value):
    answer = h.call('set_parameters', SetParameters.Request(parameters=[
        Parameter(name, value=value).to_parameter_msg()]))
    return answer.results[0]


def test_a_fence_at_the_vertex_bound_never_holds_the_executor(harness, tmp_path):
    planner = HeldFirstPlan()
    began = time.perf_counter()
    h = harness(planner=planner, fence_file=str(write_fence(tmp_path, FOUR_STARS)),
                ground_nodes=[v for p in NODES_B for v in p], num_slots=60, horizon_s=120.0,
                **HOME_PARAMETERS)
    started = time.perf_counter()
    h.spin_until(planner.running.is_set, 'first plan round the stars running')
    # Requests the executor serves while that plan runs: a parameter that calls for no plan,
    # then the margin, which does.
    asked = time.perf_counter()
    assert set_parameter(h, 'mission_end', 'rtl').successful
    answered = time.perf_counter()
    # Answered while the first plan was still in progress on the worker.
    assert not planner.finished_first.is_set()
    assert h.node.stats.plans_run == 0
    result = set_parameter(h, 'fence_margin_m', 7.0)
    changed = time.perf_counter()
    assert result.successful, result.reason
    print(f'node with {MAX_TOTAL_VERTICES} fence vertices: started in {started - began:.2f} s, '
          f'mission_end set in {answered - asked:.3f} s and a fence_margin_m change in '
          f'{changed - answered:.3f} s while a plan round the stars ran')
    h.spin_until(lambda: h.node.stats.plans_published >= 1, 'plan after the margin change')
    assert h.node.stats.plans_cancelled >= 1
    assert planner.finished_first.is_set()
    assert h.node.current_plan.result.scenario.zones.margin_m == 7.0
    assert planner.margins[0] == 5.0 and planner.margins[-1] == 7.0
    assert len(h.node.current_plan.result.scenario.zones.keep_out) == len(STAR_CENTRES)


def test_a_fence_past_the_vertex_bound_stops_the_start_in_one_line(ros_context, tmp_path,
                                                                   monkeypatch):
    one = fence_from_zones(FOUR_STARS, HOME).plan_section()['polygons'][0]['polygon']
    path = keep_out_plan_file(tmp_path / 'fence.plan', [
        [[lat + 0.004 * i, lon] for lat, lon in one] for i in range(20)])
    build_no_polygon(monkeypatch)
    with pytest.raises(InvalidScenarioError) as refused:
        PlannerNode(context=ros_context, parameter_overrides=[
            Parameter('fence_file', value=str(path))] + [
            Parameter(name, value=value) for name, value in HOME_PARAMETERS.items()])
    message = str(refused.value)
    assert '\n' not in message
    assert f'20000 polygon vertices in all, more than {MAX_TOTAL_VERTICES}' in message
    assert 'fence.plan' in message
