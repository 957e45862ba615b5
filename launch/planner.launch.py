"""Start the uav_comm_planner node with a parameters file, in a namespace, and RViz if asked.

    ros2 launch uav_comm_planner planner.launch.py
    ros2 launch uav_comm_planner planner.launch.py params_file:=my.yaml namespace:=uav1
    ros2 launch uav_comm_planner planner.launch.py namespace:=uav1 use_rviz:=true
    ros2 launch uav_comm_planner planner.launch.py mavlink_url:=udpin:0.0.0.0:14550

Arguments:
    params_file: parameters of the node (default: the package's config/planner.yaml, the
        letter's case I). Its section for the node may be keyed ``uav_comm_planner``,
        ``/uav_comm_planner``, ``/**/uav_comm_planner``, ``/<namespace>/uav_comm_planner``
        or ``/**``; the matching sections are applied in file order, so the same file works
        with and without a namespace.
    namespace: ROS namespace of the node, its topics and RViz (default: none).
    mavlink_url: the vehicle's MAVLink connection, given to the node's ``mavlink_url``
        parameter only when not empty (default: empty, the file's value or the node's own
        default stands).
    use_sim_time: true to follow /clock (a simulator or a bag) instead of the wall clock, for
        the node and RViz (default: false). Booleans are read as launch's conditions read
        them: true, True, TRUE or 1; false, False or 0.
    log_level: the node's log level: debug, info, warn, error or fatal (default: info).
    use_rviz: true to start RViz with the package's view (rviz/planner.rviz) in the same
        namespace, so that it shows this planner's plan (default: false). When rviz2 is not
        installed, the launch stops before it starts anything (no planner left running).
    color: colour codes in the node's log lines: auto (only when this launch writes to a
        terminal, so a redirected log stays plain text), true or false (default: auto).
"""

import os
import sys

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare
from ament_index_python.packages import get_package_share_directory, PackageNotFoundError
import yaml

PACKAGE = 'uav_comm_planner'
EXECUTABLE = 'planner'
NODE_NAME = 'uav_comm_planner'
RVIZ_CONFIG = ('rviz', 'planner.rviz')
#: The spellings launch's conditions (IfCondition) take, after strip() and lower().
TRUE_WORDS = ('true', '1')
FALSE_WORDS = ('false', '0')
LOG_LEVELS = ('debug', 'info', 'warn', 'error', 'fatal')


def node_parameters(path, namespace, node_name=NODE_NAME):
    """The ``ros__parameters`` of every section of the file at ``path`` that names the node.

    A parameters file is keyed by node name, and ROS matches the key against the node's full
    name: a file keyed ``uav_comm_planner`` would not reach ``/uav1/uav_comm_planner``. Read
    here and passed as values, the file applies under any namespace.
    """
    with open(path, encoding='utf-8') as stream:
        document = yaml.safe_load(stream) or {}
    if not isinstance(document, dict):
        raise RuntimeError(f'{path}: expected a mapping of node names to ros__parameters')
    full_name = '/' + '/'.join(part for part in (namespace.strip('/'), node_name) if part)
    keys = {node_name, '/' + node_name, '/**/' + node_name, full_name, '/**'}
    values = {}
    for key, section in document.items():
        if key in keys and isinstance(section, dict):
            values.update(section.get('ros__parameters') or {})
    if not values:
        raise RuntimeError(f'{path}: no ros__parameters for {full_name}; key the section '
                           f'{node_name!r} or "/**"')
    return values


def launch_boolean(name, text):
    """The boolean argument ``name`` given as ``text``, read as launch reads a condition:
    true, True, TRUE or 1; false, False or 0 (spaces around ignored). RuntimeError otherwise."""
    word = text.strip().lower()
    if word in TRUE_WORDS:
        return True
    if word in FALSE_WORDS:
        return False
    raise RuntimeError(f'{name}:={text!r}: expected true or false (or True, False, 1, 0)')


def required_package(package, argument, find_share=None):
    """The share folder of ``package``, which ``argument`` asks for; RuntimeError naming both
    when it is not installed. Called before any action is returned, so that a launch that
    cannot start a part it asks for starts nothing (no planner left running without it)."""
    try:
        return (find_share or get_package_share_directory)(package)
    except PackageNotFoundError:
        raise RuntimeError(f"{argument}: package '{package}' is not installed, so nothing was "
                           f'started; install it (ros-jazzy-{package}) or launch without '
                           f'{argument.split(":=")[0]}') from None


def colorized_output(color, stdout_is_terminal):
    """RCUTILS_COLORIZED_OUTPUT for the node: '1' or '0'.

    The node's output goes through a pseudo-terminal (emulate_tty), where rcutils would always
    colour it; 'auto' colours only when the launch itself writes to a terminal, so that
    ``ros2 launch ... > planner.log`` holds no escape codes.
    """
    if color == 'auto':
        return '1' if stdout_is_terminal else '0'
    return '1' if launch_boolean('color', color) else '0'


def _actions(context):
    def argument(name):
        return LaunchConfiguration(name).perform(context)

    namespace = argument('namespace')
    mavlink_url = argument('mavlink_url')
    use_sim_time = launch_boolean('use_sim_time', argument('use_sim_time'))
    use_rviz = launch_boolean('use_rviz', argument('use_rviz'))
    if use_rviz:
        required_package('rviz2', 'use_rviz:=true')
    parameters = [node_parameters(argument('params_file'), namespace),
                  {'use_sim_time': use_sim_time}]
    if mavlink_url:
        parameters.append({'mavlink_url': mavlink_url})
    color = colorized_output(argument('color'), sys.stdout.isatty())
    actions = [Node(package=PACKAGE, executable=EXECUTABLE, name=NODE_NAME, namespace=namespace,
                    parameters=parameters, ros_arguments=['--log-level', argument('log_level')],
                    additional_env={'RCUTILS_COLORIZED_OUTPUT': color},
                    output='screen', emulate_tty=True)]
    if use_rviz:
        # In the node's namespace, RViz resolves the view's relative topics to this planner's.
        view = os.path.join(FindPackageShare(PACKAGE).perform(context), *RVIZ_CONFIG)
        actions.append(Node(package='rviz2', executable='rviz2', name='rviz2',
                            namespace=namespace, arguments=['-d', view],
                            parameters=[{'use_sim_time': use_sim_time}], output='log'))
    return actions


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument(
            'params_file',
            default_value=PathJoinSubstitution(
                [FindPackageShare(PACKAGE), 'config', 'planner.yaml']),
            description='parameters file of the node (default: the letter\'s case I)'),
        DeclareLaunchArgument(
            'namespace', default_value='',
            description='ROS namespace of the node, its topics and RViz'),
        DeclareLaunchArgument(
            'mavlink_url', default_value='',
            description='vehicle MAVLink connection for the mavlink_url parameter, e.g. '
                        'udpin:0.0.0.0:14550; empty: not passed'),
        DeclareLaunchArgument(
            'use_sim_time', default_value='false',
            description='follow /clock (simulator or bag) instead of the wall clock: true or '
                        'false (also True, False, 1, 0)'),
        DeclareLaunchArgument(
            'log_level', default_value='info', choices=LOG_LEVELS,
            description='log level of the node'),
        DeclareLaunchArgument(
            'use_rviz', default_value='false',
            description='start RViz with the package\'s view of the plan, in the namespace: '
                        'true or false (also True, False, 1, 0); nothing starts without rviz2'),
        DeclareLaunchArgument(
            'color', default_value='auto',
            description='colour codes in the node\'s log: auto (only on a terminal), true, '
                        'false (also True, False, 1, 0)'),
        OpaqueFunction(function=_actions),
    ])
