"""Atomic file replacement: a reader sees the old file or the new one, never half of one."""

from __future__ import annotations

import contextlib
import errno
import os
from pathlib import Path
import tempfile
from typing import Callable, Iterator


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, suffix: str = '') -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it replaces ``path`` atomically.

    Raises FileNotFoundError when the folder does not exist, NotADirectoryError when it is a
    file, IsADirectoryError when ``path`` is a folder and PermissionError when the folder
    cannot be written; on any failure the temporary file is removed and ``path`` is untouched.
    """
    target = Path(path)
    folder = target.parent
    if not folder.is_dir():
        if folder.exists():
            raise NotADirectoryError(errno.ENOTDIR, 'it is not a folder', str(folder))
        raise FileNotFoundError(f'folder {str(folder)!r} does not exist')
    if target.is_dir():
        raise IsADirectoryError(errno.EISDIR, 'it is a folder', str(target))
    # mkstemp makes the file private (0600); a replaced file keeps its mode, a new one is 0644.
    mode = target.stat().st_mode & 0o777 if target.is_file() else 0o644
    handle, temporary = tempfile.mkstemp(dir=folder, prefix=f'.{target.name}.',
                                         suffix=suffix or target.suffix)
    os.close(handle)
    try:
        yield Path(temporary)
        with open(temporary, 'rb') as written:
            os.fsync(written.fileno())
        os.chmod(temporary, mode)
        os.replace(temporary, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)
        raise


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Replace ``path`` with ``text`` atomically; return the path written."""
    with atomic_path(path) as temporary:
        temporary.write_text(text, encoding='utf-8')
    return Path(path)


def write_with(path: str | os.PathLike, writer: Callable[[Path], None]) -> Path:
    """Let ``writer`` fill a temporary file, then move it over ``path`` atomically."""
    with atomic_path(path) as temporary:
        writer(temporary)
    return Path(path)
