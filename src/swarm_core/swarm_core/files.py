"""Writing output files safely: a failed write (full disk, Ctrl-C) leaves no partial or 0-byte
file, and no write follows a symbolic link or replaces anything but a regular file.  Reading an
input file (`read_regular`) takes only a regular file of a bounded size.

Every writer of outputs goes through here: `atomic_open` (a file written whole),
`atomic_path` (the same for writers that need a file name: matplotlib, animations) and
`open_regular` (a file written as it grows: a bag).  Something planted where an output goes
(a symlink, a device, a FIFO, a directory) is refused with an OSError naming it; nothing is
written through it and it is not replaced.
"""
from __future__ import annotations

import errno
import os
import stat
import tempfile
from contextlib import contextmanager
from pathlib import Path

_UMASK = os.umask(0o022)
os.umask(_UMASK)

_KINDS = ((stat.S_ISLNK, 'a symbolic link'), (stat.S_ISDIR, 'a directory'), (stat.S_ISCHR, 'a device'),
          (stat.S_ISBLK, 'a device'), (stat.S_ISFIFO, 'a FIFO'), (stat.S_ISSOCK, 'a socket'))


def _refuse(mode: int, path):
    """Raise if ``mode`` (from lstat) is not a regular file's."""
    if not stat.S_ISREG(mode):
        kind = next((k for test, k in _KINDS if test(mode)), 'not a file')
        raise OSError(errno.EEXIST, f'{kind} is there, not a regular file: not written through '
                                    'or replaced', str(path))


def read_regular(path, max_bytes: int) -> bytes:
    """The bytes of the regular file ``path`` (a symbolic link is followed to one), read only if
    it holds at most ``max_bytes``: an input (a scenario, a study, a robot description) is never
    read whole before its size is known.  OSError naming what is there instead (a directory, a
    FIFO, a device such as /dev/zero: opened without blocking, never read or waited on);
    ValueError for a larger file, its text the size found (``3000000 bytes``)."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind = next((k for test, k in _KINDS if test(st.st_mode)), 'not a file')
            raise OSError(errno.EINVAL, f'{kind}, not a regular file', str(path))
        if st.st_size > max_bytes:
            raise ValueError(f'{st.st_size} bytes')
        os.set_blocking(fd, True)
        chunks, size = [], 0
        while size <= max_bytes:                   # (a file may grow while it is read)
            chunk = os.read(fd, max_bytes + 1 - size)
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    finally:
        os.close(fd)
    if size > max_bytes:
        raise ValueError(f'more than {max_bytes} bytes')
    return b''.join(chunks)


def check_replaceable(path):
    """Raise OSError unless ``path`` is absent or a regular file (not a symlink to one)."""
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    _refuse(mode, path)


@contextmanager
def atomic_path(path, suffix: str = '.tmp'):
    """A new temporary file's name in ``path``'s directory (created empty, never an existing
    file or link; ending in ``suffix``, for writers that pick the format by it), for a writer
    that needs a name; synced and renamed over ``path`` when the block ends, removed if it
    raises.  ``path`` must be absent or a regular file."""
    path = Path(path)
    check_replaceable(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f'.{path.name}.', suffix=suffix)
    try:
        os.fchmod(fd, 0o666 & ~_UMASK)
        os.close(fd)
        yield Path(tmp)
        fd = os.open(tmp, os.O_RDONLY | os.O_NOFOLLOW)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        check_replaceable(path)           # (again: the block may have taken a while)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


@contextmanager
def atomic_open(path, mode: str = 'w'):
    """A file to write ``path`` through (`atomic_path`): a temporary file in the same
    directory, synced and renamed over ``path`` when the block ends, removed if it raises."""
    with atomic_path(path) as tmp, open(tmp, mode) as fh:
        yield fh


def write_atomic(path, text: str):
    """Write ``text`` to ``path`` through a temporary file and a rename (no half-written file)."""
    with atomic_open(path) as fh:
        fh.write(text)


def open_regular(path, mode: str = 'wb'):
    """``path`` opened to be written in place (a file that must be readable while it grows, as
    a bag is), created or truncated: never through a symlink, never a device, FIFO or
    directory.  ``mode``: 'wb' or 'ab' ('a' and 'w' for text)."""
    check_replaceable(path)
    flags = os.O_WRONLY | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK     # (a FIFO must not block)
    flags |= os.O_APPEND if mode.startswith('a') else os.O_TRUNC
    fd = os.open(path, flags, 0o666)
    try:
        _refuse(os.fstat(fd).st_mode, path)
        os.set_blocking(fd, True)
        return os.fdopen(fd, mode)
    except BaseException:
        os.close(fd)
        raise
