"""The numeric parameters take the other numeric type a ROS user habitually types: an integer
where a double is declared (``-p power_budget_w:=2``), a whole-number double where an integer
is (``num_slots:=100.0``), on the command line, in a parameters file and when set; on real
rclpy."""

from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

from helpers import node_from_arguments, ros_arguments
import pytest
from rcl_interfaces.msg import ParameterType
from rclpy.exceptions import InvalidParameterTypeException
from rclpy.parameter import Parameter

from uav_comm_planner.ros.params import coerced_value, parameter_specs


def _check_types(node) -> None:
    """Every numeric parameter holds its declared type."""
    declared = {'float': ParameterType.PARAMETER_DOUBLE, 'int': ParameterType.PARAMETER_INTEGER,
                'pair': ParameterType.PARAMETER_DOUBLE_ARRAY,
                'pairs': ParameterType.PARAMETER_DOUBLE_ARRAY}
    for spec in parameter_specs():
        if spec.kind in declared:
            assert node.get_parameter(spec.name).type_.value == declared[spec.kind], spec.name


@pytest.mark.parametrize('source', ['command line', 'parameters file'])
def test_an_integer_for_a_double_and_a_whole_double_for_an_integer_are_taken(tmp_path: Path,
                                                                              source: str):
    given = {'power_budget_w': '2', 'num_slots': '100.0', 'goal_m': '[2000, 0]',
             'horizon_s': '400', 'vehicle_max_accel_mpss': '3', 'replan_interval_s': '15'}
    context, node = node_from_arguments(ros_arguments(given, source, tmp_path))
    try:
        _check_types(node)
        config = node._binding.config
        assert config.scenario.power_budget_w == 2.0
        assert config.scenario.num_slots == 100 and type(config.scenario.num_slots) is int
        assert config.scenario.goal_m == (2000.0, 0.0) and config.scenario.horizon_s == 400.0
        assert config.vehicle.max_accel_mpss == 3.0
        assert config.node.replan_interval_s == 15.0
        # Set at run time (what `ros2 param set` and a parameter service call do).
        results = node.set_parameters([Parameter('power_budget_w', value=3),
                                       Parameter('num_slots', value=120.0),
                                       Parameter('start_m', value=[10, 0])])
        assert all(result.successful for result in results), results
        _check_types(node)
        assert node.get_parameter('power_budget_w').value == 3.0
        assert node.get_parameter('num_slots').value == 120
        assert node._binding.config.scenario.start_m == (10.0, 0.0)
        # Not a number of the other type: still refused, with the reason.
        (fraction,) = node.set_parameters([Parameter('num_slots', value=12.5)])
        (text,) = node.set_parameters([Parameter('power_budget_w', value='two')])
        assert not fraction.successful and not text.successful
        assert node.get_parameter('num_slots').value == 120
    finally:
        node.destroy_node()
        context.try_shutdown()


def test_a_number_of_the_wrong_kind_at_start_up_is_refused_by_name():
    with pytest.raises(InvalidParameterTypeException, match='num_slots'):
        node_from_arguments(['-p', 'num_slots:=12.5'])


def test_coerced_value_converts_only_the_habitual_slips():
    assert coerced_value(2, 'float') == 2.0 and type(coerced_value(2, 'float')) is float
    assert coerced_value(100.0, 'int') == 100 and type(coerced_value(100.0, 'int')) is int
    assert coerced_value([2000, 0], 'pair') == [2000.0, 0.0]
    assert coerced_value([1, 2.5, 3, 4], 'pairs') == [1.0, 2.5, 3.0, 4.0]
    for value, kind in ((12.5, 'int'), (True, 'float'), ('2', 'float'), (1, 'bool'),
                        (['a', 'b'], 'pair'), (2.0, 'float'), (3, 'int')):
        assert coerced_value(value, kind) is value, (value, kind)


@pytest.mark.parametrize('arguments, said', [
    (['-p', 'num_slots:=12.5'], 'num_slots'),
    (['--params-file', 'missing.yaml'], "Couldn't parse params file"),
])
def test_the_node_binary_says_what_is_wrong_with_its_arguments(tmp_path, arguments, said):
    """`planner --ros-args -p num_slots:=12.5`, or a params file that is not there: one line
    and exit status 2, no traceback."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    done = subprocess.run([str(Path(sys.executable).with_name('planner')), '--ros-args',
                           *arguments], capture_output=True, text=True, timeout=60,
                          cwd=tmp_path, env=env)
    assert done.returncode == 2, done.stderr
    (line,) = [line for line in done.stderr.splitlines() if 'uav_comm_planner:' in line]
    assert line.startswith('uav_comm_planner: invalid ') and said in line
    assert 'Traceback' not in done.stderr
