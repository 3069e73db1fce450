"""``photo3d ui``'s safe defaults at the command line: loopback only unless a login
is given, refusals in one line (exit status 2), a taken port named, and Ctrl-C stops
it cleanly."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import urllib.request

import pytest

from photo3d.cli import build_parser, main
from photo3d.errors import ConfigError
from photo3d.ui.options import UiOptions, check_host, is_loopback, parse_auth


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
])
def test_refusals_are_one_line_with_status_2(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"photo3d: error: {message}") and err.count("\n") == 1


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
    env = {**os.environ, "GRADIO_TEMP_DIR": str(tmp_path)}
    proc = subprocess.Popen([sys.executable, "-m", "photo3d", "ui", "--port", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        first = proc.stdout.readline()
        assert first.startswith("photo3d ui: serving on http://127.0.0.1:")
        url = first.split()[4]
        with urllib.request.urlopen(url, timeout=30) as page:
            assert page.status == 200
        assert len(list(tmp_path.glob("photo3d-ui-*"))) == 1
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill() if proc.poll() is None else None
    assert proc.returncode == 0, err
    assert out.strip().endswith("photo3d ui: stopped") and "Traceback" not in err
    assert not list(tmp_path.glob("photo3d-ui-*"))
