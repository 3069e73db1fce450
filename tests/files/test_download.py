"""Downloads into the cache: verified, atomic, never partial (photo3d.files.download).

A real HTTP server on 127.0.0.1 (a thread) serves the files; one handler cuts its
answer short to play a dropped connection.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import http.server
import threading
from pathlib import Path

import pytest

from photo3d.errors import InputError
from photo3d.files import download as dl

CONTENT = bytes(range(256)) * 10_000  # 2.56 MB: three 1 MB blocks
DIGEST = hashlib.sha256(CONTENT).hexdigest()


class Handler(http.server.SimpleHTTPRequestHandler):
    """Serves the folder; ``/cut/NAME`` announces NAME's full size but sends half;
    ``/endless/NAME`` sends zeros, without a size, until the client hangs up."""

    def do_GET(self):
        self.server.requests.append(self.path)
        if self.path.startswith("/endless/"):  # a mirror that never stops sending
            self.send_response(200)
            self.end_headers()
            with contextlib.suppress(OSError):  # until the client hangs up
                while True:
                    self.wfile.write(bytes(1 << 16))
            self.close_connection = True
            return None
        if not self.path.startswith("/cut/"):
            return super().do_GET()
        data = (Path(self.directory) / self.path[5:]).read_bytes()
        self.send_response(200)
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data[: len(data) // 2])
        self.wfile.flush()
        self.close_connection = True

    def log_message(self, *args):
        pass


@pytest.fixture
def server(tmp_path):
    """``(base URL, folder it serves, list of requested paths)``."""
    folder = tmp_path / "served"
    folder.mkdir()
    (folder / "weights.bin").write_bytes(CONTENT)
    httpd = http.server.ThreadingHTTPServer(
        ("127.0.0.1", 0), functools.partial(Handler, directory=str(folder)))
    httpd.requests = []
    thread = threading.Thread(target=httpd.serve_forever, kwargs={"poll_interval": 0.02},
                              daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{httpd.server_port}", folder, httpd.requests
    finally:
        httpd.shutdown()
        httpd.server_close()
        thread.join()


def free_port() -> int:
    """A port nothing listens on (bound, then closed)."""
    import socket

    with contextlib.closing(socket.socket()) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_download_is_verified_and_reports_progress(server, tmp_path):
    url, _, requests = server
    seen = []
    target = tmp_path / "cache" / "sub" / "weights.bin"
    assert dl.download(f"{url}/weights.bin", target, sha256=DIGEST.upper(),
                       progress=lambda done, total: seen.append((done, total))) == target
    assert target.read_bytes() == CONTENT
    assert [p.name for p in target.parent.iterdir()] == ["weights.bin"]  # no temporary left
    assert seen[0] == (0, len(CONTENT)) and seen[-1] == (len(CONTENT), len(CONTENT))
    assert [d for d, _ in seen] == sorted(d for d, _ in seen) and len(seen) == 4
    assert requests == ["/weights.bin"]


def test_a_wrong_sha256_is_refused_and_leaves_nothing(server, tmp_path):
    url, _, _ = server
    cache = tmp_path / "cache"
    with pytest.raises(InputError, match=f"refused .*its SHA-256 is {DIGEST}, expected 0+$"):
        dl.download(f"{url}/weights.bin", cache / "weights.bin", sha256="0" * 64)
    assert list(cache.iterdir()) == []
    # an older file of that name is left as it was
    (cache / "weights.bin").write_bytes(b"old")
    with pytest.raises(InputError, match="refused"):
        dl.download(f"{url}/weights.bin", cache / "weights.bin", sha256="0" * 64)
    assert [p.read_bytes() for p in cache.iterdir()] == [b"old"]


def test_a_dropped_connection_leaves_no_partial_file(server, tmp_path):
    url, _, _ = server
    cache = tmp_path / "cache"
    with pytest.raises(InputError, match="weights.bin (failed after|stopped after)") as err:
        dl.download(f"{url}/cut/weights.bin", cache / "weights.bin", sha256=DIGEST)
    assert "\n" not in str(err.value)
    assert list(cache.iterdir()) == []


def test_an_interrupted_download_leaves_no_partial_file(server, tmp_path):
    url, _, _ = server
    cache = tmp_path / "cache"

    def interrupt(done, total):
        if done > 0:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        dl.download(f"{url}/weights.bin", cache / "weights.bin", sha256=DIGEST,
                    progress=interrupt)
    assert list(cache.iterdir()) == []


def test_server_errors_and_no_server_are_one_line(server, tmp_path):
    url, _, _ = server
    with pytest.raises(InputError, match=r"cannot download .*/missing.bin: HTTP Error 404"):
        dl.download(f"{url}/missing.bin", tmp_path / "a.bin", sha256=DIGEST)
    dead = f"http://127.0.0.1:{free_port()}/weights.bin"
    with pytest.raises(InputError, match=r"cannot download .* \(offline\?\)$") as err:
        dl.download(dead, tmp_path / "a.bin", sha256=DIGEST)
    assert "\n" not in str(err.value) and "urlopen error" not in str(err.value)
    assert not (tmp_path / "a.bin").exists()


def test_file_urls_work_too(tmp_path):
    source = tmp_path / "w.bin"
    source.write_bytes(CONTENT)
    assert dl.download(source.as_uri(), tmp_path / "out" / "w.bin",
                       sha256=DIGEST).read_bytes() == CONTENT


def test_check_reachable(server):
    url, _, _ = server
    dl.check_reachable(url + "/any", what="the weights")  # listening: nothing raised
    port = free_port()
    with pytest.raises(InputError, match=f"^cannot download the weights: 127.0.0.1:{port} is "
                                         r"not reachable \(offline\?\)$"):
        dl.check_reachable(f"http://127.0.0.1:{port}/x", what="the weights", timeout=2)


def test_cache_dir_follows_photo3d_cache(monkeypatch, tmp_path):
    monkeypatch.setenv("PHOTO3D_CACHE", str(tmp_path / "c"))
    assert dl.cache_dir() == tmp_path / "c"
    monkeypatch.delenv("PHOTO3D_CACHE")
    monkeypatch.setenv("HOME", str(tmp_path))
    assert dl.cache_dir() == tmp_path / ".cache" / "photo3d"
    assert not dl.cache_dir().exists()  # created only when something is written


def test_sha256_of_matches_hashlib(tmp_path):
    path = tmp_path / "a.bin"
    path.write_bytes(CONTENT)
    assert dl.sha256_of(path) == DIGEST


def _stop_at(limit: int):
    """A progress callback that fails the test once ``limit`` bytes arrived (so code
    without a cap fails instead of filling the disk)."""
    def progress(*args):
        if args[-2] > limit:
            pytest.fail(f"the download went on past {limit} bytes")
    return progress


def test_a_download_larger_than_its_cap_is_refused_and_leaves_nothing(server, tmp_path):
    url, _, requests = server
    target = tmp_path / "cache" / "w.bin"
    with pytest.raises(InputError, match=r"^refused .*/weights.bin: larger than 1000 bytes"):
        dl.download(f"{url}/weights.bin", target, sha256=DIGEST, max_bytes=1000,
                    progress=_stop_at(0))  # its size is announced: refused before any byte
    with pytest.raises(InputError, match=r"^refused .*/endless/w.bin: larger than 3 MB"):
        dl.download(f"{url}/endless/w.bin", target, sha256=DIGEST, max_bytes=3 * 10**6,
                    progress=_stop_at(4 * 10**6))
    assert not target.exists() and list(target.parent.iterdir()) == []


def test_the_authors_weights_from_a_mirror_that_never_ends_are_refused(server, tmp_path,
                                                                       monkeypatch):
    from photo3d.nets import authors

    url, _, _ = server
    monkeypatch.setenv("PHOTO3D_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv(authors.URL_ENV, f"{url}/endless")
    monkeypatch.setattr(authors, "MAX_BYTES", 2 * 10**6, raising=False)
    with pytest.raises(InputError, match=r"larger than 2 MB.*nothing was saved") as err:
        authors.authors_weights(progress=_stop_at(20 * 10**6))  # before: until the disk fills
    assert str(err.value).count("\n") == 0
    assert list((tmp_path / "cache" / "authors").iterdir()) == []
