"""Atomic file replacement, and the one safe way the package reads a file.

Writing: a reader sees the old file or the new one, never half of one.

Only regular files are written: a path that is a folder, a device (such as ``/dev/null``), a
pipe, a socket or a symbolic link is refused before anything is written (an OSError saying
which: IsADirectoryError, NotARegularFileError, ...), since renaming over it would replace the
device or the link itself. A new file gets the mode ``0o666 & ~umask``, as ``open()`` would
give it; a replaced file keeps its mode. The temporary file is
``.<name>.partial-<pid>-<random><suffix>`` beside the target, so that one left by a killed
process is recognisable; writing a target removes the leftovers of that target whose process
is gone.

Reading (:func:`read_regular_file`, :func:`read_text_file`): only a regular file is read, opened
without blocking (a FIFO or a device never stalls the caller), checked again on the open
descriptor (a path swapped for a pipe between the check and the open is caught) and read up to
a size cap; every refusal is a typed error naming the file and the reason, raised before any
byte past the cap is read."""

from __future__ import annotations

import contextlib
import errno
import json
import os
from pathlib import Path
import secrets
import stat
import tempfile
from typing import Callable, Iterator


class NotARegularFileError(OSError):
    """The output path is a device, a pipe, a socket or a symbolic link, not a regular file."""


class InputFileError(OSError):
    """A file to read is not a regular file (a folder, device, pipe or socket), is larger than
    the reader's cap, cannot be opened or is not text; nothing past the check was read."""


#: Marks a temporary file: ``.<target name>.partial-<pid>-<random><suffix>``.
PARTIAL_MARK = '.partial-'


def _umask() -> int:
    """The process's umask, read without changing it where Linux allows (else set back)."""
    with contextlib.suppress(OSError, ValueError):
        with open('/proc/self/status', encoding='ascii') as status:
            for line in status:
                if line.startswith('Umask:'):
                    return int(line.split()[1], 8)
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _check_replaceable(info: os.stat_result | None, name: str) -> None:
    """Refuse a target that is not absent or a regular, writable file of this user."""
    if info is not None and stat.S_ISDIR(info.st_mode):
        raise IsADirectoryError(errno.EISDIR, 'it is a folder', name)
    if info is not None and not stat.S_ISREG(info.st_mode):
        kind = ('a symbolic link; give the path of the file it points to'
                if stat.S_ISLNK(info.st_mode) else 'a device, pipe or socket')
        raise NotARegularFileError(errno.EEXIST, f'not a regular file: it is {kind}', name)
    if info is not None and not info.st_mode & 0o222:
        raise PermissionError(errno.EACCES, 'the file is read-only; it is not replaced', name)
    if info is not None and info.st_uid != os.geteuid():
        raise PermissionError(errno.EPERM, 'the file belongs to another user; it is not '
                              'replaced', name)


def check_output_path(path: str | os.PathLike) -> Path:
    """Refuse an output path that cannot be replaced safely; return it as a Path.

    The folder must exist and be writable; the path must be absent or a regular file of this
    process's user with a write permission bit (even for root, a read-only or another user's
    file is not replaced). Raises FileNotFoundError when the folder does not exist,
    NotADirectoryError when it is a file, IsADirectoryError when ``path`` is a folder,
    :class:`NotARegularFileError` for a device, pipe, socket or symbolic link and
    PermissionError for a read-only or foreign file or a folder that cannot be written.
    """
    target = Path(path)
    folder = target.parent
    if not folder.is_dir():
        if folder.exists():
            raise NotADirectoryError(errno.ENOTDIR, 'it is not a folder', str(folder))
        raise FileNotFoundError(f'folder {str(folder)!r} does not exist')
    try:
        info = target.lstat()
    except FileNotFoundError:
        info = None
    _check_replaceable(info, str(target))
    if not os.access(folder, os.W_OK | os.X_OK):
        raise PermissionError(errno.EACCES, 'the folder is not writable', str(folder))
    return target


def _remove_stale_partials(target: Path) -> None:
    """Remove temporary files of ``target`` left behind by processes that no longer run."""
    prefix = f'.{target.name}{PARTIAL_MARK}'
    with contextlib.suppress(OSError):
        for entry in os.scandir(target.parent):
            if not entry.name.startswith(prefix):
                continue
            pid = entry.name[len(prefix):].split('-', 1)[0]
            if pid.isdigit() and not _running(int(pid)):
                with contextlib.suppress(OSError):
                    os.unlink(entry.path)


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, suffix: str = '') -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it replaces ``path`` atomically.

    Raises the OSError of :func:`check_output_path` before creating anything when ``path``
    cannot be replaced safely; on any failure the
    temporary file is removed and ``path`` is untouched.
    """
    target = check_output_path(path)
    folder = target.parent
    _remove_stale_partials(target)
    if target.is_file():
        mode = target.stat().st_mode & 0o7777
    else:
        mode = 0o666 & ~_umask()
    # mkstemp makes the file private (0600); the mode is set before the rename.
    handle, temporary = tempfile.mkstemp(dir=folder,
                                         prefix=f'.{target.name}{PARTIAL_MARK}{os.getpid()}-',
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


class OutputFolder:
    """A folder opened once, by descriptor, whose files are replaced by bare name only.

    The folder is opened when the object is made; every write after that is relative to the
    descriptor (``openat``, ``renameat``), so moving, replacing or linking the folder's path
    later cannot redirect a write. A target must be absent or a regular file (the same rules
    as :func:`check_output_path`; a link in its place is refused, never followed); the file is
    rendered in a private temporary folder, copied into ``.<name>.partial-<pid>-<random>``
    created with ``O_EXCL | O_NOFOLLOW`` beside the target, synced and renamed over it. Raises
    the OSError of :func:`check_output_path`, or NotADirectoryError / FileNotFoundError when
    the folder itself cannot be opened.
    """

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self._fd: int | None = os.open(self.path, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)

    def close(self) -> None:
        """Close the folder's descriptor; later writes raise OSError (EBADF)."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> OutputFolder:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    def _descriptor(self) -> int:
        if self._fd is None:
            raise OSError(errno.EBADF, 'the output folder is closed', str(self.path))
        return self._fd

    def check(self, name: str) -> None:
        """Refuse ``name`` when it is not a bare name or its file cannot be replaced."""
        if not name or '/' in name or '\0' in name or name in ('.', '..'):
            raise ValueError(f'{name!r} is not a bare file name')
        folder = self._descriptor()
        try:
            info = os.lstat(name, dir_fd=folder)
        except FileNotFoundError:
            info = None
        _check_replaceable(info, str(self.path / name))
        if not os.access('.', os.W_OK | os.X_OK, dir_fd=folder):
            raise PermissionError(errno.EACCES, 'the folder is not writable', str(self.path))

    def write_with(self, name: str, writer: Callable[[Path], None]) -> Path:
        """Let ``writer`` fill a file, then replace ``name`` in the folder with it atomically;
        returns the path shown for it (the folder's path as opened, and ``name``)."""
        self.check(name)
        folder = self._descriptor()
        self._remove_stale_partials(name)
        try:
            mode = os.lstat(name, dir_fd=folder).st_mode & 0o7777
        except FileNotFoundError:
            mode = 0o666 & ~_umask()
        with tempfile.TemporaryDirectory(prefix='uav-comm-planner-') as private:
            rendered = Path(private) / name
            writer(rendered)
            data = rendered.read_bytes()
        temporary = (f'.{name}{PARTIAL_MARK}{os.getpid()}-{secrets.token_hex(4)}'
                     f'{Path(name).suffix}')
        handle = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW
                         | os.O_CLOEXEC, 0o600, dir_fd=folder)
        try:
            with os.fdopen(handle, 'wb') as out:
                out.write(data)
                out.flush()
                os.fsync(out.fileno())
                os.fchmod(out.fileno(), mode)
            os.replace(temporary, name, src_dir_fd=folder, dst_dir_fd=folder)
        except BaseException:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(temporary, dir_fd=folder)
            raise
        return self.path / name

    def _remove_stale_partials(self, name: str) -> None:
        prefix = f'.{name}{PARTIAL_MARK}'
        folder = self._descriptor()
        with contextlib.suppress(OSError):
            for entry in os.scandir(folder):
                if not entry.name.startswith(prefix):
                    continue
                pid = entry.name[len(prefix):].split('-', 1)[0]
                if pid.isdigit() and not _running(int(pid)):
                    with contextlib.suppress(OSError):
                        os.unlink(entry.name, dir_fd=folder)


#: Flags of every read: no blocking on a FIFO or device, no controlling terminal, closed on exec.
_READ_FLAGS = (os.O_RDONLY | getattr(os, 'O_NONBLOCK', 0) | getattr(os, 'O_NOCTTY', 0)
               | getattr(os, 'O_CLOEXEC', 0))


def _kind_of(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return 'a folder'
    if stat.S_ISFIFO(mode):
        return 'a pipe (FIFO)'
    if stat.S_ISSOCK(mode):
        return 'a socket'
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return 'a device'
    return 'not a regular file'


def read_regular_file(path: str | os.PathLike, *, max_bytes: int, what: str = 'file',
                      error: type[Exception] = InputFileError) -> bytes:
    """The bytes of the regular file ``path``, at most ``max_bytes`` of them.

    A folder, device (``/dev/zero``), pipe or socket is refused from ``os.stat`` before it is
    opened; the file is opened with ``O_NONBLOCK`` and checked again with ``os.fstat`` (the same
    file, still regular, still within the cap), then read to at most ``max_bytes + 1`` bytes,
    so that a file growing while read is refused too. Raises ``error`` (by default
    :class:`InputFileError`; the callers pass their own typed error) whose message names
    ``what``, the path and the reason.
    """
    name = f'{what} {str(path)!r}'
    try:
        before = os.stat(path)
    except FileNotFoundError:
        raise error(f'cannot read {name}: there is no such {what}') from None
    except (OSError, ValueError) as exc:
        raise error(f'cannot read {name}: {getattr(exc, "strerror", None) or exc}') from None
    if not stat.S_ISREG(before.st_mode):
        raise error(f'cannot read {name}: it is {_kind_of(before.st_mode)}, not a regular file')
    if before.st_size > max_bytes:
        raise error(f'{name} is larger than {max_bytes} bytes ({before.st_size})')
    try:
        handle = os.open(path, _READ_FLAGS)
    except OSError as exc:
        raise error(f'cannot read {name}: {exc.strerror or exc}') from None
    try:
        opened = os.fstat(handle)
        if (not stat.S_ISREG(opened.st_mode)
                or (opened.st_dev, opened.st_ino) != (before.st_dev, before.st_ino)):
            raise error(f'cannot read {name}: it was replaced while it was opened')
        chunks = []
        left = max_bytes + 1
        while left > 0:
            chunk = os.read(handle, min(left, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
    except OSError as exc:
        raise error(f'cannot read {name}: {exc.strerror or exc}') from None
    finally:
        os.close(handle)
    data = b''.join(chunks)
    if len(data) > max_bytes:
        raise error(f'{name} is larger than {max_bytes} bytes')
    return data


def read_text_file(path: str | os.PathLike, *, max_bytes: int, what: str = 'file',
                   error: type[Exception] = InputFileError) -> str:
    """The UTF-8 text of the regular file ``path`` (:func:`read_regular_file`); a file that is
    not UTF-8 raises ``error`` with the byte where it stops being text."""
    raw = read_regular_file(path, max_bytes=max_bytes, what=what, error=error)
    try:
        return raw.decode('utf-8')
    except UnicodeDecodeError as exc:
        raise error(f'{what} {str(path)!r} is not UTF-8 text ({exc.reason} at byte '
                    f'{exc.start})') from None


def read_json_file(path: str | os.PathLike, *, max_bytes: int, what: str = 'file',
                   error: type[Exception] = InputFileError) -> object:
    """The JSON value in the UTF-8 regular file ``path`` (:func:`read_text_file`); a file that
    is not JSON, or nested too deeply to parse, raises ``error`` naming it."""
    text = read_text_file(path, max_bytes=max_bytes, what=what, error=error)
    try:
        return json.loads(text)
    except RecursionError:
        raise error(f'{what} {str(path)!r} is nested too deeply') from None
    except ValueError as exc:
        raise error(f'{what} {str(path)!r} is not valid JSON: {exc}') from None
