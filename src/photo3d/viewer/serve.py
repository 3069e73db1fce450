"""Serve a 3D photo folder on 127.0.0.1 and open its viewer (``photo3d view OUT``).

``viewer.html`` also works straight from disk (``file://``); serving it is for
browsers or set-ups that restrict local files, and gives a URL to paste. Only the
loopback interface is used, so nothing is exposed to the network.
"""

from __future__ import annotations

import os
import sys
import webbrowser
from collections.abc import Callable
from functools import partial
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

from photo3d.errors import InputError
from photo3d.viewer.html import VIEWER_FILE

HOST = "127.0.0.1"


class _QuietHandler(SimpleHTTPRequestHandler):
    """Static files of one folder; no request log (the library never prints)."""

    def log_message(self, format: str, *args) -> None:
        pass

    def end_headers(self) -> None:
        self.send_header("Cache-Control", "no-store")  # a re-made photo shows at once
        super().end_headers()


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
        if not (folder / VIEWER_FILE).is_file():
            raise InputError(f"no {VIEWER_FILE} in {folder}: write it with "
                             f"photo3d.viewer.write_viewer (photo3d make does by default)")
        if not 0 <= port <= 65535:
            raise InputError(f"port must be in [0, 65535], got {port}")
        handler = partial(_QuietHandler, directory=str(folder))
        try:
            self._server = ThreadingHTTPServer((HOST, port), handler)
        except OSError as err:
            raise InputError(f"cannot listen on {HOST}:{port}: {err.strerror or err}") from None
        self.url = f"http://{HOST}:{self._server.server_port}/{VIEWER_FILE}"

    def serve_forever(self) -> None:
        """Handle requests until :meth:`shutdown` (from another thread) or Ctrl-C."""
        self._server.serve_forever(poll_interval=0.2)

    def shutdown(self) -> None:
        """Stop :meth:`serve_forever` running in another thread; waits for it."""
        self._server.shutdown()

    def close(self) -> None:
        """Release the socket."""
        self._server.server_close()

    def __enter__(self) -> ViewerServer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def serve(folder: str | os.PathLike[str], *, port: int = 0, open_browser: bool = True,
          on_ready: Callable[[str, bool], None] | None = None) -> None:
    """Serve ``folder`` on 127.0.0.1 in the foreground until Ctrl-C, then return.

    Args:
        folder: a 3D photo folder holding ``viewer.html``.
        port: TCP port; 0 picks a free one.
        open_browser: open the viewer in the default web browser when there is one
            with a display (never a text-mode browser in the terminal).
        on_ready: called once listening, as ``on_ready(url, browser_opened)``, e.g.
            so a command line can print the URL when no browser was opened.

    Raises:
        InputError: no ``viewer.html`` in ``folder``, or the port is not available.
    """
    with ViewerServer(folder, port=port) as server:
        opened = open_browser and open_in_browser(server.url)
        if on_ready is not None:
            on_ready(server.url, opened)
        try:
            server.serve_forever()
        except KeyboardInterrupt:  # Ctrl-C is how the user stops serving
            return


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
