"""Start and stop the ``photo3d ui`` server (what the command line runs).

:func:`start` checks the options (:func:`~photo3d.ui.options.check_host`), creates
the server's workspace inside Gradio's temporary folder (``$GRADIO_TEMP_DIR``): its
own upload folder, which Gradio is given as the only folder it serves and stores
uploads in, and the requests' folders, served only through
:class:`~photo3d.ui.gate.Gate` (which also answers only this machine's and the
configured host names). It starts the warm-up and the TTL sweeper, builds the page
(:func:`photo3d.ui.page.build_app`) and launches it in background threads; it
returns a :class:`UiServer` once the address answers. :meth:`UiServer.close`
stops running requests (their partial output is removed), the server and the
sweeper, and removes every file the server wrote. The library never prints: the
command line prints :attr:`UiServer.url`.

Safe defaults (docs/ui.md): loopback only unless a login is given, no public
share link, no telemetry, no monitoring or MCP endpoints, uploads limited in
bytes, and a bounded queue.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import os
import secrets
import socket
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TypeVar

from photo3d.errors import ConfigError, OutputError
from photo3d.parallel import start_thread
from photo3d.ui.options import UiOptions, check_host, host_allowed, url_of
from photo3d.ui.runner import Runner
from photo3d.ui.warmup import Warmup
from photo3d.ui.workspace import Workspace, remove_stale

T = TypeVar("T")


class UiServer:
    """A running ``photo3d ui`` (a context manager that closes it).

    Attributes:
        url: the page's address, e.g. ``http://127.0.0.1:7860/``.
        options: what it was started with (``port`` is the real one).
        warmup: the warm-up (:class:`~photo3d.ui.warmup.Warmup`).
        workspace: the requests' folders (:class:`~photo3d.ui.workspace.Workspace`).
    """

    def __init__(self, demo, options: UiOptions, runner: Runner, warmup: Warmup,
                 workspace: Workspace, made: Sequence[Path] = ()) -> None:
        self.demo = demo
        self.options = options
        self.runner = runner
        self.warmup = warmup
        self.workspace = workspace
        self.url = url_of(options.host, options.port)
        self._made = list(made)  # empty folders Gradio made outside the workspace
        self._closed = False

    def wait(self) -> None:
        """Block until the server stops (Ctrl-C in the main thread interrupts it)."""
        while self.demo.is_running:
            time.sleep(0.2)

    def close(self, timeout: float = 10.0) -> None:
        """Stop requests (waiting up to ``timeout`` seconds), the server, the sweeper,
        and remove every file the server wrote. Idempotent."""
        if self._closed:
            return
        self._closed = True
        try:
            self.runner.stop(timeout)
            self.demo.close(verbose=False)
        finally:
            self.workspace.close()
            _remove_empty(self._made)  # only if empty: else someone else's now

    def __enter__(self) -> UiServer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def start(options: UiOptions | None = None) -> UiServer:
    """Start ``photo3d ui`` in background threads and return once it answers.

    Args:
        options: :class:`~photo3d.ui.options.UiOptions` (default: 127.0.0.1:7860,
            one worker, no login).

    Returns:
        The running :class:`UiServer`; close it (or use it in a ``with`` block).

    Raises:
        ConfigError: a non-loopback host without a login, or the port is taken.
        OutputError: Gradio's temporary folder (``$GRADIO_TEMP_DIR``) cannot be used.
        MissingExtra: Gradio is not installed (``pip install 'photo3d[ui]'``).
    """
    options = options or UiOptions()
    check_host(options.host, options.auth)
    port = options.port or _free_port(options.host)
    _check_port(options.host, port)  # before Gradio tries, which leaks its loop when it fails
    options = _with_port(options, port)
    from photo3d.parallel import thread_safe_kernels
    from photo3d.ui.page import CSS, build_app, load_gradio, theme

    load_gradio()  # MissingExtra before anything is created
    overlap = thread_safe_kernels()
    if options.workers > 1 and not overlap:
        raise ConfigError(f"--workers {options.workers} needs numba's OpenMP or TBB "
                          "threading layer (install libgomp1, or pip install tbb), or use "
                          "--workers 1")
    upload_root = _temp_folder()
    remove_stale(upload_root)  # roots of servers killed before they could clean up
    workspace = Workspace(upload_root / f"photo3d-ui-{secrets.token_hex(8)}", ttl=options.ttl)
    made = _gradio_folders()
    try:
        warmup = Warmup(workspace.root / "warmup")
        (warmup.start if options.warmup else warmup.skip)()
        workspace.start_sweeper()
        runner = Runner(workspace, warmup, upload_root=workspace.uploads,
                        max_bytes=options.max_upload_bytes, workers=options.workers,
                        overlap=overlap)
        demo = _in_own_loop(lambda: _launch(
            build_app(runner, warmup, workers=options.workers, ttl=options.ttl), options,
            CSS, theme(), workspace))
    except BaseException:
        workspace.close()
        _remove_empty(made)
        raise
    return UiServer(demo, options, runner, warmup, workspace, made=made)


def _launch(demo, options: UiOptions, css: str, theme, workspace: Workspace):
    """Gradio's queue and server with photo3d's safe settings (no share link, no
    monitoring or MCP endpoints, no run history, uploads limited in bytes), the
    :class:`~photo3d.ui.gate.Gate` in front, and the workspace's upload folder as the
    only one Gradio stores uploads in and serves."""
    from starlette.middleware import Middleware

    from photo3d.ui.gate import Gate

    allows = functools.partial(host_allowed, host=options.host, allowed=options.allowed_hosts)
    gate = Middleware(Gate, allows=allows, workspace=workspace)
    demo.queue(default_concurrency_limit=options.workers, max_size=options.max_queue)
    name = options.host.strip()
    if ":" in name and not name.startswith("["):  # an IPv6 address: Gradio builds its URL
        name = f"[{name}]"
    try:
        demo.launch(server_name=name, server_port=options.port, auth=options.auth,
                    share=False, prevent_thread_lock=True, quiet=True, inbrowser=False,
                    show_error=False, max_file_size=options.max_upload_bytes,
                    footer_links=["api"], enable_monitoring=False, mcp_server=False,
                    ssr_mode=False, pwa=False, run_history=False, theme=theme, css=css,
                    app_kwargs={"middleware": [gate]})
    except OSError as err:
        raise ConfigError(f"cannot listen on {options.host}:{options.port}: "
                          f"{getattr(err, 'strerror', None) or 'the port is taken'}; "
                          "choose another --port") from None
    # Before the address is handed to anyone: uploads go to (and only they are served
    # from) the workspace's upload folder, which the server removes when it stops.
    demo.server_app.uploaded_file_dir = str(workspace.uploads)
    return demo


def _temp_folder() -> Path:
    """Gradio's temporary folder (``$GRADIO_TEMP_DIR``, default ``/tmp/gradio``),
    created if needed; OutputError (one line) if it cannot hold the server's files."""
    from gradio.utils import get_upload_folder

    folder = Path(get_upload_folder())
    what = (f"GRADIO_TEMP_DIR={folder}" if os.environ.get("GRADIO_TEMP_DIR")
            else f"Gradio's temporary folder {folder}")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        if not os.access(folder, os.W_OK | os.X_OK):
            raise PermissionError(13, "Permission denied")
    except OSError as err:
        raise OutputError(f"{what} cannot hold photo3d ui's files: {err.strerror or err}; "
                          "set GRADIO_TEMP_DIR to a folder you can write") from None
    return folder


def _gradio_folders() -> list[Path]:
    """The folders Gradio creates when it starts a server (``vibe_edit_history`` in
    its temporary folder) that do not exist yet: removed again, if empty, at close."""
    from gradio import route_utils

    folder = Path(route_utils.DEFAULT_TEMP_DIR) / "vibe_edit_history"
    return [] if folder.exists() else [folder]


def _remove_empty(folders: list[Path]) -> None:
    for folder in folders:
        with contextlib.suppress(OSError):
            folder.rmdir()


def _in_own_loop(fn: Callable[[], T]) -> T:
    """``fn()``, run in a helper thread inside a running event loop that is closed
    afterwards: each Gradio app sets up a new event loop in the calling thread when
    none runs there, and never closes it (two ResourceWarnings per app)."""
    outcome: list = []

    def target() -> None:
        async def main():
            return fn()

        try:
            outcome.append((True, asyncio.run(main())))
        except BaseException as err:  # handed to the caller's thread
            outcome.append((False, err))

    start_thread(target, name="ui-launch", daemon=False).join()
    ok, value = outcome[0]
    if not ok:
        raise value
    return value


def _with_port(options: UiOptions, port: int) -> UiOptions:
    from dataclasses import replace

    return replace(options, port=port)


def _check_port(host: str, port: int) -> None:
    """Raise ConfigError if ``host:port`` cannot be listened on now."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the server will
        try:
            s.bind((host.strip("[]"), port))
        except OSError as err:
            raise ConfigError(f"cannot listen on {host}:{port}: {err.strerror or err}; "
                              "choose another --port (or --host)") from None


def _free_port(host: str) -> int:
    """A TCP port free on ``host`` now (it may be taken again before it is used)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.bind((host.strip("[]"), 0))
        return s.getsockname()[1]
