"""``photo3d ui``'s safe defaults at the command line: loopback only unless a login
is given, only this machine's and the configured host names answered, refusals in one
line (exit status 2), a taken port or an unusable temporary folder named, ``::1``
served, and Ctrl-C stops it and leaves nothing in Gradio's temporary folder."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request

import pytest

from photo3d.cli import build_parser, main
from photo3d.errors import ConfigError
from photo3d.ui.options import UiOptions, check_host, host_allowed, is_loopback, parse_auth


@pytest.mark.parametrize("host", ["0.0.0.0", "::", "192.168.1.20", "example.org", "[::]"])
def test_a_host_beyond_this_machine_needs_a_login(host):
    with pytest.raises(ConfigError, match="--auth USER:PASS"):
        check_host(host, None)
    check_host(host, ("ana", "secret"))  # with one: allowed


@pytest.mark.parametrize("host", ["127.0.0.1", "127.1.2.3", "::1", "[::1]", "localhost"])
def test_loopback_needs_no_login(host):
    assert is_loopback(host)
    check_host(host, None)


def test_the_defaults_are_loopback_one_worker_no_login():
    args = build_parser().parse_args(["ui"])
    assert (args.host, args.port, args.auth, args.workers) == ("127.0.0.1", 7860, None, 1)
    options = UiOptions()
    assert (options.host, options.auth, options.workers) == ("127.0.0.1", None, 1)


@pytest.mark.parametrize(("argv", "message"), [
    (["ui", "--host", "0.0.0.0"], "--host 0.0.0.0 makes photo3d ui reachable from other "
                                  "machines: add --auth USER:PASS"),
    (["ui", "--auth", "nopassword"], "--auth must look like USER:PASS"),
    (["ui", "--auth", ":secret"], "--auth must look like USER:PASS"),
    (["ui", "--workers", "0"], "workers must be >= 1"),
    (["ui", "--ttl", "-1"], "ttl must be a positive number"),
    (["ui", "--allow-host", "photos.lan:8080"], "--allow-host takes a host name or an "
                                                "address without a port"),
])
def test_refusals_are_one_line_with_status_2(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"photo3d: error: {message}") and err.count("\n") == 1


@pytest.mark.parametrize("mb", ["-1", "0", "0.0000001", "nan", "inf"])
def test_a_bad_upload_limit_is_refused_before_listening(mb, capsys):
    with socket.socket() as taken:  # were it not refused first, this port would be named
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = str(taken.getsockname()[1])
        assert main(["ui", "--max-upload-mb", mb, "--port", port, "--no-warmup"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"photo3d: error: --max-upload-mb must be a positive number of "
                          f"megabytes, got {float(mb):g}") and err.count("\n") == 1


@pytest.mark.parametrize(("header", "host", "allowed", "answered"), [
    ("127.0.0.1:7860", "127.0.0.1", (), True),
    ("localhost", "127.0.0.1", (), True),
    ("LOCALHOST.:7860", "127.0.0.1", (), True),
    ("[::1]:7860", "127.0.0.1", (), True),
    ("127.5.6.7:1", "127.0.0.1", (), True),
    ("evil.example.com", "127.0.0.1", (), False),  # a rebinding page's own name
    ("evil.example.com:7860", "0.0.0.0", (), False),
    ("10.0.0.5:7860", "127.0.0.1", (), False),
    ("10.0.0.5:7860", "0.0.0.0", (), True),  # an address cannot be rebound
    ("[fe80::1]:7860", "::", (), True),
    ("photos.lan:7860", "0.0.0.0", ("photos.lan",), True),
    ("Photos.LAN", "0.0.0.0", ("photos.lan",), True),
    ("other.lan", "0.0.0.0", ("photos.lan",), False),
    ("photos.lan", "photos.lan", (), True),  # the name it listens on
    ("", "127.0.0.1", (), False),
    (None, "127.0.0.1", (), False),
    ("127.0.0.1:7860, evil.example.com", "127.0.0.1", (), False),
    ("user@127.0.0.1", "127.0.0.1", (), False),
])
def test_only_this_machine_and_the_configured_names_are_answered(header, host, allowed,
                                                                 answered):
    assert host_allowed(header, host=host, allowed=allowed) is answered


@pytest.mark.parametrize("make", [lambda tmp: tmp / "a file", lambda tmp: tmp / "a file" / "sub"])
def test_an_unusable_temporary_folder_is_one_line(make, tmp_path, capsys, monkeypatch):
    pytest.importorskip("gradio", reason="needs pip install 'photo3d[ui]'")
    (tmp_path / "a file").write_text("not a folder")
    folder = make(tmp_path)
    monkeypatch.setenv("GRADIO_TEMP_DIR", str(folder))
    assert main(["ui", "--port", "0", "--no-warmup"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"photo3d: error: GRADIO_TEMP_DIR={folder} cannot hold photo3d "
                          "ui's files: ") and err.count("\n") == 1
    assert err.rstrip().endswith("set GRADIO_TEMP_DIR to a folder you can write")
    assert (tmp_path / "a file").read_text() == "not a folder"


def test_parse_auth_keeps_colons_in_the_password():
    assert parse_auth("ana:a:b:c") == ("ana", "a:b:c")


def test_a_taken_port_is_one_line_and_leaves_nothing(capsys, monkeypatch, tmp_path):
    monkeypatch.setenv("GRADIO_TEMP_DIR", str(tmp_path))
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["ui", "--port", str(port), "--no-warmup"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"photo3d: error: cannot listen on 127.0.0.1:{port}")
    assert err.count("\n") == 1
    assert not list(tmp_path.glob("photo3d-ui-*"))  # the workspace was removed


def test_ctrl_c_stops_the_server_and_removes_its_files(tmp_path):
    pytest.importorskip("gradio", reason="needs pip install 'photo3d[ui]'")
    temp = tmp_path / "gradio"
    temp.mkdir()
    (temp / "theirs.txt").write_text("not the server's")  # another program's file
    env = {**os.environ, "GRADIO_TEMP_DIR": str(temp)}
    proc = subprocess.Popen([sys.executable, "-m", "photo3d", "ui", "--port", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        first = proc.stdout.readline()
        assert first.startswith("photo3d ui: serving on http://127.0.0.1:")
        url = first.split()[4]
        with urllib.request.urlopen(url, timeout=30) as page:
            assert page.status == 200
        assert len(list(temp.glob("photo3d-ui-*"))) == 1
        port = int(url.rsplit(":", 1)[1].strip("/"))
        upload(port, b"x" * 1000)  # an upload
        upload(port, b"y" * 5000, declared=100_000)  # one the client abandons halfway
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill() if proc.poll() is None else None
    assert proc.returncode == 0, err
    assert out.strip().endswith("photo3d ui: stopped") and "Traceback" not in err
    assert [p.name for p in temp.rglob("*")] == ["theirs.txt"]  # nothing of the server's


def upload(port: int, data: bytes, *, declared: int | None = None) -> None:
    """POST ``data`` as a file to Gradio's upload route; with ``declared`` (a larger
    Content-Length), hang up after sending it, as an aborted upload does."""
    head = (b'--xx\r\nContent-Disposition: form-data; name="files"; filename="a.png"\r\n'
            b"Content-Type: image/png\r\n\r\n")
    body = head + data + (b"" if declared else b"\r\n--xx--\r\n")
    with socket.create_connection(("127.0.0.1", port), timeout=30) as conn:
        conn.sendall(b"POST /gradio_api/upload HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                     b"Content-Type: multipart/form-data; boundary=xx\r\n"
                     + f"Content-Length: {declared or len(body)}\r\n\r\n".encode() + body)
        if declared is None:
            assert conn.recv(100).startswith(b"HTTP/1.1 200")
        else:
            time.sleep(0.5)  # the server has begun writing the partial file
