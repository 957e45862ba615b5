"""The package as ROS users install it, with ROS's own tools: rosdep, colcon, launch, RViz.

- rosdep itself resolves every ``*_depend`` key of package.xml for ROS 2 Jazzy on Ubuntu noble,
  against a snapshot of rosdistro (``shared/rosdistro`` beside the checkout or above it, or the
  folder in ``UAV_COMM_PLANNER_ROSDISTRO``) through a local sources list and index, never the
  network; without the snapshot those tests skip and say so.
- ``colcon build`` (and ``--symlink-install``) of a copy of the package in a temporary
  workspace installs what ``ros2 run`` and ``ros2 launch`` find through the ament index, once
  the workspace's ``setup.sh`` is sourced.
- The launch file runs against stand-ins of launch's classes that take only the keywords of
  Jazzy's (launch itself is not on PyPI), and builds for real where launch is installed; the
  RViz file is YAML that names the node's own topics, relative, so a namespace works.
- What is installed (pip's wheel, colcon's install tree) holds the package only: none of the
  development tools of ``devtools/`` (SITL launchers, benchmark harnesses, docgen).
"""

from __future__ import annotations

import ast
import importlib.util
import json
import os
from pathlib import Path
import re
import shutil
import subprocess
import sys
import types
import xml.etree.ElementTree as ElementTree

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = 'uav_comm_planner'
PACKAGE_XML = ROOT / 'package.xml'
LAUNCH_FILE = ROOT / 'launch' / 'planner.launch.py'
RVIZ_FILE = ROOT / 'rviz' / 'planner.rviz'
EXECUTABLES = ('planner', 'send_ground_nodes', 'uav-comm-planner')
#: What a workspace needs of the checkout to build the package (no VCS data, caches, venvs).
NOT_SOURCES = shutil.ignore_patterns('.*', '__pycache__', '*.egg-info', 'build', 'install',
                                     'log', 'docs')
#: Any request to the network fails at once: rosdep must read the local snapshot only.
OFFLINE = {'http_proxy': 'http://127.0.0.1:9', 'https_proxy': 'http://127.0.0.1:9',
           'HTTP_PROXY': 'http://127.0.0.1:9', 'HTTPS_PROXY': 'http://127.0.0.1:9'}


def dependency_keys() -> list[tuple[str, str]]:
    """Every (tag, key) of package.xml's ``*depend`` elements."""
    root = ElementTree.parse(PACKAGE_XML).getroot()
    return [(element.tag, element.text.strip()) for element in root
            if element.tag.endswith('depend')]


def test_package_xml_has_dependencies_to_check():
    keys = [key for _, key in dependency_keys()]
    assert len(keys) >= 10 and 'rclpy' in keys and len(set(keys)) == len(keys)


def test_versions_of_package_xml_and_setup_py_agree():
    xml_version = ElementTree.parse(PACKAGE_XML).getroot().findtext('version')
    tree = ast.parse((ROOT / 'setup.py').read_text(encoding='utf-8'))
    versions = [ast.literal_eval(node.value) for node in ast.walk(tree)
                if isinstance(node, ast.keyword) and node.arg == 'version']
    assert versions == [xml_version]


# --- rosdep, against the rosdistro snapshot --------------------------------------------------

def rosdistro_folder() -> Path | None:
    """The snapshot: the environment variable's folder, else shared/rosdistro in an ancestor."""
    given = os.environ.get('UAV_COMM_PLANNER_ROSDISTRO')
    if given:
        return Path(given)
    for folder in (ROOT, *ROOT.parents):
        candidate = folder / 'shared' / 'rosdistro'
        if (candidate / 'rosdep' / 'base.yaml').is_file():
            return candidate
    return None


def local_rosdep(folder: Path, snapshot: Path) -> dict[str, str]:
    """The environment in which rosdep reads ``snapshot`` only: a sources list of its rosdep
    files and a rosdistro index of its Jazzy distribution (file:// URLs), caches in
    ``folder``."""
    sources = folder / 'sources.list.d'
    sources.mkdir(parents=True)
    (sources / '20-default.list').write_text(''.join(
        f'yaml {(snapshot / "rosdep" / name).resolve().as_uri()}\n'
        for name in ('base.yaml', 'python.yaml')), encoding='utf-8')
    index = {'type': 'index', 'version': 4, 'distributions': {'jazzy': {
        'distribution': [(snapshot / 'jazzy' / 'distribution.yaml').resolve().as_uri()],
        'distribution_status': 'active', 'distribution_type': 'ros2', 'python_version': 3}}}
    (folder / 'index.yaml').write_text(yaml.safe_dump(index), encoding='utf-8')
    # Without the ament index of the test's own ROS packages: --ignore-src would count them
    # as sources in the workspace and skip their keys.
    environment = {name: value for name, value in os.environ.items()
                   if name not in ('AMENT_PREFIX_PATH', 'ROS_PACKAGE_PATH')}
    return dict(environment, **OFFLINE, ROSDEP_SOURCE_PATH=str(sources),
                ROSDISTRO_INDEX_URL=(folder / 'index.yaml').as_uri(),
                ROS_HOME=str(folder / 'ros_home'), ROS_DISTRO='jazzy', ROS_PYTHON_VERSION='3')


@pytest.fixture(scope='module')
def rosdep(tmp_path_factory):
    """Runs ``rosdep ARGS... --os ubuntu:noble --rosdistro jazzy`` on the snapshot, after a
    ``rosdep update`` from it."""
    snapshot = rosdistro_folder()
    if snapshot is None:
        pytest.skip('no rosdistro snapshot (shared/rosdistro with rosdep/*.yaml and '
                    'jazzy/distribution.yaml) beside or above the checkout, and '
                    'UAV_COMM_PLANNER_ROSDISTRO is not set: cannot check the rosdep keys')
    environment = local_rosdep(tmp_path_factory.mktemp('rosdep'), snapshot)

    def run(*arguments: str, platform: str = 'ubuntu:noble') -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, '-m', 'rosdep2', *arguments, '--os', platform,
                               '--rosdistro', 'jazzy'], capture_output=True, text=True,
                              env=environment, timeout=120)

    updated = subprocess.run([sys.executable, '-m', 'rosdep2', 'update', '--rosdistro', 'jazzy'],
                             capture_output=True, text=True, env=environment, timeout=120)
    assert updated.returncode == 0, updated.stdout + updated.stderr
    assert 'Add distro "jazzy"' in updated.stdout
    return run


def simulated_install(rosdep) -> dict[str, list[str]]:
    """What ``rosdep install --simulate`` would install for the checkout, by installer."""
    done = rosdep('install', '--from-paths', str(ROOT), '--ignore-src', '--simulate',
                  '--reinstall', '-y')
    assert done.returncode == 0, done.stdout + done.stderr
    installs: dict[str, list[str]] = {}
    for line in done.stdout.splitlines():
        command = line.split()
        if command[:3] == ['apt-get', 'install', '-y']:
            installs.setdefault('apt', []).extend(command[3:])
        elif command[:2] == ['pip3', 'install']:
            installs.setdefault('pip', []).extend(w for w in command[2:] if not w.startswith('-'))
    return installs


def test_rosdep_reads_every_key_of_package_xml(rosdep):
    done = rosdep('keys', '--from-paths', str(ROOT))
    assert done.returncode == 0, done.stderr
    assert sorted(done.stdout.split()) == sorted(key for _, key in dependency_keys())


def test_rosdep_install_resolves_every_key_on_ubuntu_noble(rosdep):
    """rosdep install, as docs/node.md runs it, finds one package for every key."""
    installs = simulated_install(rosdep)
    assert sum(len(packages) for packages in installs.values()) == len(dependency_keys())
    assert {'ros-jazzy-rclpy', 'ros-jazzy-diagnostic-msgs', 'python3-numpy',
            'python3-pymap3d'} <= set(installs['apt'])
    assert sorted(installs['pip']) == ['cvxpy', 'pymavlink']


def test_the_keys_that_broke_rosdep_install_are_refused_by_rosdep(rosdep):
    """The check itself: the earlier package.xml's keys fail, their replacements resolve."""
    for wrong in ('python3-clarabel-pip', 'python3-pymavlink', 'python3-pymap3d-pip'):
        done = rosdep('resolve', wrong)
        assert done.returncode != 0 and f"no rosdep rule for '{wrong}'" in done.stderr, wrong
    right = rosdep('resolve', 'python3-pymavlink-pip', 'python3-pymap3d', 'python3-cvxpy-pip')
    assert right.returncode == 0, right.stderr
    assert right.stdout.split('\n#ROSDEP')[0].splitlines()[1:] == ['#pip', 'pymavlink']
    # A release mapped to null has no package: python3-pymap3d is absent on focal.
    focal = rosdep('resolve', 'python3-pymap3d', platform='ubuntu:focal')
    assert focal.returncode != 0 and 'not available' in focal.stderr


def _requirement_names() -> list[str]:
    """The distribution names of setup.py's install_requires, read with ast."""
    tree = ast.parse((ROOT / 'setup.py').read_text(encoding='utf-8'))
    for node in ast.walk(tree):
        if isinstance(node, ast.keyword) and node.arg == 'install_requires':
            return [re.split(r'[<>=!~ ;\[]', item, maxsplit=1)[0].lower()
                    for item in ast.literal_eval(node.value)]
    raise AssertionError('setup.py has no install_requires')


def test_every_runtime_requirement_is_installed_by_rosdep(rosdep):
    """Each of setup.py's install_requires is installed on the colcon route: by pip under its
    own name or by apt as ``python3-<name>`` (PyYAML as python3-yaml, the name of its import);
    Clarabel is a dependency of cvxpy and comes with it."""
    installs = simulated_install(rosdep)
    provided = {name.lower() for name in installs['pip']}
    provided.update(name.removeprefix('python3-') for name in installs['apt'])
    if 'cvxpy' in provided:
        provided.add('clarabel')
    if 'yaml' in provided:
        provided.add('pyyaml')
    assert [name for name in _requirement_names() if name not in provided] == []


# --- colcon build ----------------------------------------------------------------------------

#: Run in the workspace's sourced environment: what ros2 run and ros2 launch would find.
LOOKUPS = '''
import json, os, sys
from ament_index_python.packages import get_package_prefix, get_package_share_directory
from ament_index_python.resources import get_resource
import uav_comm_planner

package = sys.argv[1]
prefix = get_package_prefix(package)
# ros2 run: the executable files under <prefix>/lib/<package>.
folder = os.path.join(prefix, 'lib', package)
executables = sorted(name for name in os.listdir(folder)
                     if os.access(os.path.join(folder, name), os.X_OK))
# ros2 launch: a file name searched under the package's share folder.
share = get_package_share_directory(package)
found = {name: os.path.join(root, name) for root, _, names in os.walk(share, followlinks=True)
         for name in names}
print(json.dumps({'prefix': prefix, 'share': share, 'executables': executables,
                  'marker': get_resource('packages', package)[1],
                  'files': found, 'module': uav_comm_planner.__file__}))
'''


@pytest.fixture(scope='module', params=[False, True], ids=['copies', 'symlink-install'])
def workspace(request, tmp_path_factory) -> Path:
    """A workspace with a copy of the package in src/, built by colcon (with
    ``--symlink-install`` for the second parameter); colcon runs with this Python, as
    ``python -m colcon build`` in docs/node.md."""
    base = tmp_path_factory.mktemp('workspace')
    shutil.copytree(ROOT, base / 'src' / PACKAGE, ignore=NOT_SOURCES)
    command = [sys.executable, '-m', 'colcon', '--log-base', 'log', 'build',
               '--base-paths', 'src', '--build-base', 'build', '--install-base', 'install']
    if request.param:
        command.append('--symlink-install')
    done = subprocess.run(command, cwd=base, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    assert f'Finished <<< {PACKAGE}' in done.stdout
    return base


def sourced(workspace: Path, *command: str) -> subprocess.CompletedProcess:
    """``command`` run after ``. install/setup.sh``, as a user runs ros2 in a workspace."""
    script = f'. {workspace / "install" / "setup.sh"} && exec "$@"'
    return subprocess.run(['sh', '-c', script, 'sh', *command], capture_output=True, text=True,
                          cwd=workspace, timeout=60)


@pytest.fixture(scope='module')
def lookups(workspace) -> dict:
    done = sourced(workspace, sys.executable, '-c', LOOKUPS, PACKAGE)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_ros2_run_finds_every_executable_of_the_built_package(workspace, lookups):
    prefix = workspace / 'install' / PACKAGE
    assert Path(lookups['prefix']) == prefix
    assert (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / PACKAGE).exists()
    assert lookups['marker'] == str(prefix)
    assert lookups['executables'] == sorted(EXECUTABLES)
    # The package the executables import is the workspace's, not another installed copy.
    assert Path(lookups['module']).resolve().is_relative_to(workspace)


def test_ros2_launch_finds_the_launch_rviz_and_config_files(lookups):
    assert Path(lookups['share']).name == PACKAGE
    for relative in ('package.xml', 'launch/planner.launch.py', 'rviz/planner.rviz',
                     'config/planner.yaml'):
        installed = Path(lookups['files'][Path(relative).name])
        assert installed.read_bytes() == (ROOT / relative).read_bytes(), relative
        assert installed.parent.name == Path(lookups['share'], relative).parent.name


def test_the_installed_command_runs_in_the_sourced_workspace(workspace, lookups):
    command = Path(lookups['prefix']) / 'lib' / PACKAGE / 'uav-comm-planner'
    done = sourced(workspace, str(command), '--version')
    version = ElementTree.parse(PACKAGE_XML).getroot().findtext('version')
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f'uav-comm-planner {version}'


# --- what is installed -----------------------------------------------------------------------

#: The development tools, in devtools/ beside the package: never installed.
DEVTOOLS = ('sitl', 'px4_sitl', 'bench', 'replans', 'flights', 'docgen')


def development_tools_among(paths: list[str]) -> list[str]:
    """The paths (with / separators) that are a development tool or lie under devtools/."""
    return [path for path in paths if 'devtools' in path.split('/')
            or Path(path).suffix == '.py' and Path(path).stem in DEVTOOLS]


def test_the_wheel_holds_the_package_and_no_development_tools(tmp_path):
    """The wheel pip installs from the checkout (setup.py's packages) has every module of the
    package and its airframe files, and nothing of devtools/, although a copy of the checkout
    holds devtools/."""
    import zipfile

    source = tmp_path / 'src'
    shutil.copytree(ROOT, source, ignore=NOT_SOURCES)
    copied = {path.stem for path in (source / 'devtools').glob('*.py')}
    assert set(DEVTOOLS) <= copied
    done = subprocess.run([sys.executable, '-m', 'pip', 'wheel', '--quiet', '--no-deps',
                           '--no-build-isolation', '--no-index', '--wheel-dir',
                           str(tmp_path / 'wheel'), str(source)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    (wheel,) = (tmp_path / 'wheel').glob(f'{PACKAGE}-*.whl')
    names = zipfile.ZipFile(wheel).namelist()
    modules = sorted(str(path.relative_to(ROOT)) for path in (ROOT / PACKAGE).rglob('*.py'))
    # and its package data: the airframe files (not the samples they were fitted to)
    airframes = [str(path.relative_to(ROOT))
                 for path in (ROOT / PACKAGE / 'vehicle' / 'airframes').glob('*.yaml')]
    assert airframes
    assert sorted(name for name in names if name.startswith(f'{PACKAGE}/')) == sorted(
        modules + airframes)
    version = wheel.name.split('-')[1]
    assert {name.split('/')[0] for name in names} == {
        PACKAGE, f'{PACKAGE}-{version}.data', f'{PACKAGE}-{version}.dist-info'}
    assert development_tools_among(names) == []
    assert development_tools_among(['devtools/__init__.py', f'{PACKAGE}/vehicle/sitl.py']) == [
        'devtools/__init__.py', f'{PACKAGE}/vehicle/sitl.py']


def test_the_colcon_install_holds_no_development_tools(workspace, lookups, request):
    """colcon's install of the package: its modules, none of devtools/. (A symlink-install
    links the package's folder in the checkout, as an editable install does; there the
    package itself is checked.)"""
    package = Path(lookups['module']).parent
    installed = sorted(str(path.relative_to(package.parent)) for path in package.rglob('*.py'))
    assert f'{PACKAGE}/vehicle/limits.py' in installed
    assert development_tools_among(installed) == []
    if not request.node.callspec.params['workspace']:
        files = [str(path.relative_to(workspace / 'install'))
                 for path in (workspace / 'install').rglob('*')]
        assert package.is_relative_to(workspace / 'install')
        assert development_tools_among(files) == []


# --- launch file -----------------------------------------------------------------------------

#: Keywords of Jazzy's launch_ros.actions.Node and of the ExecuteProcess it extends.
NODE_KEYWORDS = {'executable', 'package', 'name', 'namespace', 'exec_name', 'parameters',
                 'remappings', 'ros_arguments', 'arguments', 'cmd', 'cwd', 'env',
                 'additional_env', 'shell', 'sigterm_timeout', 'sigkill_timeout',
                 'emulate_tty', 'output', 'output_format', 'log_cmd', 'cached_output',
                 'prefix', 'respawn', 'respawn_delay', 'respawn_max_retries', 'on_exit',
                 'condition'}


class _Stand:
    """A stand-in of one launch class: keeps what it was made with."""

    def __init__(self, *args, **kwargs) -> None:
        self.args, self.kwargs = args, kwargs


class _Argument(_Stand):
    def __init__(self, name, *, default_value=None, description=None, choices=None):
        super().__init__(name, default_value=default_value, description=description,
                         choices=choices)
        self.name = name


class _Node(_Stand):
    def __init__(self, **kwargs) -> None:
        unknown = set(kwargs) - NODE_KEYWORDS
        assert not unknown, f'launch_ros.actions.Node takes no {sorted(unknown)}'
        super().__init__(**kwargs)


class _Configuration(_Stand):
    def perform(self, context: dict) -> str:
        return context[self.args[0]]


class _Share(_Stand):
    def perform(self, context: dict) -> str:
        return f'/opt/ros/jazzy/share/{self.args[0]}'


@pytest.fixture
def launch_file(monkeypatch):
    """The launch file imported against stand-ins of launch and launch_ros."""
    stand_ins = {
        'launch': {'LaunchDescription': _Stand},
        'launch.actions': {'DeclareLaunchArgument': _Argument, 'OpaqueFunction': _Stand},
        'launch.substitutions': {'LaunchConfiguration': _Configuration,
                                 'PathJoinSubstitution': _Stand},
        'launch_ros': {}, 'launch_ros.actions': {'Node': _Node},
        'launch_ros.substitutions': {'FindPackageShare': _Share},
    }
    for name, members in stand_ins.items():
        monkeypatch.setitem(sys.modules, name, types.SimpleNamespace(**members))
    spec = importlib.util.spec_from_file_location('planner_launch_stand_in', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


ARGUMENTS = ['params_file', 'namespace', 'mavlink_url', 'use_sim_time', 'log_level',
             'use_rviz', 'color']


def _launch(module, **given) -> list[_Node]:
    """The nodes the launch file starts with the arguments ``given`` (others: defaults)."""
    (description,) = module.generate_launch_description().args
    declared = {a.name: a for a in description if isinstance(a, _Argument)}
    assert list(declared) == ARGUMENTS
    context = {name: a.kwargs['default_value'] for name, a in declared.items()}
    context['params_file'] = str(ROOT / 'config' / 'planner.yaml')
    context.update(given)
    for name, value in given.items():
        choices = declared[name].kwargs['choices']
        assert choices is None or value in choices, (name, value)
    (opaque,) = [a for a in description if type(a) is _Stand]
    return opaque.kwargs['function'](context)


def test_launch_declares_its_arguments_with_their_choices(launch_file):
    (description,) = launch_file.generate_launch_description().args
    declared = {a.name: a.kwargs for a in description if isinstance(a, _Argument)}
    assert list(declared) == ARGUMENTS
    # Booleans take every spelling launch's conditions take, so no fixed choices.
    assert declared['use_sim_time']['choices'] is declared['use_rviz']['choices'] is None
    assert declared['log_level']['choices'] == ('debug', 'info', 'warn', 'error', 'fatal')
    assert [declared[name]['default_value'] for name in ARGUMENTS[1:]] == [
        '', '', 'false', 'info', 'false', 'auto']
    assert all(kwargs['description'] for kwargs in declared.values())
    setup_text = (ROOT / 'setup.py').read_text(encoding='utf-8')
    assert f"'{launch_file.EXECUTABLE} = {{PACKAGE}}.ros.launcher:main'" in setup_text
    from uav_comm_planner.ros.node import NODE_NAME
    assert launch_file.NODE_NAME == NODE_NAME and launch_file.PACKAGE == PACKAGE


def test_launch_starts_the_planner_with_its_options(launch_file, monkeypatch):
    monkeypatch.setattr(sys.stdout, 'isatty', lambda: False)
    (planner,) = _launch(launch_file)
    options = planner.kwargs
    assert (options['package'], options['executable'], options['name']) == (
        PACKAGE, 'planner', 'uav_comm_planner')
    assert options['namespace'] == '' and options['output'] == 'screen'
    shipped = yaml.safe_load((ROOT / 'config' / 'planner.yaml').read_text())
    assert options['parameters'] == [shipped['uav_comm_planner']['ros__parameters'],
                                     {'use_sim_time': False}]
    assert options['ros_arguments'] == ['--log-level', 'info']
    # A redirected launch: the node's pseudo-terminal output carries no colour codes.
    assert options['emulate_tty'] is True
    assert options['additional_env'] == {'RCUTILS_COLORIZED_OUTPUT': '0'}


def test_launch_arguments_reach_the_node(launch_file, monkeypatch):
    monkeypatch.setattr(sys.stdout, 'isatty', lambda: True)
    (planner,) = _launch(launch_file, namespace='uav1', use_sim_time='true', log_level='debug',
                         mavlink_url='udpin:0.0.0.0:14550')
    options = planner.kwargs
    assert options['namespace'] == 'uav1'
    assert options['parameters'][1:] == [{'use_sim_time': True},
                                         {'mavlink_url': 'udpin:0.0.0.0:14550'}]
    assert options['ros_arguments'] == ['--log-level', 'debug']
    assert options['additional_env'] == {'RCUTILS_COLORIZED_OUTPUT': '1'}
    (plain,) = _launch(launch_file, color='false')
    assert plain.kwargs['additional_env'] == {'RCUTILS_COLORIZED_OUTPUT': '0'}


def test_launch_booleans_take_the_spellings_launch_takes(launch_file, monkeypatch):
    monkeypatch.setattr(launch_file, 'get_package_share_directory', lambda package: '/opt')
    for spelling, value in (('true', True), ('True', True), ('TRUE', True), ('1', True),
                            (' true ', True), ('false', False), ('False', False), ('0', False)):
        nodes = _launch(launch_file, use_sim_time=spelling, use_rviz=spelling, color=spelling)
        assert nodes[0].kwargs['parameters'][1] == {'use_sim_time': value}, spelling
        assert len(nodes) == (2 if value else 1), spelling
        assert nodes[0].kwargs['additional_env'] == {
            'RCUTILS_COLORIZED_OUTPUT': '1' if value else '0'}
    for bad in ('yes', 'on', '', 'treu'):
        with pytest.raises(RuntimeError, match='expected true or false'):
            _launch(launch_file, use_sim_time=bad)


def test_without_rviz2_a_launch_that_asks_for_it_starts_nothing(launch_file, monkeypatch):
    """rviz2 not installed: the launch fails before it returns any action, the planner's
    included, so no planner is left running without its parent (with mavlink_url, commanding
    the vehicle)."""
    from ament_index_python.packages import PackageNotFoundError

    def not_installed(package):
        raise PackageNotFoundError(package)
    monkeypatch.setattr(launch_file, 'get_package_share_directory', not_installed)
    with pytest.raises(RuntimeError, match="package 'rviz2' is not installed, so nothing was "
                                           'started'):
        _launch(launch_file, use_rviz='True', mavlink_url='udpin:0.0.0.0:14550')
    (planner,) = _launch(launch_file, use_rviz='false')     # not asked for: not needed
    assert planner.kwargs['executable'] == 'planner'


def test_use_rviz_starts_rviz_with_the_package_s_view_in_the_namespace(launch_file,
                                                                        monkeypatch):
    monkeypatch.setattr(launch_file, 'get_package_share_directory',
                        lambda package: f'/opt/ros/jazzy/share/{package}')
    planner, rviz = _launch(launch_file, namespace='uav1', use_rviz='true', use_sim_time='true')
    options = rviz.kwargs
    assert (options['package'], options['executable']) == ('rviz2', 'rviz2')
    assert options['namespace'] == planner.kwargs['namespace'] == 'uav1'
    assert options['arguments'] == ['-d', f'/opt/ros/jazzy/share/{PACKAGE}/rviz/planner.rviz']
    assert options['parameters'] == [{'use_sim_time': True}]
    assert (ROOT / 'rviz' / 'planner.rviz').is_file()


def test_launch_parameters_reach_the_node_in_any_namespace(launch_file, tmp_path):
    node_parameters = launch_file.node_parameters
    shipped = node_parameters(str(ROOT / 'config' / 'planner.yaml'), '')
    assert shipped == node_parameters(str(ROOT / 'config' / 'planner.yaml'), 'uav1')
    expected = yaml.safe_load((ROOT / 'config' / 'planner.yaml').read_text())
    assert shipped == expected['uav_comm_planner']['ros__parameters']
    layered = tmp_path / 'p.yaml'
    layered.write_text('/**:\n  ros__parameters: {num_slots: 10, horizon_s: 10.0}\n'
                       '/uav1/uav_comm_planner:\n  ros__parameters: {num_slots: 20}\n'
                       'other_node:\n  ros__parameters: {num_slots: 30}\n')
    assert node_parameters(str(layered), 'uav1') == {'num_slots': 20, 'horizon_s': 10.0}
    assert node_parameters(str(layered), '') == {'num_slots': 10, 'horizon_s': 10.0}
    wrong = tmp_path / 'wrong.yaml'
    wrong.write_text('other_node:\n  ros__parameters: {num_slots: 30}\n')
    with pytest.raises(RuntimeError, match='no ros__parameters for /uav_comm_planner'):
        node_parameters(str(wrong), '')


def test_launch_description_builds_when_launch_is_installed():
    # launch.actions, not launch: from the checkout, the launch/ folder alone imports as an
    # empty namespace package called launch.
    pytest.importorskip('launch.actions', reason='the launch package comes with a ROS 2 '
                                                 'installation (not on PyPI); the file ran '
                                                 'against stand-ins above')
    pytest.importorskip('launch_ros.actions', reason='launch_ros comes with a ROS 2 '
                                                     'installation')
    spec = importlib.util.spec_from_file_location('planner_launch', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    names = [argument.name for argument in description.get_launch_arguments()]
    assert names == ARGUMENTS


# --- RViz configuration ----------------------------------------------------------------------

def _displays() -> list[dict]:
    document = yaml.safe_load(RVIZ_FILE.read_text(encoding='utf-8'))
    manager = document['Visualization Manager']
    assert manager['Global Options']['Fixed Frame'] == 'map'
    return manager['Displays']


def test_rviz_shows_the_plan_the_ground_nodes_and_the_vehicle_on_relative_topics():
    from uav_comm_planner.ros.node import TOPIC_GROUND_NODES
    from uav_comm_planner.ros.params import NodeSettings
    from uav_comm_planner.ros.publishing import TOPIC_MARKERS, TOPIC_PATH
    from uav_comm_planner.ros.vehicle import TOPIC_VEHICLE_POSE, VEHICLE_POSE_QOS

    assert NodeSettings().frame_id == 'map'
    topics = {display['Class']: display['Topic'] for display in _displays()
              if 'Topic' in display}
    # Relative, so that RViz in the planner's namespace resolves them to the planner's.
    assert {display: topic['Value'] for display, topic in topics.items()} == {
        'rviz_default_plugins/Path': TOPIC_PATH,
        'rviz_default_plugins/MarkerArray': TOPIC_MARKERS,
        'rviz_default_plugins/PoseArray': TOPIC_GROUND_NODES,
        'rviz_default_plugins/Pose': TOPIC_VEHICLE_POSE}
    # The planner's outputs are transient local: RViz must ask for the same to get a plan
    # published before it started.
    for output in ('rviz_default_plugins/Path', 'rviz_default_plugins/MarkerArray'):
        assert topics[output]['Durability Policy'] == 'Transient Local'
        assert topics[output]['Reliability Policy'] == 'Reliable'
    assert VEHICLE_POSE_QOS.reliability.name == 'RELIABLE'
    assert topics['rviz_default_plugins/Pose']['Reliability Policy'] == 'Reliable'


def test_rviz_marker_namespaces_are_the_ones_the_node_publishes():
    from uav_comm_planner.core.optimizer import plan
    from uav_comm_planner.core.scenario import paper_scenario
    from uav_comm_planner.ros.messages import marker_array

    result = plan(paper_scenario('I').replace(num_slots=10, horizon_s=40.0))
    published = {marker.ns for marker in marker_array(result, 'map', 0).markers}
    (markers,) = [d for d in _displays() if d['Class'] == 'rviz_default_plugins/MarkerArray']
    assert set(markers['Namespaces']) == published


# --- license, citation, changelog ------------------------------------------------------------

def test_license_is_the_apache_text_package_xml_names():
    text = (ROOT / 'LICENSE').read_text(encoding='utf-8')
    assert ElementTree.parse(PACKAGE_XML).getroot().findtext('license') == 'Apache-2.0'
    assert 'Apache License' in text and 'Version 2.0, January 2004' in text
    assert 'END OF TERMS AND CONDITIONS' in text and 'APPENDIX' in text
    assert text.count('\n') > 190


def test_citation_names_the_software_version_and_the_letter():
    citation = yaml.safe_load((ROOT / 'CITATION.cff').read_text(encoding='utf-8'))
    version = ElementTree.parse(PACKAGE_XML).getroot().findtext('version')
    assert citation['cff-version'] == '1.2.0' and citation['type'] == 'software'
    assert str(citation['version']) == version and citation['license'] == 'Apache-2.0'
    (letter,) = citation['references']
    assert letter['type'] == 'article' and letter['year'] == 2018
    assert letter['journal'] == 'IEEE Wireless Communications Letters'
    assert [a['family-names'] for a in letter['authors']] == ['Wang', 'Ren', 'Chen', 'Ding',
                                                              'Yang']


def test_changelog_has_the_ros_layout():
    """catkin_generate_changelog's layout: the title between caret lines, then sections
    'Forthcoming' or 'X.Y.Z (YYYY-MM-DD)', each underlined with dashes, of '* ' items."""
    lines = (ROOT / 'CHANGELOG.rst').read_text(encoding='utf-8').splitlines()
    title = f'Changelog for package {PACKAGE}'
    assert lines[:3] == ['^' * len(title), title, '^' * len(title)]
    sections = [(i, line) for i, line in enumerate(lines[3:], start=3)
                if line and set(line) == {'-'}]
    assert sections
    for i, underline in sections:
        heading = lines[i - 1]
        assert len(underline) == len(heading), heading
        assert heading == 'Forthcoming' or re.fullmatch(
            r'\d+\.\d+\.\d+ \(\d{4}-\d{2}-\d{2}\)', heading), heading
        assert lines[i + 1].startswith('* '), heading


# --- make dev --------------------------------------------------------------------------------

def _make_install_commands(venv: Path, *, always: bool = False) -> str:
    """What ``make install`` would run for ``venv`` (make's dry run: nothing is installed)."""
    command = (['make', '--no-print-directory', '--dry-run', 'install', f'VENV={venv}']
               + ['--always-make'] * always)
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_make_dev_makes_every_later_install_editable(tmp_path):
    """An installed, up-to-date virtual environment reinstalls editable once ``make dev``
    has left its mark, and normally again once the mark is removed."""
    if shutil.which('make') is None:
        pytest.skip('make is not installed')
    venv = tmp_path / 'venv'
    (venv / 'bin').mkdir(parents=True)
    (venv / 'bin' / 'python').touch(mode=0o755)
    normal = _make_install_commands(venv, always=True)
    # The tested set: the lock file constrains every install.
    assert "-m pip install --quiet --constraint constraints.txt '.[ros,plots,study,test]'" \
        in normal
    assert '--editable' not in normal
    (venv / '.mode-normal').touch()
    (venv / '.installed').touch()          # installed after every source and the mode
    assert 'pip install' not in _make_install_commands(venv)
    (venv / '.editable').touch()
    editable = _make_install_commands(venv)
    assert ("-m pip install --quiet --constraint constraints.txt --editable "
            "'.[ros,plots,study,test]'") in editable
    # An editable install leaves out data_files; the recipe copies what ros2 run/launch need.
    assert 'cp -r package.xml config launch rviz' in editable
    # What that install leaves; then the mark goes and the next install is a normal one.
    (venv / '.mode-normal').rename(venv / '.mode-editable')
    (venv / '.installed').touch()
    assert 'pip install' not in _make_install_commands(venv)
    (venv / '.editable').unlink()
    assert "-m pip install --quiet --constraint constraints.txt '.[ros,plots,study,test]'" \
        in _make_install_commands(venv)


def test_the_lock_file_pins_every_requirement_within_setup_pys_ranges():
    """constraints.txt (``make lock``) holds one exact version of every distribution that
    setup.py asks for, with or without its extras, and each lies in setup.py's range; the
    Makefile installs with it."""
    from importlib.metadata import requires
    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name

    pins = {}
    for line in (ROOT / 'constraints.txt').read_text(encoding='utf-8').splitlines():
        line = line.split('#', 1)[0].strip()
        if line:
            name, _, version = line.partition('==')
            assert version, f'constraints.txt: {line!r} is not an exact pin'
            pins[canonicalize_name(name)] = version
    wanted = [Requirement(text) for text in requires(PACKAGE)]
    assert len(wanted) >= 15
    for requirement in wanted:
        name = canonicalize_name(requirement.name)
        assert name in pins, f'{requirement.name} is not pinned in constraints.txt'
        assert requirement.specifier.contains(pins[name], prereleases=True), \
            f'{requirement.name}=={pins[name]} is outside setup.py\'s {requirement.specifier}'
    assert '--constraint $(CONSTRAINTS)' in (ROOT / 'Makefile').read_text(encoding='utf-8')


@pytest.mark.skipif(shutil.which('make') is None, reason='needs make')
def test_make_run_says_it_installs_before_the_long_install():
    """`make run` on a fresh clone installs for minutes before the node starts: its first line
    says so (make -n: the commands, none run; -W setup.py: as if a source changed)."""
    done = subprocess.run(['make', '--no-print-directory', '-n', '-W', 'setup.py', 'run'],
                          cwd=ROOT, text=True, capture_output=True, timeout=60)
    assert done.returncode == 0, done.stderr
    first = done.stdout.splitlines()[0]
    assert first.startswith('echo ') and 'Installing' in first and 'minutes' in first
    assert done.stdout.index('Installing') < done.stdout.index('pip install')
