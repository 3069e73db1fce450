"""The gate every file photo3d writes passes: what a target may be, and the lock
that keeps a folder's record of photo3d's files whole.

Every write of photo3d goes through :mod:`photo3d.files` (``atomic`` for single
files, ``staging`` for folders; ``tests/files/test_write_gate.py`` scans the source
for any other). Before a temporary file is created, :func:`check_target` refuses
a target that

* is a symbolic link, to anything or to nothing (a link placed in a folder could
  point anywhere: photo3d never writes through one);
* exists and is not a regular file (a FIFO, a socket, a device: writing would
  block, or reach something else than a file);
* is one of the command's own inputs (:func:`reading`): the same path, a link to
  it or a hard link of it (the same device and inode).

Whether an existing file is photo3d's to replace is the caller's question, asked
before the work: a 3D photo folder's ``config.json`` record
(:mod:`photo3d.owned`), a training run's ``checkpoints.json``, a batch's manifest;
or the user's explicit ``--overwrite`` of a file named on the command line.
Everything else a command writes is new: a hidden temporary name of its own
(``.NAME.XXXXXXXX.tmp``, :func:`photo3d.files.temps.temp_sibling`) or a file
inside its own temporary folder (:func:`issue_folder`).

:func:`locked` serialises the read-modify-write of such a record between
processes (an ``flock`` on the folder itself, so no lock file is left behind).

Example:
    >>> import pathlib, tempfile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> photo = folder / "photo.png"; _ = photo.write_bytes(b"x")
    >>> with reading(photo):
    ...     check_target(folder / "out.png").name
    'out.png'
    >>> with reading(photo):
    ...     check_target(photo)
    Traceback (most recent call last):
    photo3d.errors.OutputError: ... is an input of this command; photo3d does not replace what it reads
"""  # noqa: E501

from __future__ import annotations

import contextlib
import fcntl
import os
import stat
import threading
from collections.abc import Iterator
from pathlib import Path

from photo3d.errors import OutputError

PathLike = str | os.PathLike[str]

_GUARD = threading.Lock()
_INPUTS: list[tuple[str, tuple[int, int] | None]] = []
"""The inputs of the running command: (real path, (device, inode) or None)."""
_FOLDERS: set[Path] = set()
"""Temporary folders this process created (:mod:`photo3d.files.staging`)."""


def _identity(path: PathLike) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return st.st_dev, st.st_ino


@contextlib.contextmanager
def reading(*paths: PathLike | None) -> Iterator[None]:
    """Declare ``paths`` the inputs of the work inside the block: no write may reach
    them, by their path, a symbolic link or a hard link (None entries are skipped).

    Example:
        >>> import pathlib, tempfile
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> (folder / "a.npz").write_bytes(b"x")
        1
        >>> (folder / "b.npz").hardlink_to(folder / "a.npz")
        >>> with reading(folder / "a.npz"):
        ...     is_input(folder / "b.npz")
        True
        >>> is_input(folder / "b.npz")
        False
    """
    entries = [(os.path.realpath(p), _identity(p)) for p in paths if p is not None]
    with _GUARD:
        _INPUTS.extend(entries)
    try:
        yield
    finally:
        with _GUARD:
            for entry in entries:
                _INPUTS.remove(entry)


def is_input(path: PathLike) -> bool:
    """True if ``path`` is an input declared by :func:`reading` (path, link or hard link).

    Example:
        >>> is_input("/nonexistent/file")
        False
    """
    real, ident = os.path.realpath(path), _identity(path)
    with _GUARD:
        return any(real == r or (ident is not None and ident == i) for r, i in _INPUTS)


def check_target(path: PathLike, *, follow_symlinks: bool = False, hint: str = "") -> Path:
    """Refuse a target photo3d must not write (see the module doc); returns the file
    that will be replaced: ``path``, or with ``follow_symlinks`` its link's target.

    Args:
        path: the file to write.
        follow_symlinks: False (default): a symbolic link is refused. True (for
            programs that ask for it): the link is followed and its target checked.
        hint: added to the link's message, in parentheses (what to do).

    Raises:
        OutputError: one line naming ``path``: a symbolic link, not a regular file,
            or an input of this command.

    Example:
        >>> import os, pathlib, tempfile
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> os.mkfifo(folder / "batch.jsonl")
        >>> check_target(folder / "batch.jsonl")
        Traceback (most recent call last):
        photo3d.errors.OutputError: ... exists and is not a regular file (a FIFO); photo3d replaces only files
        >>> (folder / "link").symlink_to("nowhere")
        >>> check_target(folder / "link")
        Traceback (most recent call last):
        photo3d.errors.OutputError: ... is a symbolic link; photo3d does not write through links
    """  # noqa: E501
    path = Path(path)
    final = path
    mode = _mode(path)
    if mode is not None and stat.S_ISLNK(mode):
        if not follow_symlinks:
            raise OutputError(f"{path} is a symbolic link; photo3d does not write through "
                              "links" + (f" ({hint})" if hint else ""))
        final = Path(os.path.realpath(path))
        mode = _mode(final)
    if mode is not None and not stat.S_ISREG(mode) and not stat.S_ISDIR(mode):
        raise OutputError(f"{path} exists and is not a regular file ({_kind(mode)}); "
                          "photo3d replaces only files")
    if is_input(final):
        raise OutputError(f"{path} is an input of this command; photo3d does not replace "
                          "what it reads")
    return final


def issue_folder(folder: PathLike) -> None:
    """Record a temporary folder this process created: files inside it are new."""
    with _GUARD:
        _FOLDERS.add(Path(os.path.abspath(folder)))


def release_folder(folder: PathLike) -> None:
    """Forget a temporary folder (committed or removed)."""
    with _GUARD:
        _FOLDERS.discard(Path(os.path.abspath(folder)))


def in_issued_folder(path: PathLike) -> bool:
    """True if ``path`` lies in a temporary folder this process created and is not
    a symbolic link (a new file the command writes directly).

    Example:
        >>> import pathlib, tempfile
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> issue_folder(folder); inside = in_issued_folder(folder / "a.png")
        >>> release_folder(folder); inside, in_issued_folder(folder / "a.png")
        (True, False)
    """
    path = Path(os.path.abspath(path))
    if path.is_symlink():
        return False
    with _GUARD:
        return any(folder in path.parents for folder in _FOLDERS)


@contextlib.contextmanager
def locked(folder: PathLike) -> Iterator[None]:
    """Hold an exclusive lock on ``folder`` (``flock`` on the folder itself) for the
    block: the read-modify-write of a record in it is whole even when several
    processes record at once. Nothing is created in the folder.

    Example:
        >>> import pathlib, tempfile
        >>> with locked(tempfile.mkdtemp()):
        ...     pass
    """
    try:
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    except OSError as err:
        raise OutputError(f"cannot lock {folder}: {err.strerror or err}") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


def try_lock(folder: PathLike) -> int | None:
    """An exclusive lock on ``folder`` that is held until :func:`unlock` (the file
    descriptor), or None when another process holds it.

    Example:
        >>> import tempfile
        >>> folder = tempfile.mkdtemp()
        >>> fd = try_lock(folder); other = try_lock(folder)
        >>> fd is not None, other is None
        (True, True)
        >>> unlock(fd)
    """
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return None
    return fd


def unlock(fd: int) -> None:
    """Release a lock from :func:`try_lock`."""
    os.close(fd)


def _mode(path: Path) -> int | None:
    """``lstat``'s mode of ``path``; None if it is absent or cannot be examined (the
    write itself then reports why)."""
    try:
        return os.lstat(path).st_mode
    except (OSError, ValueError):
        return None


def _kind(mode: int) -> str:
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return "not a file"
