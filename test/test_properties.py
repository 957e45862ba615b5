"""Properties that hold for every input (Hypothesis): the API answers with a valid result or
a typed error, the command line with exit 0 or a one-line refusal and no stray file, and a
mission export with rows inside their formats' ranges."""

from __future__ import annotations

import contextlib
import io
import json
import math
from pathlib import Path
import tempfile

from hypothesis import assume, given, HealthCheck, settings, strategies as st
import numpy as np

from uav_comm_planner import (InvalidScenarioError, MissionExportError, plan, PlannerError,
                              Scenario, SolverSettings)
from uav_comm_planner.core.model import leg_lengths, snr_scale
from uav_comm_planner.files import PARTIAL_MARK
from uav_comm_planner.tools import cli
from uav_comm_planner.tools.serialize import result_to_dict
from uav_comm_planner.vehicle.firmware import FIRMWARES
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.mavlink.files import export_mission
from uav_comm_planner.vehicle.mavlink.items import build_mission_items, NAV_WAYPOINT

FAST = settings(max_examples=40, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
PLANS = settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])

#: Anything a caller might pass for a number or a point.
anything = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-10 ** 30, 10 ** 30),
    st.booleans(), st.none(), st.text(max_size=4),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=3),
    st.tuples(st.floats(-1e4, 1e4), st.floats(-1e4, 1e4)))
point = st.tuples(st.floats(-3000.0, 3000.0), st.floats(-3000.0, 3000.0))
FIELDS = ('altitude_m', 'max_speed_mps', 'horizon_s', 'num_slots', 'start_m', 'goal_m',
          'bandwidth_hz', 'noise_psd_dbm_per_hz', 'reference_gain', 'power_budget_w')


def is_json_finite(text: str) -> bool:
    def refuse(constant: str) -> float:
        raise ValueError(constant)
    try:
        json.loads(text, parse_constant=refuse)
    except ValueError:
        return False
    return True


@FAST
@given(changes=st.dictionaries(st.sampled_from(FIELDS), anything, max_size=3),
       nodes=st.one_of(anything, st.lists(anything, max_size=3)))
def test_a_scenario_is_valid_with_finite_derived_quantities_or_a_typed_error(changes, nodes):
    try:
        scenario = Scenario(ground_nodes_m=nodes, **changes)
    except InvalidScenarioError:
        return
    for value in (snr_scale(scenario), scenario.noise_psd_w_per_hz, scenario.max_step_m,
                  scenario.altitude_m ** 2, scenario.power_budget_w * snr_scale(scenario)):
        assert math.isfinite(value) and value > 0


@FAST
@given(changes=st.dictionaries(st.sampled_from(
    ['tolerance_bps', 'relative_tolerance', 'max_outer_iterations', 'max_inner_iterations',
     'max_nodes', 'max_node_slots', 'compute_baselines', 'starts']), anything, max_size=3))
def test_solver_settings_are_valid_or_a_typed_error(changes):
    try:
        SolverSettings(**changes)
    except InvalidScenarioError:
        pass


scenarios = st.builds(
    lambda nodes, start, goal, slots, altitude, speed, bandwidth, noise, gain, budget: dict(
        ground_nodes_m=nodes, start_m=start, goal_m=goal, num_slots=slots, horizon_s=slots * 4.0,
        altitude_m=altitude, max_speed_mps=speed, bandwidth_hz=bandwidth,
        noise_psd_dbm_per_hz=noise, reference_gain=gain, power_budget_w=budget),
    nodes=st.lists(point, min_size=1, max_size=4), start=point, goal=point,
    slots=st.integers(1, 8), altitude=st.floats(1.0, 1e4), speed=st.floats(1.0, 500.0),
    bandwidth=st.floats(1e-3, 1e9), noise=st.floats(-250.0, 100.0),
    gain=st.floats(1e-15, 1.0), budget=st.floats(1e-9, 1e4))


def plan_or_refusal(fields: dict):
    try:
        return plan(Scenario(**fields), SolverSettings(compute_baselines=True))
    except PlannerError:
        return None


@PLANS
@given(fields=scenarios)
def test_every_plan_is_finite_within_its_limits_and_never_below_the_straight_line(fields):
    result = plan_or_refusal(fields)
    assume(result is not None)
    scenario = result.scenario
    for array in (result.trajectory, result.power, result.rates):
        assert np.all(np.isfinite(array))
    assert np.all(result.power >= 0)
    assert result.power.sum() <= scenario.power_budget_w * (1 + 1e-9)
    assert leg_lengths(result.trajectory, scenario).max() <= scenario.max_step_m * (1 + 1e-12)
    assert result.min_throughput >= result.baselines['straight'] * (1 - 1e-9)
    assert result.min_throughput <= result.upper_bound * (1 + 1e-9)
    assert is_json_finite(cli.json_text(result_to_dict(result)))


@PLANS
@given(fields=scenarios, latitude=st.floats(-90.0, 90.0), longitude=st.floats(-180.0, 180.0),
       altitude=st.floats(-1000.0, 10000.0), firmware=st.sampled_from(['ardupilot', 'px4']),
       suffix=st.sampled_from(['.waypoints', '.plan']))
def test_mission_export_writes_rows_inside_their_ranges_or_refuses(
        fields, latitude, longitude, altitude, firmware, suffix):
    result = plan_or_refusal(fields)
    assume(result is not None)
    home = Home(latitude, longitude, altitude)
    with tempfile.TemporaryDirectory() as folder:
        try:
            items = build_mission_items(result, home, firmware=firmware)
            path = export_mission(result, Path(folder) / f'm{suffix}', home, firmware=firmware)
        except MissionExportError:
            assert list(Path(folder).iterdir()) == []
            return
        assert [p.name for p in Path(folder).iterdir()] == [path.name]
        if suffix == '.plan':
            assert is_json_finite(path.read_text())
    for item in items:
        assert all(math.isfinite(v) for v in (*item.params[:3], item.x, item.y, item.z))
        assert abs(item.x) <= 90.0 and abs(item.y) <= 180.0
        if firmware == 'ardupilot' and item.command == NAV_WAYPOINT:
            hold = item.params[0]
            assert hold <= FIRMWARES['ardupilot'].max_hold_s and hold == int(hold)


number_text = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-10 ** 6, 10 ** 30).map(str),
    st.sampled_from(['', 'x', '1,2', '1e999', '-0', '5e-324', '0x10', '١']))
flags = st.sampled_from(['--altitude', '--speed', '--horizon', '--slots', '--bandwidth',
                         '--noise-dbm', '--beta0', '--budget', '--tolerance', '--max-nodes',
                         '--start', '--goal', '--nodes', '--home', '--case', '--max-node-slots'])
outputs = st.sampled_from(['r.json', 'f.png', 'f.xyz', 'm.waypoints', 'm.plan', 'm.txt',
                           'missing/r.json', '', '.'])


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = cli.main(argv)
    return status, out.getvalue(), err.getvalue()


@FAST
@given(pairs=st.lists(st.tuples(flags, number_text), max_size=3),
       json_name=outputs, mission_name=outputs)
def test_the_command_line_plans_or_refuses_in_one_line_without_stray_files(pairs, json_name,
                                                                           mission_name):
    # Small problems by default, so that successful examples plan quickly.
    argv = ['plan', '--slots', '6', '--horizon', '30']
    for flag, value in pairs:
        argv += [flag, value]
    with tempfile.TemporaryDirectory() as folder:
        if json_name:
            argv += ['--json', str(Path(folder) / json_name)]
        if mission_name:
            argv += ['--mission', str(Path(folder) / mission_name)]
        status, _, err = run_cli(argv)
        written = sorted(p.name for p in Path(folder).iterdir())
        assert not any(PARTIAL_MARK in name for name in written)
        if status == 2:
            assert err.count('\n') == 1 and err.startswith('uav-comm-planner: error: '), err
            assert written == []
            return
        assert status == 0, err
        assert 'Traceback' not in err
        if json_name == 'r.json':
            assert is_json_finite((Path(folder) / 'r.json').read_text())
