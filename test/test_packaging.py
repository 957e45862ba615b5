"""The package as ROS users install it: dependency keys, the colcon layout, launch and RViz files.

- Every ``*_depend`` key of package.xml must be a ROS 2 Jazzy package or a rosdep key with a
  rule for Ubuntu noble, read from a snapshot of rosdistro (``shared/rosdistro`` beside the
  checkout or above it, or the folder in ``UAV_COMM_PLANNER_ROSDISTRO``); without the
  snapshot those tests skip and say so.
- ``setup.py install`` with setup.cfg's script folder, as ``colcon build`` runs it, must give
  the layout that ``ros2 run`` and ``ros2 launch`` search.
- The launch file is parsed (and built when ``launch`` is importable); the RViz file is YAML
  that names the node's own topics.
"""

from __future__ import annotations

import ast
import os
from pathlib import Path
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ElementTree

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = 'uav_comm_planner'
PACKAGE_XML = ROOT / 'package.xml'
LAUNCH_FILE = ROOT / 'launch' / 'planner.launch.py'
RVIZ_FILE = ROOT / 'rviz' / 'planner.rviz'
EXECUTABLES = ('planner', 'send_ground_nodes', 'uav-comm-planner')
#: libyaml's loader when PyYAML has it: the rosdistro files are about 0.9 MB.
LOADER = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)
#: rosdep installers whose rule is a mapping like ``pip: {packages: [...]}``.
INSTALLERS = {'apt', 'pip', 'source', 'npm', 'gem'}


# --- rosdistro snapshot ----------------------------------------------------------------------

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


@pytest.fixture(scope='module')
def rosdistro() -> dict:
    folder = rosdistro_folder()
    if folder is None:
        pytest.skip('no rosdistro snapshot (shared/rosdistro with rosdep/*.yaml and '
                    'jazzy/distribution.yaml) beside or above the checkout, and '
                    'UAV_COMM_PLANNER_ROSDISTRO is not set: cannot check the rosdep keys')
    rules: dict = {}
    for name in ('base.yaml', 'python.yaml'):
        rules.update(yaml.load((folder / 'rosdep' / name).read_text(encoding='utf-8'), LOADER))
    distribution = yaml.load(
        (folder / 'jazzy' / 'distribution.yaml').read_text(encoding='utf-8'), LOADER)
    packages = set()
    for repository, entry in distribution['repositories'].items():
        release = entry.get('release')
        if release:
            packages.update(release.get('packages', [repository]))
    return {'rules': rules, 'jazzy': packages}


def _platform_rule_resolves(rule: object, release: str) -> bool:
    """Whether an OS's rule (list, installer mapping or per-release mapping) gives something."""
    if rule is None:
        return False
    if isinstance(rule, list):
        return True
    if isinstance(rule, dict):
        if set(rule) <= INSTALLERS:
            return True
        if release in rule:
            return _platform_rule_resolves(rule[release], release)
        if '*' in rule:
            return _platform_rule_resolves(rule['*'], release)
    return False


def resolves_for(rule: object, os_name: str = 'ubuntu', release: str = 'noble') -> bool:
    """Whether a rosdep rule installs something on ``os_name`` ``release``.

    A rule maps OS names (or ``'*'``) to a package list, to an installer mapping
    (``pip: {packages: [...]}``) or to a mapping of releases (or ``'*'``) to either; a release
    mapped to null has no package.
    """
    if not isinstance(rule, dict):
        return False
    if os_name in rule:
        return _platform_rule_resolves(rule[os_name], release)
    if '*' in rule:
        return _platform_rule_resolves(rule['*'], release)
    return False


def dependency_keys() -> list[tuple[str, str]]:
    """Every (tag, key) of package.xml's ``*depend`` elements."""
    root = ElementTree.parse(PACKAGE_XML).getroot()
    return [(element.tag, element.text.strip()) for element in root
            if element.tag.endswith('depend')]


def test_package_xml_has_dependencies_to_check():
    keys = [key for _, key in dependency_keys()]
    assert len(keys) >= 10 and 'rclpy' in keys and len(set(keys)) == len(keys)


def test_every_dependency_key_resolves_on_ubuntu_noble(rosdistro):
    unresolved = [f'<{tag}>{key}' for tag, key in dependency_keys()
                  if key not in rosdistro['jazzy']
                  and not resolves_for(rosdistro['rules'].get(key))]
    assert unresolved == [], ('rosdep install would stop at these keys: not a Jazzy package '
                              'and no Ubuntu noble rule in rosdistro')


def test_the_keys_that_broke_rosdep_install_are_refused_by_the_check(rosdistro):
    """The check itself: the earlier package.xml's keys fail it, their replacements pass."""
    rules = rosdistro['rules']
    for wrong in ('python3-clarabel-pip', 'python3-pymavlink', 'python3-pymap3d-pip'):
        assert wrong not in rosdistro['jazzy'] and not resolves_for(rules.get(wrong)), wrong
    for right in ('python3-pymavlink-pip', 'python3-pymap3d', 'python3-cvxpy-pip'):
        assert resolves_for(rules[right]), right
    # A release mapped to null has no package: python3-pymap3d is absent on focal.
    assert not resolves_for(rules['python3-pymap3d'], 'ubuntu', 'focal')


def _requirement_names() -> list[str]:
    """The distribution names of setup.py's install_requires, read with ast."""
    tree = ast.parse((ROOT / 'setup.py').read_text(encoding='utf-8'))
    for node in ast.walk(tree):
        if isinstance(node, ast.keyword) and node.arg == 'install_requires':
            return [re.split(r'[<>=!~ ;\[]', item, maxsplit=1)[0].lower()
                    for item in ast.literal_eval(node.value)]
    raise AssertionError('setup.py has no install_requires')


def test_every_runtime_requirement_has_a_rosdep_key(rosdistro):
    """Each of setup.py's install_requires is installed on the colcon route by some key.

    A key covers a requirement when its noble rule is ``pip`` with that package or the apt
    package ``python3-<name>``; Clarabel is a dependency of cvxpy and comes with it.
    """
    rules = rosdistro['rules']
    provided = set()
    for _, key in dependency_keys():
        ubuntu = (rules.get(key) or {}).get('ubuntu')
        if isinstance(ubuntu, dict) and 'pip' in ubuntu:
            provided.update(name.lower() for name in ubuntu['pip'].get('packages', []))
        elif isinstance(ubuntu, (list, dict)):
            listed = ubuntu if isinstance(ubuntu, list) else ubuntu.get('*') or []
            provided.update(name.lower().removeprefix('python3-') for name in listed)
    if 'cvxpy' in provided:
        provided.add('clarabel')
    missing = [name for name in _requirement_names() if name not in provided]
    assert missing == []


def test_versions_of_package_xml_and_setup_py_agree():
    xml_version = ElementTree.parse(PACKAGE_XML).getroot().findtext('version')
    tree = ast.parse((ROOT / 'setup.py').read_text(encoding='utf-8'))
    versions = [ast.literal_eval(node.value) for node in ast.walk(tree)
                if isinstance(node, ast.keyword) and node.arg == 'version']
    assert versions == [xml_version]


# --- the colcon layout -----------------------------------------------------------------------

def executables_in(prefix: Path, package: str) -> dict[str, Path]:
    """What ``ros2 run`` offers: executable files under ``<prefix>/lib/<package>``."""
    folder = prefix / 'lib' / package
    return {path.name: path for path in sorted(folder.rglob('*'))
            if path.is_file() and os.access(path, os.X_OK)}


@pytest.fixture(scope='module')
def colcon_install(tmp_path_factory) -> Path:
    """The package installed as ``colcon build`` (ament_python, no symlinks) installs it."""
    base = tmp_path_factory.mktemp('colcon')
    build, prefix = base / 'build', base / 'install' / PACKAGE
    build.mkdir()
    command = [sys.executable, 'setup.py', '--quiet', 'egg_info', '--egg-base', str(build),
               'build', '--build-base', str(build / 'build'),
               'install', '--prefix', str(prefix), '--record', str(build / 'files.txt'),
               '--single-version-externally-managed']
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return prefix


def test_ros2_run_finds_every_executable_in_the_colcon_layout(colcon_install, monkeypatch):
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(colcon_install))
    marker = colcon_install / 'share' / 'ament_index' / 'resource_index' / 'packages' / PACKAGE
    assert marker.is_file()
    try:
        from ament_index_python.packages import get_package_prefix
    except ImportError:   # the lookup ros2 run makes, done by hand
        prefix = colcon_install
    else:
        prefix = Path(get_package_prefix(PACKAGE))
    assert prefix == colcon_install
    assert sorted(executables_in(prefix, PACKAGE)) == sorted(EXECUTABLES)


def test_ros2_launch_finds_the_launch_rviz_and_config_files(colcon_install):
    share = colcon_install / 'share' / PACKAGE
    for relative in ('package.xml', 'launch/planner.launch.py', 'rviz/planner.rviz',
                     'config/planner.yaml'):
        installed = share / relative
        assert installed.read_bytes() == (ROOT / relative).read_bytes(), relative


def test_the_installed_command_runs_from_the_colcon_layout(colcon_install):
    """The script in lib/uav_comm_planner runs the installed copy and reads its version."""
    site = next(colcon_install.glob('lib/python3*/site-packages'))
    environment = dict(os.environ, PYTHONPATH=str(site))
    command = executables_in(colcon_install, PACKAGE)['uav-comm-planner']
    done = subprocess.run([str(command), '--version'], capture_output=True, text=True,
                          env=environment, timeout=60)
    version = ElementTree.parse(PACKAGE_XML).getroot().findtext('version')
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f'uav-comm-planner {version}'


# --- launch file -----------------------------------------------------------------------------

def _launch_tree() -> ast.Module:
    return ast.parse(LAUNCH_FILE.read_text(encoding='utf-8'), str(LAUNCH_FILE))


def _calls(tree: ast.AST, name: str) -> list[ast.Call]:
    return [node for node in ast.walk(tree) if isinstance(node, ast.Call)
            and getattr(node.func, 'id', getattr(node.func, 'attr', None)) == name]


def test_launch_file_declares_its_arguments_and_starts_the_planner():
    tree = _launch_tree()
    functions = {node.name for node in tree.body if isinstance(node, ast.FunctionDef)}
    assert 'generate_launch_description' in functions
    declared = [ast.literal_eval(call.args[0]) for call in _calls(tree, 'DeclareLaunchArgument')]
    assert declared == ['params_file', 'namespace', 'mavlink_url']
    constants = {node.targets[0].id: ast.literal_eval(node.value) for node in tree.body
                 if isinstance(node, ast.Assign) and isinstance(node.value, ast.Constant)}
    assert constants['PACKAGE'] == PACKAGE
    setup_text = (ROOT / 'setup.py').read_text(encoding='utf-8')
    assert f"'{constants['EXECUTABLE']} = {{PACKAGE}}.ros.launcher:main'" in setup_text
    from uav_comm_planner.ros.node import NODE_NAME
    assert constants['NODE_NAME'] == NODE_NAME


def test_launch_passes_mavlink_url_only_when_given():
    (planner,) = [node for node in _launch_tree().body
                  if isinstance(node, ast.FunctionDef) and node.name == '_planner']
    guarded = [node for node in ast.walk(planner) if isinstance(node, ast.If)
               and isinstance(node.test, ast.Name) and node.test.id == 'mavlink_url']
    assert len(guarded) == 1
    (append,) = guarded[0].body
    assert ast.unparse(append) == "parameters.append({'mavlink_url': mavlink_url})"
    uses = [node for node in ast.walk(planner)
            if isinstance(node, ast.Constant) and node.value == 'mavlink_url']
    assert len(uses) == 2   # the launch configuration read, and the guarded parameter


def _launch_function(name: str):
    """One plain function of the launch file, compiled on its own (no launch import needed)."""
    tree = _launch_tree()
    (function,) = [node for node in tree.body
                   if isinstance(node, ast.FunctionDef) and node.name == name]
    module = ast.Module(body=[function], type_ignores=[])
    scope = {'yaml': yaml, 'NODE_NAME': 'uav_comm_planner'}
    exec(compile(module, str(LAUNCH_FILE), 'exec'), scope)
    return scope[name]


def test_launch_parameters_reach_the_node_in_any_namespace(tmp_path):
    node_parameters = _launch_function('node_parameters')
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
                                                 'installation (not on PyPI); the file was '
                                                 'parsed above')
    pytest.importorskip('launch_ros.actions', reason='launch_ros comes with a ROS 2 '
                                                     'installation')
    import importlib.util
    spec = importlib.util.spec_from_file_location('planner_launch', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    names = [argument.name for argument in description.get_launch_arguments()]
    assert names == ['params_file', 'namespace', 'mavlink_url']


# --- RViz configuration ----------------------------------------------------------------------

def _displays() -> list[dict]:
    document = yaml.safe_load(RVIZ_FILE.read_text(encoding='utf-8'))
    manager = document['Visualization Manager']
    assert manager['Global Options']['Fixed Frame'] == 'map'
    return manager['Displays']


def test_rviz_shows_the_path_the_markers_and_the_ground_nodes():
    from uav_comm_planner.ros.node import TOPIC_GROUND_NODES
    from uav_comm_planner.ros.publishing import TOPIC_MARKERS, TOPIC_PATH
    from uav_comm_planner.ros.params import NodeSettings

    assert NodeSettings().frame_id == 'map'
    topics = {display['Class']: display['Topic'] for display in _displays()
              if 'Topic' in display}
    assert topics['rviz_default_plugins/Path']['Value'] == '/' + TOPIC_PATH
    assert topics['rviz_default_plugins/MarkerArray']['Value'] == '/' + TOPIC_MARKERS
    assert topics['rviz_default_plugins/PoseArray']['Value'] == '/' + TOPIC_GROUND_NODES
    # The planner's outputs are transient local: RViz must ask for the same to get a plan
    # published before it started.
    for output in ('rviz_default_plugins/Path', 'rviz_default_plugins/MarkerArray'):
        assert topics[output]['Durability Policy'] == 'Transient Local'
        assert topics[output]['Reliability Policy'] == 'Reliable'


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
    command = ['make', '--dry-run', 'install', f'VENV={venv}'] + (['--always-make'] * always)
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
