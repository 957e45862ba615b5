"""The package's layering, read from each module's imports with ``ast``.

| folder    | may import (besides the standard library and errors/files)              |
| --------- | ----------------------------------------------------------------------- |
| core/     | numpy, scipy, cvxpy, clarabel                                           |
| vehicle/  | core, pymavlink, pymap3d, yaml (airframe files)                         |
| mission/  | core, vehicle (the pipeline the node and the command line share)        |
| ros/      | core, vehicle, mission, rclpy and ROS messages                          |
| tools/    | core, vehicle, mission, scipy, matplotlib (contourpy), dask, pyarrow; never rclpy |
| top level | errors and files import nothing of the package; ``__init__`` re-exports |
|           | the public API from core, mission and vehicle                            |

Inside vehicle/, ``mavlink/`` builds on the other modules, none of which imports it.

Beside the package, ``devtools/`` (SITL launchers, the benchmark, docgen; not installed) may
import any part of the package; no module of the package imports it.
"""

from __future__ import annotations

import ast
from pathlib import Path
import sys

import pytest

PACKAGE = 'uav_comm_planner'
ROOT = Path(__file__).resolve().parents[1] / PACKAGE
#: The development tools beside the package, which setup.py leaves out.
DEVTOOLS_NAME = 'devtools'
DEVTOOLS = ROOT.parent / DEVTOOLS_NAME
FOLDERS = ('core', 'vehicle', 'mission', 'ros', 'tools')

#: For each folder, the package's own folders it may import.
ALLOWED_INSIDE = {
    'core': {'core'},
    'vehicle': {'core', 'vehicle'},
    'mission': {'core', 'vehicle', 'mission'},
    'ros': {'core', 'vehicle', 'mission', 'ros'},
    'tools': {'core', 'vehicle', 'mission', 'tools'},
}
#: Third-party top-level modules each folder may import.
THIRD_PARTY = {
    'core': {'numpy', 'scipy', 'cvxpy', 'clarabel'},
    'vehicle': {'numpy', 'pymavlink', 'pymap3d', 'yaml'},
    'mission': {'numpy'},
    'ros': {'numpy', 'rclpy', 'builtin_interfaces', 'geometry_msgs', 'nav_msgs', 'std_msgs',
            'std_srvs', 'visualization_msgs', 'rcl_interfaces', 'diagnostic_msgs',
            'trajectory_msgs'},
    'tools': {'numpy', 'scipy', 'matplotlib', 'contourpy', 'dask', 'distributed', 'pyarrow'},
}
#: The top-level modules of the package that every folder may use.
SHARED = {'errors', 'files'}
ROS_MODULES = THIRD_PARTY['ros'] - {'numpy'}


def imported_modules(path: Path) -> set[str]:
    """Every module named by an import statement of ``path``, at any depth (lazy ones too)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, f'{path}: relative import; use absolute imports'
            names.add(node.module)
            if node.module == PACKAGE:
                names.update(f'{PACKAGE}.{alias.name}' for alias in node.names)
    return names


def modules_of(folder: str) -> list[Path]:
    """Every module of ``folder``, those of its subpackages (``tools/study/``,
    ``vehicle/mavlink/``) too."""
    return sorted((ROOT / folder).rglob('*.py'))


def package_part(name: str) -> str | None:
    """``core`` for ``uav_comm_planner.core.model``; ``errors`` for ``uav_comm_planner.errors``."""
    parts = name.split('.')
    return parts[1] if parts[0] == PACKAGE and len(parts) > 1 else None


def test_the_tree_has_the_four_folders_and_a_small_top_level():
    assert all((ROOT / folder / '__init__.py').is_file() for folder in FOLDERS)
    assert {p.stem for p in ROOT.glob('*.py')} == {'__init__', 'errors', 'files'}
    assert not [p for p in ROOT.glob('*/') if p.is_dir() and p.name not in FOLDERS
                and p.name != '__pycache__']


@pytest.mark.parametrize('folder', FOLDERS)
def test_each_folder_imports_only_what_its_layer_allows(folder):
    allowed_parts = ALLOWED_INSIDE[folder] | SHARED
    allowed_external = THIRD_PARTY[folder] | set(sys.stdlib_module_names) | {'__future__'}
    wrong = []
    for path in modules_of(folder):
        for name in imported_modules(path):
            top = name.split('.')[0]
            if top == PACKAGE:
                if package_part(name) not in allowed_parts:
                    wrong.append(f'{path.relative_to(ROOT)} imports {name}')
            elif top not in allowed_external:
                wrong.append(f'{path.relative_to(ROOT)} imports {name}')
    assert wrong == []


def test_only_ros_imports_rclpy_or_ros_messages():
    offenders = [f'{path.relative_to(ROOT)} imports {name}'
                 for folder in ('core', 'vehicle', 'tools') for path in modules_of(folder)
                 for name in imported_modules(path) if name.split('.')[0] in ROS_MODULES]
    assert offenders == []


def test_errors_and_files_import_nothing_of_the_package():
    for stem in SHARED:
        names = imported_modules(ROOT / f'{stem}.py')
        assert not [n for n in names if n.split('.')[0] == PACKAGE], stem


def test_the_public_api_comes_from_core_mission_vehicle_and_errors():
    names = imported_modules(ROOT / '__init__.py')
    assert {package_part(n) for n in names if n.split('.')[0] == PACKAGE} <= {'core', 'errors'}
    import uav_comm_planner
    # The names loaded on first use: from the core, the mission layer and the vehicle's limits.
    assert {package_part(n) for n in uav_comm_planner._LAZY.values()} == {'core', 'mission',
                                                                          'vehicle'}
    for name in ('plan', 'paper_scenario', 'Scenario', 'SolverSettings', 'PlanResult',
                 'PlannerError', 'InvalidScenarioError', 'InfeasibleHorizonError',
                 'SolverError', 'MissionExportError', 'plan_mission', 'MissionRequest',
                 'MissionPlan', 'VehicleLimits'):
        assert hasattr(uav_comm_planner, name), name
        assert name in uav_comm_planner.__all__, name


def test_the_mission_layer_imports_from_the_top_level_package():
    """``from uav_comm_planner import ...`` gives the mission layer's own objects; a name the
    package does not export is an AttributeError, not a lazy import of something else."""
    import uav_comm_planner
    from uav_comm_planner import MissionPlan, MissionRequest, plan_mission, VehicleLimits
    from uav_comm_planner.mission import pipeline, request
    from uav_comm_planner.vehicle import limits

    assert plan_mission is pipeline.plan_mission and MissionPlan is pipeline.MissionPlan
    assert MissionRequest is request.MissionRequest
    assert VehicleLimits is limits.VehicleLimits
    with pytest.raises(AttributeError, match="no attribute 'plan_missions'"):
        uav_comm_planner.plan_missions


def devtools_modules() -> list[Path]:
    """Every module of devtools/."""
    return sorted(DEVTOOLS.rglob('*.py'))


def test_devtools_holds_the_sitl_launchers_benchmark_and_docgen_outside_the_package():
    """The development tools live beside the package, none of them inside it."""
    tools = {'sitl', 'px4_sitl', 'bench', 'replans', 'flights', 'docgen'}
    assert tools <= {path.stem for path in devtools_modules()}
    assert (DEVTOOLS / '__init__.py').is_file() and (DEVTOOLS / 'README.md').is_file()
    assert not [path for path in ROOT.rglob('*.py') if path.stem in tools]


def test_the_package_never_imports_devtools_or_the_tests():
    """The installed package runs without devtools/ and test/ (neither is installed)."""
    offenders = [f'{path.relative_to(ROOT)} imports {name}' for path in ROOT.rglob('*.py')
                 for name in imported_modules(path)
                 if name.split('.')[0] in (DEVTOOLS_NAME, 'test', 'helpers', 'conftest')]
    assert offenders == []


def test_devtools_import_the_package_and_each_other_only():
    """devtools/ may use any part of the package (absolute imports), the standard library,
    numpy, scipy and pymavlink; never rclpy itself (docgen reaches ROS through ros/)."""
    allowed = {PACKAGE, DEVTOOLS_NAME, 'numpy', 'scipy', 'pymavlink', '__future__'} | set(
        sys.stdlib_module_names)
    wrong = [f'{path.relative_to(DEVTOOLS)} imports {name}' for path in devtools_modules()
             for name in imported_modules(path) if name.split('.')[0] not in allowed]
    assert wrong == []


def module_name(path: Path) -> str:
    """``uav_comm_planner.vehicle.mavlink.items`` for that file; a package by its folder
    (``uav_comm_planner.tools.study`` for ``uav_comm_planner/tools/study/__init__.py``)."""
    parts = path.relative_to(ROOT.parent).with_suffix('').parts
    return '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)


def package_imports(path: Path, modules: set[str]) -> set[str]:
    """The modules of ``modules`` that ``path`` imports, lazily or not; ``from A import B``
    imports ``A.B`` when that is a module, else ``A``."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            names.update(f'{node.module}.{alias.name}' if f'{node.module}.{alias.name}'
                         in modules else node.module for alias in node.names)
    return names & modules


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import cycles of ``graph`` (module -> the modules it imports), one per back edge of
    a depth-first walk, each as the path from a module back to itself."""
    found, done, trail = [], set(), []

    def walk(name: str) -> None:
        trail.append(name)
        for imported in sorted(graph[name]):
            if imported in trail:
                found.append(trail[trail.index(imported):] + [imported])
            elif imported not in done:
                walk(imported)
        trail.pop()
        done.add(name)

    for name in sorted(graph):
        if name not in done:
            walk(name)
    return found


def test_imports_go_one_way():
    """No module imports itself through others, counting the imports inside functions: a
    cycle would make the import order matter (study imported its figures, which imported it)."""
    paths = {module_name(path): path for path in (*ROOT.rglob('*.py'), *devtools_modules())}
    graph = {name: package_imports(path, set(paths)) for name, path in paths.items()}
    assert cycles(graph) == []
    assert cycles({'a': {'b'}, 'b': {'c'}, 'c': {'a'}}) == [['a', 'b', 'c', 'a']]


def test_mavlink_builds_on_the_other_vehicle_modules_never_the_reverse():
    """limits, timing, flyable, evaluation, geodesy and firmware never import vehicle/mavlink/
    (which imports them): the mission, its files and the link sit above the vehicle's model
    (the software-in-the-loop launchers that fly missions over it are in devtools/)."""
    modules = {module_name(path) for path in ROOT.rglob('*.py')}
    beside = [path for path in (ROOT / 'vehicle').glob('*.py') if path.stem != '__init__']
    mavlink = f'{PACKAGE}.vehicle.mavlink'
    offenders = [f'{path.relative_to(ROOT)} imports {name}' for path in beside
                 for name in package_imports(path, modules)
                 if name == mavlink or name.startswith(f'{mavlink}.')]
    assert offenders == []
    assert f'{mavlink}.items' in modules and len(beside) >= 6


def test_the_rule_reader_sees_a_violation(tmp_path):
    """The checker itself: a core module importing rclpy or vehicle is caught."""
    bad = tmp_path / 'bad.py'
    bad.write_text('import rclpy\nfrom uav_comm_planner.vehicle import mission\n'
                   'def f():\n    from uav_comm_planner.ros import node\n')
    assert imported_modules(bad) == {'rclpy', 'uav_comm_planner.vehicle',
                                     'uav_comm_planner.ros'}


#: Rooms small enough to read: a module over this many lines, or a class over
#: MAX_CLASS_LINES, is to be split by concept.
MAX_MODULE_LINES = 600
MAX_CLASS_LINES = 200


def test_no_module_or_class_outgrows_its_room():
    too_long = []
    for path in sorted((*ROOT.rglob('*.py'), *devtools_modules())):
        text = path.read_text()
        where = path.relative_to(ROOT.parent)
        if len(text.splitlines()) > MAX_MODULE_LINES:
            too_long.append(f'{where}: {len(text.splitlines())} lines')
        for node in ast.walk(ast.parse(text, str(path))):
            if isinstance(node, ast.ClassDef):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_CLASS_LINES:
                    too_long.append(f'{where}: class {node.name}, {lines} lines')
    assert too_long == []
