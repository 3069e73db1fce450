"""Serving a 3D photo folder on 127.0.0.1 (``photo3d view``)."""

from __future__ import annotations

import _thread
import http.client
import importlib
import signal
import socket
import threading
import urllib.error
import urllib.request

import pytest
from filetree import tree

import photo3d.viewer
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
        with pytest.raises(KeyboardInterrupt):  # raised once the server is closed
            serve(folder, open_browser=False, on_ready=on_ready)
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


@pytest.fixture
def running(tmp_path):
    """A server of ``tmp_path/photo`` in a thread, with a secret beside the folder,
    links to it and to a file inside, a subfolder and a hidden file."""
    photo = tmp_path / "photo"
    photo.mkdir()
    (photo / "viewer.html").write_text("<!doctype html>")
    (photo / "video").mkdir()
    (photo / "video" / "circle.mp4").write_bytes(b"mp4")
    (photo / ".hidden").write_text("temporary")
    (tmp_path / "secret.txt").write_text("secret")
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "elsewhere" / "x.txt").write_text("secret too")
    (photo / "out.txt").symlink_to(tmp_path / "secret.txt")
    (photo / "in.html").symlink_to("viewer.html")
    (photo / "linked").symlink_to(tmp_path / "elsewhere")
    (photo / "fifo").mkdir()  # a folder named like a file
    with ViewerServer(photo) as server:
        thread = threading.Thread(target=server.serve_forever)
        thread.start()
        try:
            yield server
        finally:
            server.shutdown()
            thread.join()


def request(server, path: str, *, host: str | None = "own",
            method: str = "GET") -> tuple[int, bytes, dict]:
    port = server.url.split(":")[2].split("/")[0]
    conn = http.client.HTTPConnection("127.0.0.1", int(port), timeout=10)
    try:
        conn.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
        if host is not None:
            conn.putheader("Host", f"127.0.0.1:{port}" if host == "own" else
                           host.replace("PORT", port))
        conn.endheaders()
        response = conn.getresponse()
        return response.status, response.read(), dict(response.getheaders())
    finally:
        conn.close()


def test_only_regular_files_inside_the_folder_are_served(running):
    assert request(running, "/viewer.html")[:2] == (200, b"<!doctype html>")
    assert request(running, "/viewer.html?x=1#y")[:2] == (200, b"<!doctype html>")
    assert request(running, "/video/circle.mp4")[:2] == (200, b"mp4")
    assert request(running, "/viewer.html", method="HEAD")[0] == 200
    refused = ["/out.txt", "/in.html", "/linked/x.txt", "/linked/", "/../secret.txt",
               "/%2e%2e/secret.txt", "/video/../../secret.txt", "/video/%2e%2e/%2e%2e/secret.txt",
               "/..%2fsecret.txt", "/.hidden", "/video", "/video/", "/fifo", "//etc/passwd",
               "/viewer.html/", "/missing.txt", "/video\\..\\..\\secret.txt", "/%00"]
    for path in refused:
        status, body, _ = request(running, path)
        assert status in (403, 404), path
        assert b"secret" not in body and b"circle.mp4" not in body and b"x.txt" not in body
    status, body, headers = request(running, "/")
    assert status == 302 and headers["Location"] == "/viewer.html" and body == b""
    status, body, _ = request(running, "http://evil.example/viewer.html")
    assert status == 400 and b"doctype" not in body


def test_only_requests_to_its_own_host_are_answered(running):
    assert request(running, "/viewer.html", host="localhost:PORT")[:2] == (200, b"<!doctype html>")
    assert request(running, "/viewer.html", host="LocalHost:PORT")[0] == 200
    for host in ("evil.example", "evil.example:PORT", "127.0.0.1", "localhost",
                 "127.0.0.1:1", "0.0.0.0:PORT", "[::1]:PORT", ""):
        status, body, _ = request(running, "/viewer.html", host=host)
        assert status in (400, 421), host
        assert b"doctype" not in body
    status, body, _ = request(running, "/viewer.html", host=None)
    assert status == 400 and b"doctype" not in body


def test_the_server_listens_on_loopback_only(folder):
    with ViewerServer(folder) as server:
        assert server._server.server_address[0] == "127.0.0.1"
        assert server._server.socket.getsockname()[0] == "127.0.0.1"


@pytest.mark.parametrize("points_to", ["outside.html", "missing.html", "inside.html"])
def test_a_linked_viewer_page_is_refused_before_any_work(tmp_path, capsys, monkeypatch,
                                                       points_to):
    from photo3d.cli import main

    photo = tmp_path / "photo"
    photo.mkdir()
    (tmp_path / "outside.html").write_text("theirs")
    (photo / "inside.html").write_text("mine")
    (photo / "viewer.html").symlink_to(photo / points_to if points_to == "inside.html"
                                       else tmp_path / points_to)
    before = tree(tmp_path)

    def refuse(*args, **kwargs):
        raise AssertionError("worked before the link was refused")

    monkeypatch.setattr("photo3d.photo.load", refuse)
    monkeypatch.setattr(serve_module, "serve", refuse)
    monkeypatch.setattr(photo3d.viewer, "serve", refuse)  # what view imports
    assert main(["view", str(photo), "--no-browser"]) == 2
    err = capsys.readouterr().err
    assert err == (f"photo3d: error: {photo / 'viewer.html'} is a symbolic link; "
                   "photo3d does not write through links\n")
    assert tree(tmp_path) == before
    with pytest.raises(InputError, match="is a symbolic link"):
        ViewerServer(photo)


def test_a_download_the_browser_aborts_ends_quietly(folder, capfd):
    import struct
    import time

    (folder / "big.mp4").write_bytes(b"\0" * (32 * 2**20))  # more than the socket buffers
    with ViewerServer(folder) as server:
        thread = threading.Thread(target=server.serve_forever)
        thread.start()
        try:
            port = int(server.url.split(":")[2].split("/")[0])
            for _ in range(3):
                with socket.create_connection(("127.0.0.1", port), timeout=10) as conn:
                    conn.sendall(f"GET /big.mp4 HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n"
                                 .encode())
                    assert conn.recv(4096).startswith(b"HTTP/1.0 200")
                    # hang up at once, with a reset, as a browser closing its tab does
                    conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            # the server notices when it writes next: wait until its threads are done
            deadline = time.monotonic() + 30
            while (any(t.name.endswith("(process_request_thread)") for t in threading.enumerate())
                   and time.monotonic() < deadline):
                time.sleep(0.05)
            assert fetch(server.url)[0] == 200  # still serving
        finally:
            server.shutdown()
            thread.join()
    err = capfd.readouterr().err
    assert "Traceback" not in err and "BrokenPipe" not in err and "ConnectionReset" not in err


@pytest.mark.parametrize("port", [99999, "taken"])
def test_view_refuses_a_bad_port_before_writing_the_viewer(tmp_path, capsys, port):
    # hostile round: view wrote viewer.html into a folder made without it, then refused
    import numpy as np
    from test_robustness import run

    import photo3d

    depth = np.ones((16, 16), np.float32)
    depth[4:12, 4:12] = 0.5
    photo = photo3d.make(np.full((16, 16, 3), 0.5, np.float32), depth=depth,
                         config=photo3d.Config(size=None)).save(
        tmp_path / "photo", viewer=False, ply=None, glb=False)
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        if port == "taken":
            port = taken.getsockname()[1]
        run(capsys, "view", photo, "--port", port, "--no-browser", status=2, root=tmp_path,
            message=f"{port}")
    assert not (photo / "viewer.html").exists()
