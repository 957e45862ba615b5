"""Start the uav_comm_planner node with a parameters file, in a namespace.

    ros2 launch uav_comm_planner planner.launch.py
    ros2 launch uav_comm_planner planner.launch.py params_file:=my.yaml namespace:=uav1
    ros2 launch uav_comm_planner planner.launch.py mavlink_url:=udpin:0.0.0.0:14550

Arguments:
    params_file: parameters of the node (default: the package's config/planner.yaml, the
        letter's case I). Its section for the node may be keyed ``uav_comm_planner``,
        ``/uav_comm_planner``, ``/**/uav_comm_planner``, ``/<namespace>/uav_comm_planner``
        or ``/**``; the matching sections are applied in file order, so the same file works
        with and without a namespace.
    namespace: ROS namespace of the node and its topics (default: none).
    mavlink_url: the vehicle's MAVLink connection, given to the node's ``mavlink_url``
        parameter only when not empty (default: empty, the file's value or the node's own
        default stands).
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare
import yaml

PACKAGE = 'uav_comm_planner'
EXECUTABLE = 'planner'
NODE_NAME = 'uav_comm_planner'


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


def _planner(context):
    namespace = LaunchConfiguration('namespace').perform(context)
    params_file = LaunchConfiguration('params_file').perform(context)
    mavlink_url = LaunchConfiguration('mavlink_url').perform(context)
    parameters = [node_parameters(params_file, namespace)]
    if mavlink_url:
        parameters.append({'mavlink_url': mavlink_url})
    return [Node(package=PACKAGE, executable=EXECUTABLE, name=NODE_NAME, namespace=namespace,
                 parameters=parameters, output='screen', emulate_tty=True)]


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument(
            'params_file',
            default_value=PathJoinSubstitution(
                [FindPackageShare(PACKAGE), 'config', 'planner.yaml']),
            description='parameters file of the node (default: the letter\'s case I)'),
        DeclareLaunchArgument(
            'namespace', default_value='',
            description='ROS namespace of the node and its topics'),
        DeclareLaunchArgument(
            'mavlink_url', default_value='',
            description='vehicle MAVLink connection for the mavlink_url parameter, e.g. '
                        'udpin:0.0.0.0:14550; empty: not passed'),
        OpaqueFunction(function=_planner),
    ])
