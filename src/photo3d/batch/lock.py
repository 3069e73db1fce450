"""One batch per output folder at a time: the lock file ``OUT/batch.lock``.

:func:`batch_lock` takes an exclusive :func:`fcntl.flock` on the file for the
length of a batch and removes the file when it ends. The kernel drops the lock
when the holder dies, so a batch killed with SIGKILL blocks nobody: its file is
left, unlocked, and the next batch takes it over. (Removing the file while a
second batch is opening it could hand both a lock on different files; the taker
checks that the file it locked is still the one named ``batch.lock``.)

The file is photo3d's only if it holds what a batch writes there
(:func:`is_lock_text`: ``photo3d batch PID``; a bare PID, which older batches
wrote, is refused too, since a user's file may hold one): it is
created with that content in one step (written to a hidden temporary file, locked,
then linked to its name), so a batch never leaves it empty. A ``batch.lock`` that
holds anything else was not written by photo3d: it is refused in one line, never
taken over or removed.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
from collections.abc import Iterator
from pathlib import Path

from photo3d.errors import OutputError
from photo3d.files.temps import remove_temp_files, temp_sibling

LOCK = "batch.lock"
_TEXT = re.compile(rb"photo3d batch [0-9]{1,12}\n")
_MAX_TEXT = 64  # a lock photo3d wrote holds one short line


def lock_text() -> bytes:
    """What a batch writes into its lock file: ``photo3d batch PID`` and a newline.

    Example:
        >>> is_lock_text(lock_text())
        True
    """
    return f"photo3d batch {os.getpid()}\n".encode()


def is_lock_text(data: bytes) -> bool:
    """True if ``data`` is what a batch writes into its lock file. A bare number (what
    older batches wrote) is not enough: a user's file may hold one.

    Example:
        >>> [is_lock_text(t) for t in (b"photo3d batch 12\\n", b"12\\n", b"", b"my notes\\n")]
        [True, False, False, False]
    """
    return _TEXT.fullmatch(data) is not None


@contextlib.contextmanager
def batch_lock(out: str | Path) -> Iterator[Path]:
    """Hold ``out/batch.lock`` for the block; yields its path.

    Raises:
        OutputError: another batch holds it; it exists and photo3d did not write it;
            or it cannot be created (it is a symbolic link, the folder is read-only,
            the disk is full). One line; nothing is left behind.

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
        >>> _ = (out / LOCK).write_text("my notes")
        >>> try:
        ...     with batch_lock(out):
        ...         pass
        ... except OutputError as err:
        ...     print(str(err).endswith("photo3d did not write it: move it away or choose "
        ...                             "another output folder (nothing was written)"))
        True
    """
    path = Path(out) / LOCK
    fd = _take(path)
    try:
        remove_temp_files(path)  # what a batch killed while creating its lock left
        yield path
    finally:
        try:
            if os.path.samestat(os.fstat(fd), os.stat(path, follow_symlinks=False)):
                os.unlink(path)  # while still locked, so nobody else holds this file
        except OSError:
            pass  # gone, or replaced by something that is not this lock: left alone
        os.close(fd)


def _take(path: Path) -> int:
    """A descriptor of ``path``, locked; the file existed as photo3d's or is created."""
    for _ in range(100):
        try:
            fd = os.open(path, os.O_RDWR | os.O_NOFOLLOW | os.O_CLOEXEC)
        except FileNotFoundError:
            fd = _create(path)
            if fd is None:  # another batch created it meanwhile: look at that one
                continue
            return fd
        except OSError as err:
            raise _cannot(path, err) from None
        try:
            _check_ours(path, fd)
            _flock(path, fd)
            same = os.path.samestat(os.fstat(fd), os.stat(path, follow_symlinks=False))
        except FileNotFoundError:
            same = False
        except BaseException:
            os.close(fd)
            raise
        if same:
            return fd
        os.close(fd)  # the holder removed it as we opened it: take the new one
    raise OutputError(f"cannot take the lock file {path}: it keeps changing")


def _create(path: Path) -> int | None:
    """Create ``path`` holding :func:`lock_text`, already locked; None if it appeared
    meanwhile."""
    tmp = temp_sibling(path)
    try:
        fd = os.open(tmp, os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC,
                     0o666)
    except OSError as err:
        raise _cannot(path, err) from None
    try:
        try:
            text = lock_text()
            if os.write(fd, text) != len(text):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            _flock(path, fd)  # nobody else can hold a file nobody else sees
            os.link(tmp, path)
        except (FileExistsError, FileNotFoundError):  # it appeared, or a batch that had
            os.close(fd)  # just taken it removed our temporary file: look again
            return None
        except OSError as err:
            os.close(fd)
            if err.errno not in _NO_LINKS:
                raise _cannot(path, err) from None
            return _create_in_place(path)  # a file system without hard links
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
    return fd


_NO_LINKS = (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.ENOSYS)
"""What ``link`` fails with on a file system that has no hard links (FAT, some network
file systems)."""


def _create_in_place(path: Path) -> int | None:
    """:func:`_create` without a hard link: create ``path`` itself, lock it, write it
    (a batch killed between the two leaves it empty: refused by the next one, which
    says so); None if it appeared meanwhile."""
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC,
                     0o666)
    except FileExistsError:
        return None
    except OSError as err:
        raise _cannot(path, err) from None
    try:
        _flock(path, fd)
        text = lock_text()
        if os.write(fd, text) != len(text):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    except BaseException as err:
        with contextlib.suppress(OSError):
            os.unlink(path)  # this call's own, empty or partial file
        os.close(fd)
        if isinstance(err, OSError):
            raise _cannot(path, err) from None
        raise
    return fd


def _check_ours(path: Path, fd: int) -> None:
    """Refuse a lock file that does not hold what a batch writes there."""
    try:
        data = os.pread(fd, _MAX_TEXT + 1, 0)
    except OSError as err:
        raise _cannot(path, err) from None
    if not is_lock_text(data):
        raise OutputError(f"{path} exists and photo3d did not write it: move it away or "
                          "choose another output folder (nothing was written)")


def _flock(path: Path, fd: int) -> None:
    import fcntl

    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        raise OutputError(f"another photo3d batch is writing {path.parent} (it holds {path}); "
                          "wait for it to finish or choose another output folder") from None


def _cannot(path: Path, err: OSError) -> OutputError:
    link = " (a symbolic link?)" if os.path.islink(path) else ""
    return OutputError(f"cannot create the lock file {path}: {err.strerror or err}{link}")
