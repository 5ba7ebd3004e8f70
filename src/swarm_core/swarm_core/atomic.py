"""Atomic file writes: a failed write (full disk, Ctrl-C) leaves no partial or 0-byte file."""
from __future__ import annotations

import os
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_open(path, mode: str = 'w'):
    """A file to write ``path`` through: a temporary file in the same directory, synced and
    renamed over ``path`` when the block ends, removed if it raises."""
    path = Path(path)
    tmp = path.with_name(f'.{path.name}.{os.getpid()}.tmp')
    try:
        with open(tmp, mode) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
