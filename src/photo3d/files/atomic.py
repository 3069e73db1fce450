"""The one way photo3d writes a single file: into a hidden temporary sibling, then
renamed over the target in one step.

A reader never sees a half-written file, an interrupted or failed write leaves the
old file (or nothing) in place, and the temporary file is removed on any error,
Ctrl-C or termination signal (run the work inside
:func:`photo3d.files.signals.handle_signals` so SIGTERM unwinds too). Folders of
several files are written with :mod:`photo3d.files.staging` instead.

Example:
    >>> import pathlib, tempfile
    >>> target = pathlib.Path(tempfile.mkdtemp()) / "notes.json"
    >>> with atomic_write(target, "w") as f:
    ...     _ = f.write('{"a": 1}')
    >>> target.read_text(), [p.name for p in target.parent.iterdir()]
    ('{"a": 1}', ['notes.json'])
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from photo3d.errors import OutputError

PathLike = str | os.PathLike[str]


def temp_sibling(path: PathLike) -> Path:
    """A free hidden name beside ``path``: ``.NAME.XXXXXXXX.tmp`` (eight hex digits).

    Example:
        >>> temp_sibling("out/a.png").name.startswith(".a.png.")
        True
    """
    path = Path(path)
    return path.with_name(f".{path.name[:64]}.{secrets.token_hex(4)}.tmp")


@contextlib.contextmanager
def atomic_write(path: PathLike, mode: str = "wb") -> Iterator[IO]:
    """Open a temporary sibling of ``path`` for writing; rename it over ``path`` when
    the block ends without an error, remove it otherwise.

    Args:
        path: the file to write (its folder must exist).
        mode: ``"wb"`` or ``"w"`` (text, UTF-8).

    Raises:
        OutputError: the file cannot be written (permissions, full disk, a folder
            in the way); nothing is left behind.
    """
    if mode not in ("wb", "w"):
        raise ValueError(f"mode must be 'wb' or 'w', got {mode!r}")
    path = Path(path)
    tmp = temp_sibling(path)
    try:
        with open(tmp, "x" + mode[1:], **({} if "b" in mode else {"encoding": "utf-8"})) as f:
            yield f
        os.replace(tmp, path)
    except OSError as err:
        raise OutputError(f"cannot write {path}: {err.strerror or err}") from None
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)


def write_bytes(path: PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_write`); returns the path.

    Example:
        >>> import pathlib, tempfile
        >>> write_bytes(pathlib.Path(tempfile.mkdtemp()) / "a.bin", b"xy").read_bytes()
        b'xy'
    """
    with atomic_write(path, "wb") as f:
        f.write(data)
    return Path(path)


def write_text(path: PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; returns the path.

    Example:
        >>> import pathlib, tempfile
        >>> write_text(pathlib.Path(tempfile.mkdtemp()) / "a.txt", "hi").read_text()
        'hi'
    """
    with atomic_write(path, "w") as f:
        f.write(text)
    return Path(path)
