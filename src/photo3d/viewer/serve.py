"""Serve a 3D photo folder on 127.0.0.1 and open its viewer (``photo3d view OUT``).

``viewer.html`` also works straight from disk (``file://``); serving it is for
browsers or set-ups that restrict local files, and gives a URL to paste.

What is served, and to whom:

* Only the loopback interface is used, so nothing is exposed to the network.
* Only requests whose ``Host:`` is the server's own (``127.0.0.1:PORT`` or
  ``localhost:PORT``) are answered (400 without one, 421 for another), so a web
  page on another site cannot read the folder through DNS rebinding.
* Only regular files inside the folder are served (``GET`` and ``HEAD``), found
  without following any symbolic link: a link, even one pointing inside, a
  folder (never listed), a hidden name, ``..`` or anything that is not a regular
  file is 404. ``/`` redirects to ``viewer.html``.
* A download the browser aborts (a closed tab, a video seeking elsewhere) ends
  quietly: nothing is printed for it.
"""

from __future__ import annotations

import contextlib
import os
import socket
import stat
import sys
import webbrowser
from collections.abc import Callable
from functools import partial
from http import HTTPStatus
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import IO
from urllib.parse import unquote, urlsplit

from photo3d.errors import InputError
from photo3d.viewer.html import VIEWER_FILE

HOST = "127.0.0.1"

_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_DIR_FD = os.open in os.supports_dir_fd and hasattr(os, "O_DIRECTORY")


class _QuietHandler(SimpleHTTPRequestHandler):
    """Regular files of one folder, to its own ``Host:`` only; no request log (the
    library never prints). ``folder_fd``: the folder opened once (None where the
    platform cannot open files relative to it)."""

    def __init__(self, *args, folder_fd: int | None, **kwargs) -> None:
        self.folder_fd = folder_fd
        super().__init__(*args, **kwargs)

    def log_message(self, format: str, *args) -> None:
        pass

    def end_headers(self) -> None:
        self.send_header("Cache-Control", "no-store")  # a re-made photo shows at once
        super().end_headers()

    def send_head(self) -> IO[bytes] | None:
        """Headers of a ``GET`` or ``HEAD``; the open file to send, or None."""
        if not self._host_is_ours():
            return None
        if not self.path.startswith("/"):  # an absolute URL names another host
            self.send_error(HTTPStatus.BAD_REQUEST, "Bad request target")
            return None
        path = unquote(urlsplit(self.path).path)
        if path == "/":
            self.send_response(HTTPStatus.FOUND)
            self.send_header("Location", "/" + VIEWER_FILE)
            self.send_header("Content-Length", "0")
            self.end_headers()
            return None
        fd = _open_regular(self.directory, self.folder_fd, path.split("/")[1:])
        if fd is None:
            self.send_error(HTTPStatus.NOT_FOUND, "File not found")
            return None
        f = os.fdopen(fd, "rb")
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", self.guess_type(path))
        self.send_header("Content-Length", str(os.fstat(fd).st_size))
        self.end_headers()
        return f

    def _host_is_ours(self) -> bool:
        """True if ``Host:`` names this server; else sends 400 (none) or 421."""
        host = self.headers.get_all("Host") or []
        if len(host) != 1:
            self.send_error(HTTPStatus.BAD_REQUEST, "Exactly one Host header is required")
            return False
        port = self.server.server_address[1]
        if host[0].strip().lower() not in (f"{HOST}:{port}", f"localhost:{port}"):
            self.send_error(HTTPStatus.MISDIRECTED_REQUEST, "Unknown host")
            return False
        return True


def _open_regular(folder: str, folder_fd: int | None, parts: list[str]) -> int | None:
    """A read-only descriptor of the regular file ``folder/PARTS...``, or None.

    None when a part is empty, hidden (``.``, ``..``, ``.name``) or holds a
    backslash or NUL, when any part is a symbolic link, when a leading part is
    not a folder or the last is not a regular file. With ``folder_fd`` each step
    is opened relative to the last one with ``O_NOFOLLOW``, so a link swapped in
    meanwhile is not followed either.
    """
    if not parts or any(not p or p.startswith(".") or "\\" in p or "\0" in p for p in parts):
        return None
    flags = os.O_RDONLY | _NOFOLLOW | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    fd = None
    try:
        if folder_fd is not None:
            fd = os.dup(folder_fd)
            for part in parts[:-1]:
                step = os.open(part, os.O_RDONLY | os.O_DIRECTORY | _NOFOLLOW, dir_fd=fd)
                os.close(fd)
                fd = step
            step = os.open(parts[-1], flags, dir_fd=fd)
            os.close(fd)
            fd = step
        else:  # no dir_fd (Windows): check every part, then that the same file opened
            path = folder
            for part in parts:
                path = os.path.join(path, part)
                if stat.S_ISLNK(os.lstat(path).st_mode):
                    return None
            seen = os.lstat(path)
            fd = os.open(path, flags)
            if (os.fstat(fd).st_ino, os.fstat(fd).st_dev) != (seen.st_ino, seen.st_dev):
                raise OSError("the file changed while it was opened")
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise OSError("not a regular file")
    except OSError:  # missing, a link (ELOOP), a folder, a socket...: all "not found"
        if fd is not None:
            os.close(fd)
        return None
    return fd


class _Server(ThreadingHTTPServer):
    """A threading HTTP server that says nothing when a client goes away mid-answer."""

    def handle_error(self, request, client_address) -> None:
        if isinstance(sys.exc_info()[1], ConnectionError):  # BrokenPipe, ConnectionReset
            return  # the browser aborted a download: nothing went wrong here
        super().handle_error(request, client_address)


def check_port(port: int, *, bind: bool = True) -> None:
    """Refuse a ``port`` outside [0, 65535] or, with ``bind``, one that cannot be
    listened on at 127.0.0.1 now (in use, privileged), so a command can refuse it
    before writing anything. 0 (any free port) always passes.

    Raises:
        InputError: the port is out of range or cannot be bound.

    Example:
        >>> check_port(0)
        >>> check_port(70000)
        Traceback (most recent call last):
        ...
        photo3d.errors.InputError: port must be in [0, 65535], got 70000
    """
    if not 0 <= port <= 65535:
        raise InputError(f"port must be in [0, 65535], got {port}")
    if not bind or port == 0:
        return
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the server does
        try:
            probe.bind((HOST, port))
        except OSError as err:
            raise InputError(f"cannot listen on {HOST}:{port}: {err.strerror or err}") from None


class ViewerServer:
    """An HTTP server for one 3D photo folder on 127.0.0.1 (a context manager).

    Args:
        folder: a 3D photo folder holding ``viewer.html``.
        port: TCP port; 0 picks a free one.

    Attributes:
        url: address of the viewer page, ``http://127.0.0.1:PORT/viewer.html``.

    Example:
        >>> import tempfile, pathlib, threading, urllib.request
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> _ = (folder / "viewer.html").write_text("<!doctype html>")
        >>> with ViewerServer(folder) as server:
        ...     thread = threading.Thread(target=server.serve_forever)
        ...     thread.start()
        ...     with urllib.request.urlopen(server.url) as page:
        ...         body = page.read()
        ...     server.shutdown(); thread.join()
        >>> body
        b'<!doctype html>'
    """

    def __init__(self, folder: str | os.PathLike[str], *, port: int = 0) -> None:
        folder = Path(folder)
        page = folder / VIEWER_FILE
        if page.is_symlink():
            raise InputError(f"{page} is a symbolic link; photo3d serves only regular files")
        if not page.is_file():
            raise InputError(f"no {VIEWER_FILE} in {folder}: write it with "
                             f"photo3d.viewer.write_viewer (photo3d make does by default)")
        check_port(port, bind=False)
        real = os.path.realpath(folder)  # a link given as the folder is followed once, here
        try:
            self._folder_fd = (os.open(real, os.O_RDONLY | os.O_DIRECTORY) if _DIR_FD
                               else None)
        except OSError as err:
            raise InputError(f"cannot read {folder}: {err.strerror or err}") from None
        handler = partial(_QuietHandler, directory=real, folder_fd=self._folder_fd)
        try:
            self._server = _Server((HOST, port), handler)
        except OSError as err:
            self._close_folder()
            raise InputError(f"cannot listen on {HOST}:{port}: {err.strerror or err}") from None
        self.url = f"http://{HOST}:{self._server.server_port}/{VIEWER_FILE}"

    def serve_forever(self) -> None:
        """Handle requests until :meth:`shutdown` (from another thread) or Ctrl-C."""
        self._server.serve_forever(poll_interval=0.2)

    def shutdown(self) -> None:
        """Stop :meth:`serve_forever` running in another thread; waits for it."""
        self._server.shutdown()

    def close(self) -> None:
        """Release the socket and the folder."""
        self._server.server_close()
        self._close_folder()

    def _close_folder(self) -> None:
        if self._folder_fd is not None:
            with contextlib.suppress(OSError):
                os.close(self._folder_fd)
            self._folder_fd = None

    def __enter__(self) -> ViewerServer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def serve(folder: str | os.PathLike[str], *, port: int = 0, open_browser: bool = True,
          on_ready: Callable[[str, bool], None] | None = None) -> None:
    """Serve ``folder`` on 127.0.0.1 in the foreground until interrupted: Ctrl-C's
    :class:`KeyboardInterrupt` (or a termination signal's, under
    :func:`~photo3d.files.signals.handle_signals`) is raised once the server is closed.

    Args:
        folder: a 3D photo folder holding ``viewer.html``.
        port: TCP port; 0 picks a free one.
        open_browser: open the viewer in the default web browser when there is one
            with a display (never a text-mode browser in the terminal).
        on_ready: called once listening, as ``on_ready(url, browser_opened)``, e.g.
            so a command line can print the URL when no browser was opened.

    Raises:
        InputError: no ``viewer.html`` in ``folder`` (or it is a symbolic link), or
            the port is not available.
    """
    with ViewerServer(folder, port=port) as server:
        opened = open_browser and open_in_browser(server.url)
        if on_ready is not None:
            on_ready(server.url, opened)
        server.serve_forever()  # until Ctrl-C or a signal: raised after the server closes


def open_in_browser(url: str) -> bool:
    """Open ``url`` in a graphical web browser; False when there is none.

    On Linux and other Unix systems without ``DISPLAY`` / ``WAYLAND_DISPLAY`` (a
    server, a container, an SSH session) nothing is tried unless ``BROWSER`` is set:
    :mod:`webbrowser` would otherwise start a text browser in the terminal.
    """
    graphical = (
        sys.platform in ("win32", "darwin")
        or any(os.environ.get(name) for name in ("DISPLAY", "WAYLAND_DISPLAY", "BROWSER"))
    )
    if not graphical:
        return False
    try:
        return bool(webbrowser.open(url))
    except webbrowser.Error:
        return False
