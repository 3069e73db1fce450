"""Per-request temporary folders that expire, and the check of every uploaded file.

Everything a ``photo3d ui`` server writes lies under one root (:class:`Workspace`):
its upload folder (:attr:`Workspace.uploads`, where the web framework stores uploads
and their partial files) and one folder per request, named by 128 random bits, where
the 3D photo folder, the depth preview and the zip are written. Only the files a
request returned are served, each under its own random token
(:meth:`Workspace.publish`), never by their path. A request's folder is kept ``ttl``
seconds after the request ends (so the page's download links keep working), then
removed by a background sweeper, which also removes the upload folder's leftovers
older than ``ttl`` (empty folders, partial uploads); a cancelled request's folder is
removed at once (:meth:`Workspace.discard`); everything is removed when the server
stops. A server that could not clean up (killed with SIGKILL, a power cut) leaves its
root behind; the root holds a lock file the live server keeps locked, so the next
server removes the roots nobody holds (:func:`remove_stale`), and nothing else.

Uploads are never opened by a path the client chose: :func:`check_upload` accepts
only a regular file inside the upload folder the server created (not a link, not
inside a request's folder) and within the byte limit.

Example:
    >>> import tempfile
    >>> ws = Workspace(Path(tempfile.mkdtemp()) / "ws", ttl=60)
    >>> with ws.request() as folder:
    ...     _ = (folder / "a.txt").write_text("hi")
    >>> ws.sweep(now=ws.clock() + 61)
    1
    >>> folder.exists(); ws.close()
    False
"""

from __future__ import annotations

import os
import re
import secrets
import shutil
import stat
import threading
import time
import weakref
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from photo3d.errors import InputError, OutputError
from photo3d.parallel import start_thread

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: no stale-root detection
    fcntl = None

LOCK_NAME = ".photo3d-ui.lock"
"""The lock file in a workspace root, locked (``flock``) while its server runs."""
ROOT_PATTERN = re.compile(r"photo3d-ui-[0-9a-f]{16}")
"""The names of the roots ``photo3d ui`` creates in the upload folder."""
UPLOADS = "uploads"
"""The root's folder the web framework stores this server's uploads in."""
TOKEN = re.compile(r"[A-Za-z0-9_-]{22}")
"""What a published file's token looks like (:meth:`Workspace.publish`)."""


def _hold(path: Path) -> int | None:
    """Open ``path`` and lock it (``flock``, released when the descriptor closes: by
    the caller, or by the system when the process ends however it ends); the file
    descriptor, or None without ``fcntl``."""
    if fcntl is None:  # pragma: no cover - Windows
        return None
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        raise
    return fd


def remove_stale(upload_root: str | os.PathLike[str]) -> list[Path]:
    """Remove the workspace roots in ``upload_root`` left by servers that died
    without cleaning up: folders named like photo3d's roots, holding photo3d's lock
    file, which no running process holds. Returns the folders removed.

    Example:
        >>> import tempfile
        >>> up = Path(tempfile.mkdtemp())
        >>> live = Workspace(up / "photo3d-ui-0123456789abcdef", ttl=60)
        >>> dead = up / "photo3d-ui-fedcba9876543210"; dead.mkdir()
        >>> _ = (dead / LOCK_NAME).write_bytes(b"")        # its server was killed
        >>> other = up / "photo3d-ui-notmine"; other.mkdir()  # not a photo3d name
        >>> [p.name for p in remove_stale(up)], live.root.exists(), other.exists()
        (['photo3d-ui-fedcba9876543210'], True, True)
        >>> live.close()
    """
    removed: list[Path] = []
    if fcntl is None:  # pragma: no cover - Windows
        return removed
    root = Path(upload_root)
    try:
        entries = sorted(root.iterdir())
    except OSError:
        return removed
    for folder in entries:
        lock = folder / LOCK_NAME
        if (not ROOT_PATTERN.fullmatch(folder.name) or folder.is_symlink()
                or not folder.is_dir() or lock.is_symlink() or not lock.is_file()):
            continue
        try:
            with open(lock, "rb") as handle:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)  # held: a live server
                shutil.rmtree(folder, ignore_errors=True)
        except OSError:
            continue
        if not folder.exists():
            removed.append(folder)
    return removed


class Workspace:
    """A root folder holding the server's uploads and one temporary folder per
    request, each removed ``ttl`` seconds after its request ends.

    Args:
        root: the folder to create (must not exist) and own; removed by :meth:`close`.
        ttl: seconds a finished request's folder (and an upload) is kept.
        clock: the time source (``time.monotonic``; tests pass a fake one).

    Attributes:
        uploads: the upload folder (``root/uploads``, ``0700``).

    Thread-safe: requests, the sweeper and :meth:`close` may run in any threads.
    """

    def __init__(self, root: str | os.PathLike[str], *, ttl: float,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.root = Path(root)
        self.ttl = float(ttl)
        self.clock = clock
        try:
            self.root.mkdir(mode=0o700, parents=True)
        except OSError as err:
            raise OutputError(f"cannot create the working folder {self.root}: "
                              f"{err.strerror or err}") from None
        fd = _hold(self.root / LOCK_NAME)
        # released by close(), or when the workspace is collected without one
        self._release = weakref.finalize(self, os.close, fd) if fd is not None else None
        self.uploads = self.root / UPLOADS
        self.uploads.mkdir(mode=0o700)
        self._lock = threading.Lock()
        self._busy: set[Path] = set()
        self._expires: dict[Path, float] = {}
        self._published: dict[str, tuple[Path, Path]] = {}  # token -> (folder, file)
        self._stop = threading.Event()
        self._sweeper: threading.Thread | None = None

    @contextmanager
    def request(self) -> Iterator[Path]:
        """A new, empty folder for one request (``0700``, named by 128 random bits);
        its ``ttl`` starts when the ``with`` block ends, also on an error (unless
        :meth:`discard` removed it meanwhile)."""
        folder = self.root / f"request-{secrets.token_hex(16)}"
        folder.mkdir(mode=0o700)
        with self._lock:
            self._busy.add(folder)
        try:
            yield folder
        finally:
            with self._lock:
                if folder in self._busy:
                    self._busy.discard(folder)
                    self._expires[folder] = self.clock() + self.ttl

    def discard(self, folder: Path) -> None:
        """Remove a request's folder now (a cancelled request), with what it
        published."""
        with self._lock:
            self._busy.discard(folder)
            self._expires.pop(folder, None)
            self._forget([folder])
        shutil.rmtree(folder, ignore_errors=True)

    def publish(self, path: Path) -> str:
        """Serve ``path``, a file in a request's folder, under a new random token
        (128 bits, :data:`TOKEN`) until its folder is removed; returns the token.

        Example:
            >>> import tempfile
            >>> ws = Workspace(Path(tempfile.mkdtemp()) / "ws", ttl=60)
            >>> with ws.request() as folder:
            ...     _ = (folder / "a.zip").write_bytes(b"PK")
            ...     token = ws.publish(folder / "a.zip")
            >>> ws.published(token).name, ws.published("x" * 22)
            ('a.zip', None)
            >>> ws.close()
        """
        folder = self._request_of(path)
        token = secrets.token_urlsafe(16)
        with self._lock:
            self._published[token] = (folder, path)
        return token

    def published(self, token: str) -> Path | None:
        """The file published under ``token``, or None (unknown, expired, removed)."""
        with self._lock:
            found = self._published.get(token)
        return None if found is None else found[1]

    def _request_of(self, path: Path) -> Path:
        """The request folder ``path`` lies in (a ValueError otherwise)."""
        relative = Path(path).relative_to(self.root)
        folder = self.root / relative.parts[0]
        if len(relative.parts) < 2 or not folder.name.startswith("request-"):
            raise ValueError(f"{path} is not in a request's folder")
        return folder

    def _forget(self, folders: list[Path]) -> None:
        """Drop what ``folders`` published (the caller holds the lock)."""
        gone = set(folders)
        for token in [t for t, (f, _) in self._published.items() if f in gone]:
            del self._published[token]

    def sweep(self, now: float | None = None) -> int:
        """Remove the folders of finished requests whose ``ttl`` has passed; returns
        how many were removed."""
        now = self.clock() if now is None else now
        with self._lock:
            due = [f for f, end in self._expires.items() if end <= now and f not in self._busy]
            for folder in due:
                del self._expires[folder]
            self._forget(due)
        for folder in due:
            shutil.rmtree(folder, ignore_errors=True)  # already gone: nothing to do
        self._sweep_uploads()
        return len(due)

    def _sweep_uploads(self) -> None:
        """Remove the upload folder's leftovers older than ``ttl`` (wall-clock age):
        empty folders (the framework removes expired uploads but not their folders)
        and files at its top (the partial files of aborted uploads)."""
        limit = time.time() - self.ttl
        try:
            entries = list(os.scandir(self.uploads))
        except OSError:
            return
        for entry in entries:
            try:
                if entry.stat(follow_symlinks=False).st_mtime > limit:
                    continue
                if entry.is_dir(follow_symlinks=False):
                    os.rmdir(entry.path)  # only when empty
                else:
                    os.unlink(entry.path)
            except OSError:  # not empty, or already gone
                continue

    def start_sweeper(self, every: float | None = None) -> None:
        """Sweep every ``every`` seconds (default: a quarter of ``ttl``, at most a
        minute) in a daemon thread until :meth:`close`."""
        interval = every if every is not None else min(60.0, max(self.ttl / 4, 0.5))

        def loop() -> None:
            while not self._stop.wait(interval):
                self.sweep()

        self._sweeper = start_thread(loop, name="ui-sweeper")

    def contains(self, path: str | os.PathLike[str]) -> bool:
        """True if ``path`` (resolved) lies inside the root but not in its upload
        folder (a request's result, the lock file, the warm-up)."""
        real = Path(os.path.realpath(path))
        return (real.is_relative_to(os.path.realpath(self.root))
                and not real.is_relative_to(os.path.realpath(self.uploads)))

    def close(self) -> None:
        """Stop the sweeper and remove the root with everything in it."""
        self._stop.set()
        if self._sweeper is not None:
            self._sweeper.join()
        with self._lock:
            self._published.clear()
        for _ in range(3):  # a request still finishing may add a file meanwhile
            shutil.rmtree(self.root, ignore_errors=True)
            if not self.root.exists():
                break
            time.sleep(0.2)
        if self._release is not None:
            self._release()


def check_upload(path: str | os.PathLike[str], *, upload_root: str | os.PathLike[str],
                 workspace: Workspace | None = None, max_bytes: int,
                 what: str = "photo") -> Path:
    """The uploaded file at ``path``, after checking that the server created it.

    Args:
        path: the file the web framework handed over for an upload.
        upload_root: the folder uploads are stored in; ``path`` must lie inside it.
        workspace: the requests' folders, which ``path`` must not lie in (another
            request's results are not an upload).
        max_bytes: largest size accepted.
        what: the input's name for messages (``"photo"``, ``"depth map"``).

    Returns:
        ``path`` resolved.

    Raises:
        InputError: outside ``upload_root``, inside ``workspace``, a symbolic link,
            not a regular file, or larger than ``max_bytes``.

    Example:
        >>> import tempfile
        >>> root = Path(tempfile.mkdtemp()); _ = (root / "p.png").write_bytes(b"x" * 10)
        >>> check_upload(root / "p.png", upload_root=root, max_bytes=100).name
        'p.png'
        >>> check_upload("/etc/passwd", upload_root=root, max_bytes=100)
        Traceback (most recent call last):
        photo3d.errors.InputError: the photo was not uploaded to this server
    """
    given = Path(path)
    real = Path(os.path.realpath(given))
    inside = real.is_relative_to(os.path.realpath(upload_root))
    if not inside or (workspace is not None and workspace.contains(real)):
        raise InputError(f"the {what} was not uploaded to this server")
    try:
        info = os.lstat(given)
    except OSError:
        raise InputError(f"the {what} upload is gone (uploads expire; send it again)") from None
    if stat.S_ISLNK(info.st_mode):
        raise InputError(f"the {what} upload is a symbolic link")
    if not stat.S_ISREG(info.st_mode):
        raise InputError(f"the {what} upload is not a regular file")
    if info.st_size > max_bytes:
        raise InputError(f"the {what} is {_size(info.st_size)}; this server accepts at most "
                         f"{_size(max_bytes)}")
    return real


def _size(n: int) -> str:
    """``n`` bytes for people: ``'200.0 MB'``, ``'512 bytes'``."""
    return f"{n / 2**20:.1f} MB" if n >= 2**20 else f"{n:,} bytes"
