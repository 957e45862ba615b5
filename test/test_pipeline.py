"""The one planning pipeline: the command line and the node plan the same request through
plan_mission() and get the same mission; the vehicle's limits follow one precedence rule."""

from __future__ import annotations

import pytest

from uav_comm_planner import paper_scenario
from uav_comm_planner.errors import InvalidScenarioError, PlannerError
from uav_comm_planner.mission.pipeline import plan_mission
from uav_comm_planner.mission.request import MissionRequest, vehicle_limits
from uav_comm_planner.ros.params import config_from_parameters
from uav_comm_planner.tools import cli
from uav_comm_planner.vehicle.limits import VehicleLimits
from uav_comm_planner.vehicle.mavlink.items import build_mission_items

#: Case I at a multirotor's 10 m/s, the node's default scenario.
MULTIROTOR = {'max_speed_mps': 10.0, 'horizon_s': 400.0, 'num_slots': 100}
#: A ground station's parameter file: 6 m/s, 2 m/s/s.
SLOW = 'WPNAV_SPEED,600\nWPNAV_ACCEL,200\n'


@pytest.mark.parametrize('suffix', ['.waypoints', '.plan'])
def test_the_command_line_and_the_node_write_the_same_mission(harness, tmp_path, suffix):
    by_cli = tmp_path / f'cli{suffix}'
    assert cli.main(['plan', '--case', 'I', '--speed', '10', '--horizon', '400', '--slots',
                     '100', '--mission', str(by_cli)]) == 0
    by_node = tmp_path / f'node{suffix}'
    h = harness(mission_dir=str(tmp_path), mission_file=by_node.name, vehicle_aware=True,
                **MULTIROTOR)
    h.published(1)
    assert by_node.read_bytes() == by_cli.read_bytes()
    # And the items the node holds are the ones the pipeline builds for the same request.
    planned = plan_mission(MissionRequest(paper_scenario('I', **MULTIROTOR)))
    assert h.node.current_plan.plan.items == planned.items
    assert planned.items == tuple(build_mission_items(planned.vehicle_plan,
                                                      planned.request.home))


def test_the_items_are_built_once_and_written_as_built(tmp_path):
    planned = plan_mission(MissionRequest(paper_scenario('I', **MULTIROTOR)))
    first = planned.write(tmp_path / 'a.waypoints').read_text()
    # Another end rebuilds them; the same settings return the plan itself.
    assert planned.for_output(home=planned.request.home, end='land',
                              firmware='ardupilot') is planned
    rtl = planned.for_output(home=planned.request.home, end='rtl', firmware='ardupilot')
    assert rtl.items != planned.items and rtl.result is planned.result
    assert rtl.write(tmp_path / 'b.waypoints').read_text() != first
    unflown = plan_mission(MissionRequest(paper_scenario('I', **MULTIROTOR), items=False))
    assert unflown.items is None
    with pytest.raises(PlannerError, match='without mission items'):
        unflown.write(tmp_path / 'c.waypoints')


def test_explicit_values_beat_the_parameter_file_which_beats_the_defaults(tmp_path):
    params = tmp_path / 'slow.param'
    params.write_text(SLOW)
    assert vehicle_limits() == VehicleLimits()
    from_file = vehicle_limits(parameter_file=params)
    assert (from_file.max_speed_mps, from_file.max_accel_mpss) == (6.0, 2.0)
    assert from_file.max_jerk_mpsss == VehicleLimits().max_jerk_mpsss
    both = vehicle_limits({'max_speed_mps': 8.0}, params)
    assert (both.max_speed_mps, both.max_accel_mpss) == (8.0, 2.0)
    with pytest.raises(TypeError):
        vehicle_limits({'no_such_limit': 1.0})


def test_the_node_and_the_command_line_apply_the_same_rule(tmp_path):
    params = tmp_path / 'slow.param'
    params.write_text(SLOW)
    # The node: a vehicle_* parameter set explicitly beats the file, one left alone does not.
    values = {'vehicle_params_file': str(params), 'vehicle_max_speed_mps': 8.0,
              'max_speed_mps': 5.0}
    config = config_from_parameters(values)
    assert (config.vehicle.max_speed_mps, config.vehicle.max_accel_mpss) == (8.0, 2.0)
    left = config_from_parameters(values, explicit={'vehicle_params_file', 'max_speed_mps'})
    assert left.vehicle.max_speed_mps == 6.0
    # The command line: --wp-speed beats the file the same way.
    args = cli.build_parser().parse_args(
        ['plan', '--case', 'I', '--vehicle-params', str(params), '--wp-speed', '8'])
    assert cli._vehicle_limits(args) == config.vehicle
    with pytest.raises(InvalidScenarioError, match='parameter file'):
        vehicle_limits(parameter_file=tmp_path / 'missing.param')
