"""Atomic replacement of output files."""

import os

import pytest

from uav_comm_planner.files import write_text_atomic, write_with


def test_new_file_is_readable_by_others_and_a_replaced_file_keeps_its_mode(tmp_path):
    target = tmp_path / 'plan.json'
    write_text_atomic(target, 'first')
    assert target.stat().st_mode & 0o777 == 0o644
    os.chmod(target, 0o600)
    write_text_atomic(target, 'second')
    assert target.read_text() == 'second'
    assert target.stat().st_mode & 0o777 == 0o600


def test_a_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path):
    target = tmp_path / 'plan.json'
    write_text_atomic(target, 'good')

    def half_then_fail(temporary):
        temporary.write_text('hal')
        raise RuntimeError('disk full')

    with pytest.raises(RuntimeError, match='disk full'):
        write_with(target, half_then_fail)
    assert target.read_text() == 'good'
    assert sorted(p.name for p in tmp_path.iterdir()) == ['plan.json']


def test_missing_folder_is_a_clear_error(tmp_path):
    with pytest.raises(FileNotFoundError, match='does not exist'):
        write_text_atomic(tmp_path / 'no' / 'plan.json', 'x')


def test_a_folder_in_the_way_is_a_clear_error_and_nothing_is_written(tmp_path):
    (tmp_path / 'plan.json').mkdir()
    with pytest.raises(IsADirectoryError, match='it is a folder'):
        write_text_atomic(tmp_path / 'plan.json', 'x')
    (tmp_path / 'file').write_text('x')
    with pytest.raises(NotADirectoryError, match='is not a folder'):
        write_text_atomic(tmp_path / 'file' / 'plan.json', 'x')
    assert sorted(p.name for p in tmp_path.iterdir()) == ['file', 'plan.json']
