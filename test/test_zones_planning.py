"""Plans inside the zones: the scenario's and the request's zones, the restrictions the
trajectory step adds, the starts around the zones, and every plan checked by the zones' exact
clearance (:meth:`~uav_comm_planner.core.zones.Zones.path_clearance`)."""

from __future__ import annotations

import json

import pytest

from uav_comm_planner.core.scenario import paper_scenario
from uav_comm_planner.core.zones import KeepOutCircle, KeepOutPolygon, OperatingArea, Zones
from uav_comm_planner.errors import InfeasibleHorizonError, InvalidScenarioError
from uav_comm_planner.mission.request import MissionRequest
from uav_comm_planner.tools.serialize import scenario_from_dict, scenario_to_dict

AREA = OperatingArea([(-100, -100), (2100, -100), (2100, 600), (-100, 600)])


def letter_zones(**changes) -> Zones:
    """The letter's area with a disc across case I's straight line and a triangle."""
    fields = dict(area=AREA, keep_out=(KeepOutCircle((1000.0, 0.0), 100.0),
                                       KeepOutPolygon([(500, -60), (620, -60), (560, 40)])))
    fields.update(changes)
    return Zones(**fields)


def test_start_and_goal_must_keep_the_margin_with_the_numbers():
    with pytest.raises(InfeasibleHorizonError, match=r'start_m .* inside .* -10.00 m.* 5 m'):
        paper_scenario('I', zones=Zones(keep_out=(KeepOutCircle((0, 0), 10),)))
    with pytest.raises(InfeasibleHorizonError, match=r'goal_m .* closer .* 2.00 m, .* 5 m'):
        paper_scenario('I', zones=Zones(keep_out=(KeepOutCircle((2000, 12), 10),)))
    with pytest.raises(InfeasibleHorizonError, match='outside the operating area'):
        paper_scenario('II', zones=Zones(area=OperatingArea([(-1, -1), (2001, -1), (2001, 1)])))
    with pytest.raises(InvalidScenarioError, match='zones must be a Zones'):
        paper_scenario('I', zones=[KeepOutCircle((0, 0), 10)])


def test_scenarios_with_equal_zones_compare_and_hash_equal_and_survive_json():
    scenario = paper_scenario('I', zones=letter_zones())
    again = paper_scenario('I', zones=Zones.from_dict(letter_zones().to_dict()))
    assert scenario == again and hash(scenario) == hash(again)
    assert scenario != paper_scenario('I')
    assert scenario_from_dict(json.loads(json.dumps(scenario_to_dict(scenario)))) == scenario
    assert scenario_from_dict(scenario_to_dict(paper_scenario('I'))).zones is None
    with pytest.raises(InvalidScenarioError, match='keep-out zone is'):
        Zones.from_dict({'keep_out': [{'center_m': [0, 0]}]})


def test_a_request_s_zones_replace_the_scenario_s():
    zones = letter_zones()
    request = MissionRequest(paper_scenario('I'), zones=zones)
    assert request.planned_scenario.zones == zones
    assert MissionRequest(paper_scenario('I')).planned_scenario == paper_scenario('I')
    with pytest.raises(InfeasibleHorizonError, match='start_m'):
        _ = MissionRequest(paper_scenario('I'), zones=Zones(
            keep_out=(KeepOutCircle((0, 0), 10),))).planned_scenario
    with pytest.raises(InvalidScenarioError, match='zones must be a Zones'):
        MissionRequest(paper_scenario('I'), zones='fence.plan')
