"""Checked atomic renames of folders (Linux ``renameat2``, with a plain fallback).

:func:`claim` moves a folder to a name that must not exist; :func:`swap` exchanges
two folders. Both fail with :class:`~photo3d.errors.OutputError` instead of ever
replacing a folder another process wrote meanwhile. Used by
:mod:`photo3d.files.staging`.
"""

from __future__ import annotations

import ctypes
import errno
import os
import secrets
from pathlib import Path

from photo3d.errors import OutputError

_RENAME_NOREPLACE, _RENAME_EXCHANGE, _AT_FDCWD = 1, 2, -100


def identity(path: Path) -> tuple | None:
    """``(device, inode)`` of ``path`` (not following a final link), or None if absent."""
    try:
        st = os.lstat(path)
    except (FileNotFoundError, NotADirectoryError):
        return None
    return st.st_dev, st.st_ino


def _renameat2(src: Path, dst: Path, flags: int) -> bool:
    """Linux ``renameat2``; False when the system or file system lacks it."""
    try:
        fn = ctypes.CDLL(None, use_errno=True).renameat2
    except (AttributeError, OSError):
        return False
    if fn(_AT_FDCWD, os.fsencode(src), _AT_FDCWD, os.fsencode(dst), flags) == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP):
        return False
    raise OSError(code, os.strerror(code), str(dst))


def claim(tmp: Path, final: Path, out: Path) -> None:
    """Rename ``tmp`` to ``final``, failing if ``final`` exists (atomic on Linux)."""
    try:
        if _renameat2(tmp, final, _RENAME_NOREPLACE):
            return
        if final.exists() or final.is_symlink():
            raise FileExistsError(errno.EEXIST, "exists", str(final))
        os.rename(tmp, final)  # fallback: only an empty folder could be replaced here
    except (FileExistsError, OSError) as err:
        if isinstance(err, FileExistsError) or err.errno in (errno.EEXIST, errno.ENOTEMPTY):
            raise OutputError(f"output {out} was written by another run meanwhile; "
                              "this run's result was discarded") from None
        raise


def swap(tmp: Path, final: Path, out: Path, *, expected: tuple | None) -> Path:
    """Put ``tmp`` in place of ``final`` (atomically on Linux); return where the old one is."""
    if _renameat2(tmp, final, _RENAME_EXCHANGE):
        if identity(tmp) != expected:  # someone replaced it between check and swap
            _renameat2(tmp, final, _RENAME_EXCHANGE)
            raise OutputError(f"output {out} changed while photo3d was working "
                              "(another run?); this run's result was discarded")
        return tmp
    old = final.with_name(f".{final.name[:64]}.{secrets.token_hex(4)}.old")
    os.rename(final, old)
    try:
        claim(tmp, final, out)
    except BaseException:
        os.rename(old, final)
        raise
    return old
