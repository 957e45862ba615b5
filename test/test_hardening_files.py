"""Files the package reads: only regular files, opened without blocking, read within a cap,
and validated completely (lists within their limits) before any plan, connection or output."""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path
import resource
import threading
import time
from typing import Callable, Iterator

import pytest

from uav_comm_planner.errors import InvalidScenarioError, MissionFileError
from uav_comm_planner.files import InputFileError, read_regular_file, read_text_file
from uav_comm_planner.tools import cli
from uav_comm_planner.vehicle.limits import read_parameter_file
from uav_comm_planner.vehicle.mavlink.files import MAX_MISSION_ITEMS, read_mission_file

#: A refusal must come at once; a blocking open or an endless read would take forever.
PROMPT_S = 5.0


@pytest.fixture
def fifo(tmp_path) -> Iterator[Path]:
    """A FIFO no one writes to; a reader blocked on it is let go at the end of the test."""
    path = tmp_path / 'fifo.json'
    os.mkfifo(path)
    yield path
    with contextlib.suppress(OSError):
        # Releases a reader that opened it blocking (the behaviour this suite refuses).
        os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))


@contextlib.contextmanager
def address_space_cap(extra_bytes: int = 1 << 30) -> Iterator[None]:
    """Cap the process's address space at its present size plus ``extra_bytes`` while the block
    runs, so that a reader that would read ``/dev/zero`` to the end fails fast with a
    MemoryError instead of taking the machine's memory."""
    with open('/proc/self/status', encoding='ascii') as status:
        size_kib = next(int(line.split()[1]) for line in status if line.startswith('VmSize:'))
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    cap = size_kib * 1024 + extra_bytes
    if hard != resource.RLIM_INFINITY:
        cap = min(cap, hard)
    resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def promptly(function: Callable[[], object]) -> object:
    """Run ``function`` in a thread, the address space capped; fail unless it returns or
    raises within PROMPT_S."""
    outcome: dict[str, object] = {}

    def run() -> None:
        try:
            outcome['value'] = function()
        except BaseException as exc:  # noqa: B902 - handed back to the test
            outcome['error'] = exc
    worker = threading.Thread(target=run, daemon=True)
    began = time.monotonic()
    with address_space_cap():
        worker.start()
        worker.join(PROMPT_S)
    assert not worker.is_alive(), f'still running after {PROMPT_S} s: it blocked'
    assert time.monotonic() - began < PROMPT_S
    if 'error' in outcome:
        raise outcome['error']
    return outcome.get('value')


def huge_sparse_file(tmp_path: Path, name: str) -> Path:
    """A file of 64 GiB that takes no disk space: its size alone must refuse it."""
    path = tmp_path / name
    with open(path, 'wb') as handle:
        handle.truncate(64 << 30)
    return path


# The shared reader.

@pytest.mark.parametrize('which, message', [
    ('/dev/zero', 'it is a device'),
    ('fifo', 'it is a pipe'),
    ('folder', 'it is a folder'),
    ('huge', 'is larger than 1000 bytes'),
    ('missing', 'there is no such file'),
])
def test_the_reader_refuses_anything_but_a_small_regular_file_at_once(tmp_path, fifo, which,
                                                                      message):
    paths = {'/dev/zero': Path('/dev/zero'), 'fifo': fifo, 'folder': tmp_path,
             'huge': huge_sparse_file(tmp_path, 'huge'), 'missing': tmp_path / 'missing'}
    with pytest.raises(InputFileError, match=message):
        promptly(lambda: read_regular_file(paths[which], max_bytes=1000))


def test_the_reader_reads_a_regular_file_and_follows_a_link_to_one(tmp_path):
    target = tmp_path / 'a.txt'
    target.write_text('héllo', encoding='utf-8')
    (tmp_path / 'link.txt').symlink_to(target)
    assert read_text_file(tmp_path / 'link.txt', max_bytes=100) == 'héllo'
    assert read_regular_file(target, max_bytes=6) == 'héllo'.encode()
    with pytest.raises(InputFileError, match='larger than 5 bytes'):
        read_regular_file(target, max_bytes=5)
    (tmp_path / 'b.txt').write_bytes(b'\xff')
    with pytest.raises(InvalidScenarioError, match='not UTF-8 text'):
        read_text_file(tmp_path / 'b.txt', max_bytes=10, error=InvalidScenarioError)


def test_a_file_that_grows_past_the_cap_while_read_is_refused(tmp_path, monkeypatch):
    path = tmp_path / 'growing'
    path.write_bytes(b'x' * 10)
    real_read = os.read

    def read_growing(handle, size):
        return real_read(handle, size) or (b'y' * size)   # never reaches the end
    monkeypatch.setattr(os, 'read', read_growing)
    with pytest.raises(InputFileError, match='larger than 100 bytes'):
        read_regular_file(path, max_bytes=100)


# Every reader uses it.

@pytest.mark.parametrize('which', ['/dev/zero', 'fifo', 'folder', 'huge'])
def test_parameter_files_must_be_small_regular_files(tmp_path, fifo, which):
    paths = {'/dev/zero': Path('/dev/zero'), 'fifo': fifo, 'folder': tmp_path,
             'huge': huge_sparse_file(tmp_path, 'huge.param')}
    with pytest.raises(InvalidScenarioError, match='parameter file'):
        promptly(lambda: read_parameter_file(paths[which]))


@pytest.mark.parametrize('which', ['/dev/zero', 'fifo', 'folder', 'huge'])
def test_mission_files_must_be_small_regular_files(tmp_path, which):
    paths = {'/dev/zero': Path('/dev/zero'), 'folder': tmp_path / 'm.plan',
             'huge': huge_sparse_file(tmp_path, 'huge.waypoints')}
    if which == 'fifo':
        os.mkfifo(tmp_path / 'fifo.waypoints')
        paths['fifo'] = tmp_path / 'fifo.waypoints'
    if which == 'folder':
        paths['folder'].mkdir()
    try:
        with pytest.raises(MissionFileError):
            promptly(lambda: read_mission_file(paths[which]))
    finally:
        with contextlib.suppress(OSError, KeyError):
            os.close(os.open(paths['fifo'], os.O_WRONLY | os.O_NONBLOCK))


def test_mission_files_are_refused_beyond_a_mavlink_missions_item_count(tmp_path):
    path = tmp_path / 'big.waypoints'
    row = '1\t0\t3\t16\t0\t0\t0\t0\t47.0\t8.0\t10\t1\n'
    path.write_text('QGC WPL 110\n' + row * (MAX_MISSION_ITEMS + 1))
    with pytest.raises(MissionFileError, match=f'more than a MAVLink mission carries '
                                               f'\\({MAX_MISSION_ITEMS}\\)'):
        read_mission_file(path)
    plan = tmp_path / 'big.plan'
    plan.write_text(json.dumps({'mission': {'plannedHomePosition': [47, 8, 400],
                                            'items': [0] * MAX_MISSION_ITEMS}}))
    with pytest.raises(MissionFileError, match='more than a MAVLink mission'):
        read_mission_file(plan)
    plan.write_text(json.dumps({'mission': {'plannedHomePosition': [47, 8, 400],
                                            'items': [5]}}))
    with pytest.raises(MissionFileError, match='item 1 is int, not an object'):
        read_mission_file(plan)


# The command line: one line, exit 2, nothing written, nothing connected.

def refused(capsys, tmp_path: Path, argv: list[str]) -> str:
    """Run the command line (promptly); return its one error line, checking exit 2 and that
    ``tmp_path`` holds the same files as before."""
    before = sorted(p.name for p in tmp_path.iterdir())
    status = promptly(lambda: cli.main(argv))
    out, err = capsys.readouterr()
    assert status == 2, (out, err)
    assert err.count('\n') == 1 and err.startswith('uav-comm-planner: error: '), err
    assert 'Traceback' not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    return err


@pytest.mark.parametrize('option', ['--vehicle-params', '--scenario'])
@pytest.mark.parametrize('which, message', [('/dev/zero', 'it is a device'),
                                            ('fifo', 'it is a pipe'),
                                            ('folder', 'it is a folder'),
                                            ('huge', 'is larger than')])
def test_plan_refuses_devices_pipes_folders_and_huge_files_in_one_line(tmp_path, fifo, capsys,
                                                                       option, which, message):
    paths = {'/dev/zero': '/dev/zero', 'fifo': str(fifo), 'folder': str(tmp_path),
             'huge': str(huge_sparse_file(tmp_path, 'huge.json'))}
    err = refused(capsys, tmp_path, ['plan', option, paths[which],
                                     '--json', str(tmp_path / 'r.json')])
    assert message in err


@pytest.mark.parametrize('settings', [[], None, 5, 'fast'])
def test_a_result_file_whose_settings_are_not_an_object_is_a_one_line_refusal(
        tmp_path, capsys, settings):
    result = tmp_path / 'result.json'
    result.write_text(json.dumps({'scenario': {'ground_nodes_m': [[0, 0]]},
                                  'settings': settings}))
    err = refused(capsys, tmp_path, ['plan', '--scenario', str(result)])
    assert 'settings in' in err and 'must be a JSON object of solver settings' in err


def test_a_sweep_file_with_too_many_budgets_is_refused_before_the_first_plan(tmp_path, capsys):
    sweep = tmp_path / 'sweep.json'
    sweep.write_text(json.dumps({'scenario': {'ground_nodes_m': [[0, 0]]},
                                 'budgets_w': [1.0] * (cli.MAX_SWEEP_BUDGETS + 1)}))
    err = refused(capsys, tmp_path, ['sweep', '--scenario', str(sweep)])
    assert f'more than {cli.MAX_SWEEP_BUDGETS}' in err
    many = ','.join(['1'] * (cli.MAX_SWEEP_BUDGETS + 1))
    assert f'more than {cli.MAX_SWEEP_BUDGETS}' in refused(capsys, tmp_path,
                                                           ['sweep', '--budgets', many])
    sweep.write_text(json.dumps({'scenario': {'ground_nodes_m': [[0, 0]]},
                                 'budgets_w': [True]}))
    assert 'must be a list of numbers' in refused(capsys, tmp_path,
                                                  ['sweep', '--scenario', str(sweep)])


def test_a_scenario_file_with_more_nodes_than_the_limit_is_refused_before_it_is_built(
        tmp_path, capsys, monkeypatch):
    from uav_comm_planner.core import scenario as scenario_module

    def never(*args, **kwargs):
        raise AssertionError('the scenario was built before its node count was checked')
    scenario_file = tmp_path / 's.json'
    scenario_file.write_text(json.dumps({'ground_nodes_m': [[i, 0] for i in range(200_000)]}))
    monkeypatch.setattr(scenario_module.Scenario, '__post_init__', never)
    err = refused(capsys, tmp_path, ['plan', '--scenario', str(scenario_file)])
    assert 'too many ground nodes: 200000 given, the limit max_nodes is 100' in err


def test_the_scenario_file_is_read_once_per_command(tmp_path, capsys, monkeypatch):
    scenario_file = tmp_path / 's.json'
    scenario_file.write_text(json.dumps({
        'scenario': {'ground_nodes_m': [[0, 0]], 'num_slots': 5, 'horizon_s': 400.0},
        'settings': {'max_node_slots': 3}}))
    reads = []
    real = cli.read_scenario_file
    monkeypatch.setattr(cli, 'read_scenario_file',
                        lambda path: reads.append(path) or real(path))
    err = refused(capsys, tmp_path, ['plan', '--scenario', str(scenario_file)])
    assert 'compute budget' in err and len(reads) == 1


@pytest.mark.parametrize('which', ['/dev/zero', 'fifo'])
def test_upload_refuses_a_mission_that_is_not_a_regular_file_before_connecting(
        tmp_path, capsys, monkeypatch, which):
    from uav_comm_planner.vehicle.mavlink import upload

    def no_connection(*args, **kwargs):
        raise AssertionError('connected before the mission file was read')
    monkeypatch.setattr(upload, 'connect', no_connection)
    path = '/dev/zero' if which == '/dev/zero' else str(tmp_path / 'm.waypoints')
    if which == 'fifo':
        os.mkfifo(path)
    try:
        err = refused(capsys, tmp_path, ['upload', path, '--connect', 'tcp:127.0.0.1:9'])
    finally:
        if which == 'fifo':
            with contextlib.suppress(OSError):
                os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))
    assert 'not a regular file' in err or 'a .waypoints' in err


# The node's mission folder: opened once, written by descriptor.

def test_an_output_folder_keeps_writing_where_it_was_opened(tmp_path):
    from uav_comm_planner.files import OutputFolder

    folder = tmp_path / 'missions'
    folder.mkdir()
    elsewhere = tmp_path / 'elsewhere'
    elsewhere.mkdir()
    with OutputFolder(folder) as output:
        output.write_with('a.txt', lambda path: path.write_text('one'))
        os.chmod(folder / 'a.txt', 0o640)
        # The folder's path is replaced by a link to another folder after it was opened.
        folder.rename(tmp_path / 'moved')
        folder.symlink_to(elsewhere, target_is_directory=True)
        output.write_with('a.txt', lambda path: path.write_text('two'))
        assert (tmp_path / 'moved' / 'a.txt').read_text() == 'two'
        assert ((tmp_path / 'moved' / 'a.txt').stat().st_mode & 0o777) == 0o640
        assert list(elsewhere.iterdir()) == []
        assert sorted(p.name for p in (tmp_path / 'moved').iterdir()) == ['a.txt']


@pytest.mark.parametrize('name, make, error', [
    ('link.txt', lambda folder: (folder / 'link.txt').symlink_to(folder / 'target.txt'),
     'symbolic link'),
    ('sub', lambda folder: (folder / 'sub').mkdir(), 'it is a folder'),
    ('../up.txt', lambda folder: None, 'not a bare file name'),
    ('..', lambda folder: None, 'not a bare file name'),
])
def test_an_output_folder_never_follows_a_link_nor_leaves_its_folder(tmp_path, name, make,
                                                                     error):
    from uav_comm_planner.files import OutputFolder

    (tmp_path / 'target.txt').write_text('kept')
    make(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    with OutputFolder(tmp_path) as output, pytest.raises((OSError, ValueError), match=error):
        output.write_with(name, lambda path: path.write_text('new'))
    assert (tmp_path / 'target.txt').read_text() == 'kept'
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert not (tmp_path.parent / 'up.txt').exists()


def test_a_study_is_counted_before_its_grid_is_crossed_and_its_stored_design_read_safely(
        tmp_path):
    from uav_comm_planner.tools.study.design import MAX_ROWS, StudyDesign, StudyError
    from uav_comm_planner.tools.study.tables import saved_design

    with pytest.raises(InvalidScenarioError, match=f'cases must be at most {MAX_ROWS}'):
        StudyDesign(cases=10 ** 12)
    grid = ','.join(str(v) for v in range(1, 101))
    with pytest.raises(InvalidScenarioError, match='more than'):
        StudyDesign(cases=1000, draws={'slots': grid, 'nodes': '1:5',
                                       'power_budget_w': ','.join(f'{v}' for v in
                                                                  range(1, 201))})
    table = tmp_path / 'study.csv'
    table.write_text('index\n')
    os.mkfifo(tmp_path / 'study.csv.json')
    with pytest.raises(StudyError, match='it is a pipe'):
        promptly(lambda: saved_design(table))
