"""Serving a 3D photo folder on 127.0.0.1 (``photo3d view``)."""

from __future__ import annotations

import _thread
import importlib
import signal
import socket
import threading
import urllib.error
import urllib.request

import pytest

from photo3d.errors import InputError
from photo3d.viewer import ViewerServer, serve

# the module, not the function photo3d.viewer re-exports under the same name
serve_module = importlib.import_module("photo3d.viewer.serve")


@pytest.fixture
def folder(tmp_path):
    (tmp_path / "viewer.html").write_text("<!doctype html><title>x</title>")
    (tmp_path / "mesh.glb").write_bytes(b"glTF")
    return tmp_path


def fetch(url: str) -> tuple[int, bytes]:
    try:
        with urllib.request.urlopen(url, timeout=10) as response:
            return response.status, response.read()
    except urllib.error.HTTPError as err:
        err.close()
        return err.code, b""


def test_server_serves_the_folder_on_loopback(folder):
    with ViewerServer(folder) as server:
        thread = threading.Thread(target=server.serve_forever)
        thread.start()
        try:
            assert server.url.startswith("http://127.0.0.1:") and server.url.endswith(
                "/viewer.html")
            assert fetch(server.url) == (200, b"<!doctype html><title>x</title>")
            base = server.url.rsplit("/", 1)[0]
            assert fetch(base + "/mesh.glb") == (200, b"glTF")
            assert fetch(base + "/missing.txt")[0] == 404
        finally:
            server.shutdown()
            thread.join()


def test_serve_runs_until_ctrl_c(folder):
    seen = {}

    def on_ready(url: str, opened: bool) -> None:
        def visit_then_interrupt() -> None:
            seen["page"] = fetch(url)
            _thread.interrupt_main()  # what Ctrl-C does

        seen["url"], seen["opened"] = url, opened
        seen["thread"] = threading.Thread(target=visit_then_interrupt)
        seen["thread"].start()

    # A shell that starts us in the background may have set SIGINT to "ignore", which
    # would make interrupt_main() do nothing: use Python's Ctrl-C handler for this test.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        serve(folder, open_browser=False, on_ready=on_ready)  # returns after "Ctrl-C"
    finally:
        signal.signal(signal.SIGINT, previous)
    seen["thread"].join()
    assert seen["opened"] is False
    assert seen["page"][0] == 200 and seen["url"].startswith("http://127.0.0.1:")


def test_errors_name_the_problem(tmp_path, folder):
    with pytest.raises(InputError, match="no viewer.html"):
        ViewerServer(tmp_path / "nowhere")
    with pytest.raises(InputError, match="port"):
        ViewerServer(folder, port=70000)
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        with pytest.raises(InputError, match="cannot listen"):
            ViewerServer(folder, port=taken.getsockname()[1])


def test_browser_is_opened_only_with_a_display(monkeypatch):
    opened = []
    monkeypatch.setattr(serve_module.webbrowser, "open", lambda url: opened.append(url) or True)
    monkeypatch.setattr(serve_module.sys, "platform", "linux")
    for name in ("DISPLAY", "WAYLAND_DISPLAY", "BROWSER"):
        monkeypatch.delenv(name, raising=False)
    assert serve_module.open_in_browser("http://127.0.0.1:1/viewer.html") is False
    assert opened == []  # no text-mode browser taking over the terminal
    monkeypatch.setenv("DISPLAY", ":0")
    assert serve_module.open_in_browser("http://127.0.0.1:1/viewer.html") is True
    assert opened == ["http://127.0.0.1:1/viewer.html"]
