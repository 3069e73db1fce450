"""One batch per output folder at a time: the lock file ``OUT/batch.lock``.

:func:`batch_lock` takes an exclusive :func:`fcntl.flock` on the file for the
length of a batch and removes the file when it ends. The kernel drops the lock
when the holder dies, so a batch killed with SIGKILL blocks nothing: its file is
left, unlocked, and the next batch takes it over. (Removing the file while a
second batch is opening it could hand both a lock on different files; the taker
checks that the file it locked is still the one named ``batch.lock``.)
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

from photo3d.errors import OutputError

LOCK = "batch.lock"


@contextlib.contextmanager
def batch_lock(out: str | Path) -> Iterator[Path]:
    """Hold ``out/batch.lock`` for the block; yields its path.

    Raises:
        OutputError: another batch holds it, or it cannot be created (it is a
            symbolic link, the folder is read-only).

    Example:
        >>> import tempfile
        >>> out = Path(tempfile.mkdtemp())
        >>> with batch_lock(out):
        ...     try:
        ...         with batch_lock(out):
        ...             pass
        ...     except OutputError as err:
        ...         print(str(err).startswith("another photo3d batch is writing"))
        True
        >>> list(out.iterdir())
        []
    """
    import fcntl

    path = Path(out) / LOCK
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o666)
        except OSError as err:
            raise OutputError(f"cannot create the lock file {path}: {err.strerror or err}"
                              + (" (a symbolic link?)" if os.path.islink(path) else "")) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            raise OutputError(f"another photo3d batch is writing {out} (it holds {path}); "
                              "wait for it to finish or choose another output folder") from None
        try:
            same = os.path.samestat(os.fstat(fd), os.stat(path, follow_symlinks=False))
        except OSError:
            same = False
        if same:
            break
        os.close(fd)  # the holder removed it as we opened it: take the new one
    try:
        os.write(fd, f"{os.getpid()}\n".encode())
        yield path
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)  # while still locked, so nobody else holds this file
        os.close(fd)
