"""The one way photo3d writes a single file: into a hidden temporary sibling, then
renamed over the target in one step.

A reader never sees a half-written file, an interrupted or failed write leaves the
old file (or nothing) in place, and the temporary file is removed on any error,
Ctrl-C or termination signal (run the work inside
:func:`photo3d.files.signals.handle_signals` so SIGTERM unwinds too; the ones still
there when the interpreter exits are removed then). The location is checked when
the temporary file is created, before the data is produced. Folders of several
files are written with :mod:`photo3d.files.staging` instead.

* :func:`atomic_write` opens the temporary file (``.NAME.XXXXXXXX.tmp``) for code
  that writes to a file object; :func:`write_bytes`, :func:`write_text` and
  :func:`write_json` write one value.
* :func:`atomic_path` yields the temporary path for a library that takes a path
  (Pillow, numpy, PyAV, safetensors). Its name keeps the target's suffix
  (``.NAME.XXXXXXXX.tmp.png``) for libraries that pick the format from it.
* :class:`PendingFile` is the same for a writer that outlives one ``with`` block
  (:class:`~photo3d.io.video.VideoWriter`): :meth:`~PendingFile.commit` or
  :meth:`~PendingFile.discard` it.
* :func:`check_writable` checks a target early. What a killed writer left is
  recognised and removed by :mod:`photo3d.files.temps`.

Every target first passes the gate (:func:`photo3d.files.gate.check_target`): a
symbolic link (to anything or to nothing), a FIFO, socket or device, or one of the
command's inputs is refused, so a link placed in an output folder can never make
photo3d write outside it; the commit renames over the name itself, so a link that
appears meanwhile is replaced, never written through. ``follow_symlinks=True``
follows a link instead, for programs that ask for it.

* :func:`writing` and :func:`open_write` are what the format writers
  (:mod:`photo3d.io`) write through: a temporary file this module handed out, or a
  new file in a temporary folder of :mod:`photo3d.files.staging`, is written as it
  is; any other path gets the whole atomic write above.

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
import errno
import json
import os
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

from photo3d.errors import OutputError
from photo3d.files.gate import check_target, in_issued_folder
from photo3d.files.stop import check, deferred
from photo3d.files.temps import LIVE, hold, release, remove_orphan_files, temp_sibling

PathLike = str | os.PathLike[str]

class Pending:
    """A temporary result that is discarded unless committed: leaving its ``with``
    block without :meth:`commit` (an error, Ctrl-C) calls :meth:`discard`.

    Subclasses set ``self._done = False`` and implement ``commit`` and ``discard``
    (which sets ``_done``); :class:`PendingFile` and
    :class:`photo3d.files.staging.Staging` are the two.

    Example:
        >>> class Demo(Pending):
        ...     _done = False
        ...     def discard(self): print("discarded"); self._done = True
        >>> with Demo():
        ...     pass
        discarded
    """

    _done: bool

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        if not self._done:
            self.discard()

    def discard(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError


class PendingFile(Pending):
    """A hidden temporary sibling of ``path`` that replaces it on :meth:`commit`.

    Creating one checks the target (not a folder, its folder exists, the name fits
    the file system) and creates the temporary file, empty, so that a location
    that cannot be written is refused before the data is produced. Write to
    ``pending.path`` (any library that takes a path), then :meth:`commit`; on any
    error :meth:`discard`. As a context manager, leaving the block without a
    commit discards it.

    Args:
        path: the file to write; an existing file is replaced.
        suffix: appended to the temporary name ``.NAME.XXXXXXXX.tmp`` (default
            none), e.g. the target's own suffix for a library that infers the
            format from it.
        follow_symlinks: False (default): a target that is a symbolic link is
            refused and :meth:`commit` renames over ``path`` itself. True: the
            link is followed (for programs that ask for it). Either way the
            target passes :func:`photo3d.files.gate.check_target` (not a FIFO or
            device, not an input of the command).

    Attributes:
        path: the temporary file to write into.
        target: the file as given (for messages).
        final: the file that :meth:`commit` replaces (``target`` with symbolic
            links followed).

    Raises:
        OutputError: ``path`` is a folder, its folder is missing, or the file
            system refuses a new file there (permissions, read-only, full, name
            too long); ``path`` is a symbolic link and ``follow_symlinks`` is False.

    Example:
        >>> import pathlib, tempfile
        >>> pending = PendingFile(pathlib.Path(tempfile.mkdtemp()) / "a.bin")
        >>> _ = pending.path.write_bytes(b"xy")
        >>> pending.commit().read_bytes(), pending.path.exists()
        (b'xy', False)
    """

    def __init__(self, path: PathLike, *, suffix: str = "",
                 follow_symlinks: bool = False) -> None:
        self.target = Path(path)
        self._done = False
        check()  # a worker thread starts no write once a signal asked to stop
        self.final = check_target(self.target, follow_symlinks=follow_symlinks)
        try:
            _check_target(self.final, self.target)
            self.path = _create_temp(self.final, suffix)
        except OSError as err:
            raise OutputError(f"cannot write {self.target}: {err.strerror or err}") from None
        LIVE.add(self.path)
        hold(self.path)

    def commit(self) -> Path:
        """Rename the temporary file over the target; return the target as given.

        Raises:
            OutputError: the rename failed (the temporary file is removed, the old
                file stays).

        Example:
            >>> import pathlib, tempfile
            >>> pending = PendingFile(pathlib.Path(tempfile.mkdtemp()) / "a.bin")
            >>> pending.commit().read_bytes()
            b''
        """
        try:
            check()  # a worker thread moves nothing into place once a signal asked to stop
        except BaseException:
            self.discard()
            raise
        hooks = list(getattr(_COMMITS, "hooks", ()))
        with deferred():  # in place and recorded (on_commit), or neither
            try:
                for _, before in hooks:
                    if before is not None:
                        before(self.path, self.final)
                os.replace(self.path, self.final)
            except OSError as err:
                self.discard()
                raise OutputError(f"cannot write {self.target}: "
                                  f"{err.strerror or err}") from None
            except BaseException:
                self.discard()
                raise
            self._done = True
            LIVE.discard(self.path)
            release(self.path)
            for after, _ in hooks:
                after(self.final)
        return self.target

    def discard(self) -> None:
        """Remove the temporary file (the target is not touched). Idempotent.

        Example:
            >>> import pathlib, tempfile
            >>> pending = PendingFile(pathlib.Path(tempfile.mkdtemp()) / "a.bin")
            >>> pending.discard()
            >>> list(pending.path.parent.iterdir())
            []
        """
        self._done = True
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.path)
        LIVE.discard(self.path)
        release(self.path)


_COMMITS = threading.local()  # .hooks: on_commit()'s, of this thread


@contextlib.contextmanager
def on_commit(hook: Callable[[Path], None], *,
              before: Callable[[Path, Path], None] | None = None) -> Iterator[None]:
    """Inside the block, call ``hook(final)`` as each file this thread writes is moved
    into place (:meth:`PendingFile.commit`), in the same step: a signal cannot land
    between the two (:func:`photo3d.files.signals.deferred`). For a record of what was
    written (:func:`photo3d.owned.recording`). ``before(temporary, final)`` is called
    just before the move (an error there keeps the file out of place): a SIGKILL,
    which nothing can hold, may still land between the move and ``hook``, and what
    ``before`` records lets the next command tell the file as this one's.

    Example:
        >>> import pathlib, tempfile
        >>> target = pathlib.Path(tempfile.mkdtemp()) / "a.txt"
        >>> with on_commit(lambda final: print(final.name)):
        ...     _ = write_text(target, "hi")
        a.txt
    """
    hooks = _COMMITS.__dict__.setdefault("hooks", [])
    entry = (hook, before)
    hooks.append(entry)
    try:
        yield
    finally:
        hooks.remove(entry)


@contextlib.contextmanager
def atomic_path(path: PathLike, *, suffix: str | None = None,
                follow_symlinks: bool = False) -> Iterator[Path]:
    """Yield a temporary sibling of ``path`` to write to; rename it over ``path`` when
    the block ends without an error, remove it otherwise.

    For writers that take a path rather than a file object (Pillow, numpy,
    safetensors). The temporary file exists, empty, when the block starts (see
    :class:`PendingFile`, which also lists the checks).

    Args:
        path: the file to write; an existing file is replaced.
        suffix: the temporary name's last suffix: ``.NAME.XXXXXXXX.tmp`` + suffix.
            Default: ``path``'s own (``.png``), for libraries that infer the format
            from it (``np.savez`` appends ``.npz`` to a name without it).
        follow_symlinks: False refuses a ``path`` that is a symbolic link
            (see :class:`PendingFile`).

    Raises:
        OutputError: the file cannot be written; an ``OSError`` raised in the block,
            or an ``OutputError`` naming the temporary file, becomes one line naming
            ``path``. Nothing is left behind.

    Example:
        >>> import pathlib, tempfile
        >>> import numpy as np
        >>> target = pathlib.Path(tempfile.mkdtemp()) / "a.npy"
        >>> with atomic_path(target) as tmp:
        ...     np.save(tmp, np.arange(3))
        >>> np.load(target).tolist(), [p.name for p in target.parent.iterdir()]
        ([0, 1, 2], ['a.npy'])
    """
    pending = PendingFile(path, suffix=Path(path).suffix if suffix is None else suffix,
                          follow_symlinks=follow_symlinks)
    with pending:
        try:
            yield pending.path
        except (OSError, OutputError) as err:
            named = _naming_target(err, pending)
            if named is None:
                raise
            raise named from None
        pending.commit()


@contextlib.contextmanager
def atomic_write(path: PathLike, mode: str = "wb", *,
                 follow_symlinks: bool = False) -> Iterator[IO]:
    """Open a temporary sibling of ``path`` for writing; rename it over ``path`` when
    the block ends without an error, remove it otherwise.

    Args:
        path: the file to write; an existing file is replaced.
        mode: ``"wb"`` or ``"w"`` (text, UTF-8).
        follow_symlinks: False refuses a ``path`` that is a symbolic link
            (see :class:`PendingFile`).

    Raises:
        OutputError: the file cannot be written (permissions, full disk, a folder
            in the way); nothing is left behind.

    Example:
        >>> import pathlib, tempfile
        >>> target = pathlib.Path(tempfile.mkdtemp()) / "a.txt"
        >>> with atomic_write(target, "w") as f:
        ...     _ = f.write("hé")
        >>> target.read_bytes()
        b'h\\xc3\\xa9'
    """
    if mode not in ("wb", "w"):
        raise ValueError(f"mode must be 'wb' or 'w', got {mode!r}")
    with atomic_path(path, suffix="", follow_symlinks=follow_symlinks) as tmp:
        with open(tmp, mode, **({} if "b" in mode else {"encoding": "utf-8"})) as f:
            yield f


@contextlib.contextmanager
def writing(path: PathLike, *, suffix: str | None = None) -> Iterator[Path]:
    """The path a format writer writes ``path`` through.

    ``path`` itself when it is a temporary file this module handed out (the
    caller's :func:`atomic_path`) or a new file inside a temporary folder of
    :mod:`photo3d.files.staging`; else a temporary sibling renamed over ``path`` at
    the end (:func:`atomic_path`, with every check of the gate).

    Example:
        >>> import pathlib, tempfile
        >>> target = pathlib.Path(tempfile.mkdtemp()) / "a.bin"
        >>> with atomic_path(target) as tmp:
        ...     with writing(tmp) as same:
        ...         _ = same.write_bytes(b"x")
        ...     same == tmp
        True
        >>> with writing(target) as other:
        ...     other != target
        True
    """
    path = Path(path)
    if _issued(path):
        yield path
        return
    with atomic_path(path, suffix=suffix) as tmp:
        yield tmp


@contextlib.contextmanager
def open_write(path: PathLike, mode: str = "wb") -> Iterator[IO]:
    """Open ``path`` for a format writer to stream into, through :func:`writing`.

    Args:
        path: the file to write.
        mode: ``"wb"`` or ``"w"`` (text, UTF-8).

    Example:
        >>> import pathlib, tempfile
        >>> target = pathlib.Path(tempfile.mkdtemp()) / "a.txt"
        >>> with open_write(target, "w") as f:
        ...     _ = f.write("hi")
        >>> target.read_text()
        'hi'
    """
    if mode not in ("wb", "w"):
        raise ValueError(f"mode must be 'wb' or 'w', got {mode!r}")
    with writing(path, suffix="") as tmp, open(
            tmp, mode, **({} if "b" in mode else {"encoding": "utf-8"})) as f:
        yield f


@contextlib.contextmanager
def open_append(path: PathLike) -> Iterator[IO]:
    """Open ``path`` to append text lines (UTF-8, ``newline=""``), created if missing.

    The one write that is not atomic: a log that grows a line at a time
    (``losses.csv``). The target passes the gate first (no symbolic link, FIFO or
    input), and is opened with ``O_NOFOLLOW``, so a link that appears meanwhile is
    refused, never written through.

    Raises:
        OutputError: one line naming ``path``.

    Example:
        >>> import pathlib, tempfile
        >>> target = pathlib.Path(tempfile.mkdtemp()) / "log.csv"
        >>> for row in ("a\\n", "b\\n"):
        ...     with open_append(target) as f:
        ...         _ = f.write(row)
        >>> target.read_text()
        'a\\nb\\n'
    """
    check_target(path)
    flags = os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC
    try:
        fd = os.open(path, flags, 0o666)
    except OSError as err:
        raise OutputError(f"cannot write {path}: {err.strerror or err}") from None
    try:
        with open(fd, "a", encoding="utf-8", newline="") as f:
            yield f
    except OSError as err:
        raise OutputError(f"cannot write {path}: {err.strerror or err}") from None


def _issued(path: Path) -> bool:
    """True if ``path`` is a temporary file handed out here or lies in a staged folder."""
    if path.is_symlink():
        return False
    return path in LIVE or Path(os.path.abspath(path)) in LIVE or in_issued_folder(path)


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


def write_json(path: PathLike, value: Any, *, indent: int | None = 2) -> Path:
    """Write ``value`` as JSON (``json.dumps(value, indent=indent)``, no final newline)
    to ``path`` atomically; returns the path.

    Example:
        >>> import pathlib, tempfile
        >>> write_json(pathlib.Path(tempfile.mkdtemp()) / "a.json", {"a": [1]}).read_text()
        '{\\n  "a": [\\n    1\\n  ]\\n}'
    """
    return write_text(path, json.dumps(value, indent=indent))


def check_writable(file: PathLike, *, follow_symlinks: bool = False) -> Path:
    """Check early that ``file`` can be written: its folder exists and takes a new file.

    A hidden temporary file is created beside it and removed (see
    :class:`PendingFile`). Returns ``file`` as a Path. ``follow_symlinks=False``
    also refuses a ``file`` that is a symbolic link (:func:`refuse_symlink`).

    Raises:
        OutputError: ``file`` is a folder, its folder is missing, or the file system
            refuses a new file there (permissions, read-only, full, name too long);
            ``file`` is a symbolic link and ``follow_symlinks`` is False.

    Example:
        >>> import pathlib, tempfile
        >>> check_writable(pathlib.Path(tempfile.mkdtemp()) / "depth.png").name
        'depth.png'
    """
    PendingFile(file, follow_symlinks=follow_symlinks).discard()
    return Path(file)


def refuse_symlink(path: PathLike, *, hint: str = "") -> Path:
    """Refuse ``path`` if it is a symbolic link (to anything, or to nothing).

    For writers that must never write outside their folder: a link placed there
    could point anywhere. Returns ``path`` as a Path.

    Raises:
        OutputError: ``PATH is a symbolic link; photo3d does not write through links``
            (then `` (HINT)`` when a ``hint`` says what to do).

    Example:
        >>> import pathlib, tempfile
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> (folder / "a.png").symlink_to("/nowhere")
        >>> refuse_symlink(folder / "b.png").name
        'b.png'
        >>> refuse_symlink(folder / "a.png")
        Traceback (most recent call last):
        photo3d.errors.OutputError: ... is a symbolic link; photo3d does not write through links
    """
    path = Path(path)
    if path.is_symlink():
        raise OutputError(f"{path} is a symbolic link; photo3d does not write through links"
                          + (f" ({hint})" if hint else ""))
    return path


def _naming_target(err: OSError | OutputError, pending: PendingFile) -> OutputError | None:
    """``err`` as one line naming the target: ``cannot write TARGET: reason`` for an
    ``OSError``, the message with the temporary name replaced for an
    ``OutputError`` that names it; None for another ``OutputError``."""
    if isinstance(err, OSError):
        return OutputError(f"cannot write {pending.target}: {_reason(err, pending.path)}")
    if str(pending.path) in str(err):
        return OutputError(str(err).replace(str(pending.path), str(pending.target)))
    return None


def _reason(err: OSError, path: Path) -> str:
    """Why writing ``path`` failed: the system's words; a full disk is named as one
    even when the library raised its own message (numpy's ``tofile``: "N requested
    and 0 written", or, when it reserves the space first and the disk has less, "Not
    enough free space to write N bytes after offset M", with no errno and the disk
    not yet full).

    Example:
        >>> _reason(OSError("Not enough free space to write 57759352 bytes after offset 363"),
        ...         Path("."))
        'No space left on device'
    """
    if err.strerror:
        return err.strerror
    if str(err).startswith("Not enough free space"):  # numpy's npy_fallocate
        return os.strerror(errno.ENOSPC)
    try:
        vfs = os.statvfs(path.parent)
    except OSError:
        return str(err)
    if vfs.f_bavail * vfs.f_frsize < (1 << 20):
        return os.strerror(errno.ENOSPC)
    return str(err)


def _create_temp(final: Path, suffix: str) -> Path:
    """A new empty file ``.NAME.XXXXXXXX.tmp`` + ``suffix`` beside ``final``, after
    removing the orphans of killed writers of ``final`` (:func:`remove_orphan_files`)."""
    remove_orphan_files(final)
    for _ in range(100):
        tmp = temp_sibling(final)
        tmp = tmp.with_name(tmp.name + suffix)
        try:  # the mode the umask leaves, as open() gives
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        except FileExistsError:
            continue
        return tmp
    raise OSError(errno.EEXIST, "no free temporary name")


def _check_target(final: Path, target: Path) -> None:
    if final.is_dir():
        raise OutputError(f"output {target} is a folder; expected a file name")
    parent = final.parent
    if not parent.is_dir():
        raise OutputError(f"cannot write {target}: the folder {parent} does not exist")
    try:
        name_max = os.pathconf(parent, "PC_NAME_MAX")
    except (OSError, ValueError):
        name_max = 255
    if len(os.fsencode(final.name)) > name_max:
        raise OSError(errno.ENAMETOOLONG, os.strerror(errno.ENAMETOOLONG))

