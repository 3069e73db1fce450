"""Temporary names, and what killed writers leave behind.

Every photo3d writer works under a hidden temporary name beside its target,
``.NAME.XXXXXXXX.tmp`` (:func:`temp_sibling`; :mod:`photo3d.files.atomic` for files,
:mod:`photo3d.files.staging` for folders), and holds it locked with ``flock`` while it
writes (:func:`hold`). The kernel drops the lock when the writer dies, even killed
with SIGKILL, so a later command tells a killed writer's leftover (:func:`orphaned`)
from a live writer's and removes only the former: a file's (:func:`remove_orphan_files`,
before every atomic write), a staged folder's (:func:`remove_orphans`, before every
staged one), or any left in a folder a command writes into (:func:`remove_orphans_in`).
:data:`LIVE` lists this process's temporary files, which are removed at exit as a
last resort.

Example:
    >>> is_temp_of(".a.png.0123abcd.tmp", "a.png"), is_temp_name("a.png")
    (True, False)
"""

from __future__ import annotations

import atexit
import contextlib
import os
import re
import secrets
import shutil
import time
from pathlib import Path

PathLike = str | os.PathLike[str]

LIVE: set[Path] = set()
"""Temporary files not yet committed or discarded (removed at exit as a last resort)."""

_HEX = frozenset("0123456789abcdef")
_HELD: dict[Path, int] = {}
"""The open descriptor holding each live temporary file's or folder's lock."""
ORPHAN_AGE_S = 5.0
"""A temporary file or folder unlocked this long after it was made is an orphan (its
writer locks it a moment after creating it)."""


def temp_sibling(path: PathLike) -> Path:
    """A free hidden name beside ``path``: ``.NAME.XXXXXXXX.tmp`` (eight hex digits).

    ``NAME`` is cut to 64 characters, so the temporary name is never too long for
    the file system when the target's name is not.

    Example:
        >>> temp_sibling("out/a.png").name.startswith(".a.png.")
        True
    """
    path = Path(path)
    return path.with_name(f".{path.name[:64]}.{secrets.token_hex(4)}.tmp")


def temp_entries(path: PathLike, *, suffixed: bool = True) -> list[Path]:
    """What lies beside ``path`` (symbolic links resolved) under one of its temporary
    names (:func:`is_temp_of`); ``[]`` if its folder cannot be listed.

    Example:
        >>> import pathlib, tempfile
        >>> target = pathlib.Path(tempfile.mkdtemp()) / "a.png"
        >>> temp_entries(target)
        []
    """
    final = Path(os.path.realpath(path))
    try:
        entries = list(final.parent.iterdir())
    except OSError:
        return []
    return [e for e in entries if is_temp_of(e.name, final.name, suffixed=suffixed)]


def is_temp_name(name: str) -> bool:
    """True if ``name`` is a temporary name photo3d gives to a writer of any target:
    ``.TARGET.XXXXXXXX.tmp``, with at most one suffix after it (:func:`is_temp_of`).

    Example:
        >>> [is_temp_name(n) for n in (".a.png.0123abcd.tmp.png", ".out.0123abcd.tmp", "a.tmp")]
        [True, True, False]
    """
    return _TEMP_NAME.fullmatch(name) is not None


_TEMP_NAME = re.compile(r"\..+\.[0-9a-f]{8}\.tmp(?:\.[^.]+)?")


def is_temp_of(name: str, target: str, *, suffixed: bool = True) -> bool:
    """True if ``name`` is a temporary name photo3d gives to a writer of ``target``.

    That is :func:`temp_sibling`'s ``.TARGET.XXXXXXXX.tmp``, followed, when
    ``suffixed``, by at most one suffix (``.png``, ``.part``: :func:`atomic_path`).

    Example:
        >>> [is_temp_of(n, "a.png") for n in (".a.png.0123abcd.tmp", ".a.png.0123abcd.tmp.png",
        ...                                   ".a.png.xyz.tmp", "a.png")]
        [True, True, False, False]
        >>> is_temp_of(".out.0123abcd.tmp.png", "out", suffixed=False)
        False
    """
    head = f".{target[:64]}."
    if not name.startswith(head):
        return False
    middle, dot, tail = name[len(head):].partition(".")
    if len(middle) != 8 or not _HEX.issuperset(middle) or not dot:
        return False
    if tail == "tmp":
        return True
    return suffixed and tail.startswith("tmp.") and "." not in tail[4:] and len(tail) > 4


def remove_temp_files(path: PathLike) -> list[Path]:
    """Remove the temporary files a killed writer of ``path`` left beside it.

    Only files named as this module names them (:func:`is_temp_of`) are removed;
    call this only when no other process is writing ``path``. Returns what was
    removed.

    Example:
        >>> import pathlib, tempfile
        >>> target = pathlib.Path(tempfile.mkdtemp()) / "a.png"
        >>> left = temp_sibling(target); left.touch()  # its writer was killed
        >>> [p == left for p in remove_temp_files(target)], left.exists()
        ([True], False)
    """
    removed = []
    for entry in temp_entries(path):
        if entry.is_file() and not entry.is_symlink():
            with contextlib.suppress(FileNotFoundError):
                entry.unlink()
            LIVE.discard(entry)
            removed.append(entry)
    return removed


WRITER_MARK = ".photo3d-writer"
"""The file inside a temporary folder that its writer holds locked (:func:`hold`);
removed before the folder is moved into place."""


def hold(path: Path) -> None:
    """Lock the temporary file ``path``, or a :data:`WRITER_MARK` file inside the
    temporary folder ``path`` (not the folder itself, which the write gate locks to
    record), with ``flock`` for as long as this process writes it: the kernel drops
    the lock when the process ends, even killed with SIGKILL, which is how a later
    run tells an orphan (:func:`orphaned`).

    Example:
        >>> import pathlib, tempfile
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> hold(folder); orphaned(folder, age=0.0)
        False
        >>> release(folder, keep=True); orphaned(folder, age=0.0)
        True
    """
    try:
        import fcntl
    except ImportError:  # no flock (Windows): orphans are not recognised
        return
    path = Path(path)
    folder = path.is_dir() and not path.is_symlink()
    # a folder's mark is locked under another name, then renamed to its own: it is
    # never seen unlocked while its writer lives (orphaned(age=0) can trust the lock)
    target = path / f"{WRITER_MARK}.{secrets.token_hex(4)}" if folder else path
    try:
        if folder:
            fd = os.open(target, os.O_RDWR | os.O_CREAT | os.O_EXCL
                         | getattr(os, "O_NOFOLLOW", 0), 0o600)
        else:
            fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    except OSError:
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        if folder:
            os.rename(target, path / WRITER_MARK)
    except OSError:
        if folder:
            with contextlib.suppress(OSError):
                os.unlink(target)
        os.close(fd)
        return
    _HELD[path] = fd


def release(path: Path, *, keep: bool = False) -> None:
    """Drop :func:`hold`'s lock of ``path`` (committed or discarded); a folder's
    :data:`WRITER_MARK` is removed first, unless ``keep`` (tests)."""
    fd = _HELD.pop(Path(path), None)
    if fd is None:
        return
    if not keep:
        with contextlib.suppress(OSError):
            os.unlink(Path(path) / WRITER_MARK)  # a file's: no such entry
    os.close(fd)


def orphaned(path: Path, *, age: float | None = None) -> bool:
    """True if the temporary file or folder ``path`` (not a link) was made more than
    ``age`` seconds ago (default :data:`ORPHAN_AGE_S`; a file that holds bytes, at
    any age: its writer locked it before writing) and no process holds it
    (:func:`hold`; a folder without its :data:`WRITER_MARK` is being moved into
    place, or is not photo3d's: never an orphan): its writer is gone."""
    try:
        import fcntl
    except ImportError:
        return False
    path = Path(path)
    nofollow = getattr(os, "O_NOFOLLOW", 0)
    try:
        if path.is_symlink():
            return False
        target = path / WRITER_MARK if path.is_dir() else path
        fd = os.open(target, os.O_RDONLY | nofollow)
    except OSError:  # gone, no mark
        return False
    try:
        st = os.fstat(fd)
        young = time.time() - st.st_ctime < (ORPHAN_AGE_S if age is None else age)
        if young and (target != path or st.st_size == 0):  # a writer locks a file
            return False  # before its first byte: one with bytes is not being created
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # free: its writer is gone
        return True
    except OSError:  # held: its writer is alive
        return False
    finally:
        os.close(fd)


def remove_orphan_files(path: PathLike) -> list[Path]:
    """Remove the temporary files of ``path`` (:func:`is_temp_of`) whose writer is
    gone (:func:`orphaned`); safe while other processes write ``path``. Every
    atomic write does this first. Returns what was removed.

    Example:
        >>> import pathlib, tempfile
        >>> target = pathlib.Path(tempfile.mkdtemp()) / "a.png"
        >>> remove_orphan_files(target)
        []
    """
    removed = []
    for entry in temp_entries(path):
        if entry.is_file() and entry not in LIVE and orphaned(entry):
            with contextlib.suppress(FileNotFoundError):
                entry.unlink()
            removed.append(entry)
    return removed


def remove_orphans(out: PathLike, *, age: float | None = None) -> list[Path]:
    """Remove the temporary folders of ``out`` whose writer is gone: named as
    :func:`~photo3d.files.staging.stage_output` names them, made more than ``age``
    seconds ago (default :data:`~photo3d.files.temps.ORPHAN_AGE_S`; ``0``: any, for a
    caller that knows the writers it started are dead) and
    locked by no process (a live writer holds its folder's lock; the kernel drops it
    when the writer dies, even of SIGKILL). Safe while other processes write ``out``.
    Returns what was removed.

    Example:
        >>> import pathlib, tempfile
        >>> from photo3d.files.staging import stage_output
        >>> out = pathlib.Path(tempfile.mkdtemp()) / "result"
        >>> staging = stage_output(out)  # alive: this process holds its lock
        >>> remove_orphans(out), staging.path.exists()
        ([], True)
        >>> staging.discard()
    """
    removed = []
    for tmp in temp_entries(out, suffixed=False):
        if tmp.is_dir() and not tmp.is_symlink() and orphaned(tmp, age=age):
            shutil.rmtree(tmp, ignore_errors=True)
            removed.append(tmp)
    return removed


def remove_orphans_in(folder: PathLike) -> list[Path]:
    """Remove the temporary files and folders of any name (:func:`is_temp_name`) in
    ``folder`` and in its subfolders (not links) whose writer is gone
    (:func:`~photo3d.files.temps.orphaned`): what a killed command left in a folder
    it wrote into. Safe while other processes write there. Returns what was removed.

    Example:
        >>> import pathlib, tempfile
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> _ = (folder / ".splats.ply.0123abcd.tmp.ply").write_bytes(b"ply")  # nobody holds it
        >>> [p.name for p in remove_orphans_in(folder)], list(folder.iterdir())
        (['.splats.ply.0123abcd.tmp.ply'], [])
    """
    removed, unsure = [], []
    try:
        entries = sorted(Path(folder).iterdir())
    except OSError:
        return removed
    for entry in entries:
        if entry.is_symlink():
            continue
        if is_temp_name(entry.name) and orphaned(entry):
            _remove(entry)
            removed.append(entry)
        elif is_temp_name(entry.name) and orphaned(entry, age=0):
            unsure.append(entry)  # unlocked but young and empty: made a moment ago?
        elif entry.is_dir() and not is_temp_name(entry.name):  # a live writer's: its own
            removed += _orphan_files(entry)
    if unsure:  # a writer locks its file a moment after making it: wait that out once
        made = []
        for entry in unsure:
            with contextlib.suppress(OSError):
                made.append(entry.stat().st_ctime)
        time.sleep(min(ORPHAN_AGE_S, max(0.0, ORPHAN_AGE_S - time.time() + max(made, default=0))))
        for entry in unsure:
            if orphaned(entry):
                _remove(entry)
                removed.append(entry)
    return removed


def _remove(entry: Path) -> None:
    """Remove the temporary file or folder ``entry`` (gone already: nothing)."""
    if entry.is_dir():
        shutil.rmtree(entry, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            entry.unlink()


def _orphan_files(folder: Path) -> list[Path]:
    """:func:`remove_orphans_in` one level down (files only)."""
    removed = []
    with contextlib.suppress(OSError):
        for entry in sorted(folder.iterdir()):
            if is_temp_name(entry.name) and entry.is_file() and not entry.is_symlink() \
                    and orphaned(entry):
                with contextlib.suppress(FileNotFoundError):
                    entry.unlink()
                removed.append(entry)
    return removed


@atexit.register
def _remove_live() -> None:
    for tmp in list(LIVE):
        with contextlib.suppress(OSError):
            os.unlink(tmp)
