"""The authors' weights, one flag away (photo3d.nets.authors, ``--weights authors``).

A real HTTP server on 127.0.0.1 (a thread) plays the authors' file server; it serves
three small fake checkpoints whose SHA-256 stand in for the authors' sums
(``OFFICIAL_SHA256`` is patched), so no test touches the network.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import http.server
import socket
import threading
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch")

from photo3d.cli import build_parser, main  # noqa: E402
from photo3d.cli.options import make_options  # noqa: E402
from photo3d.errors import ConfigError, InputError  # noqa: E402
from photo3d.nets import authors, weights  # noqa: E402

FAKE = {kind: f"not the {kind} net ".encode() * 50_000 for kind in weights.KINDS}  # ~1 MB
NAMES = ["edge-model.pth", "depth-model.pth", "color-model.pth"]


class Handler(http.server.SimpleHTTPRequestHandler):
    def do_GET(self):
        self.server.requests.append(self.path)
        return super().do_GET()

    def log_message(self, *args):
        pass


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache, and the fake files' sums as the authors'; returns the folder
    the authors' weights go to."""
    monkeypatch.setenv("PHOTO3D_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv(authors.URL_ENV, raising=False)
    for kind, data in FAKE.items():
        monkeypatch.setitem(weights.OFFICIAL_SHA256, kind, hashlib.sha256(data).hexdigest())
    return tmp_path / "cache" / "authors"


@pytest.fixture
def server(tmp_path, monkeypatch, cache):
    """Serves the three fake files at ``$PHOTO3D_AUTHORS_URL``; returns ``(folder
    served, list of requested paths)``."""
    folder = tmp_path / "served" / "files"
    fill(folder)
    httpd = http.server.ThreadingHTTPServer(
        ("127.0.0.1", 0), functools.partial(Handler, directory=str(folder.parent)))
    httpd.requests = []
    thread = threading.Thread(target=httpd.serve_forever, kwargs={"poll_interval": 0.02},
                              daemon=True)
    thread.start()
    monkeypatch.setenv(authors.URL_ENV, f"http://127.0.0.1:{httpd.server_port}/files")
    try:
        yield folder, httpd.requests
    finally:
        httpd.shutdown()
        httpd.server_close()
        thread.join()


@pytest.fixture
def offline(cache, monkeypatch):
    """``$PHOTO3D_AUTHORS_URL`` at a port nothing listens on; returns that URL."""
    with contextlib.closing(socket.socket()) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    url = f"http://127.0.0.1:{port}/model/"
    monkeypatch.setenv(authors.URL_ENV, url)
    return url


def fill(folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for kind, data in FAKE.items():
        (folder / f"{kind}-model.pth").write_bytes(data)


def test_the_published_location_is_the_authors_download_script():
    assert authors.AUTHORS_URL == "https://filebox.ece.vt.edu/~jbhuang/project/3DPhoto/model/"
    assert list(authors.FILES.values()) == NAMES


def test_downloads_the_three_files_once_verified_with_progress(server, cache):
    _, requests = server
    seen = []
    folder = authors.authors_weights(progress=lambda *a: seen.append(a))
    assert folder == cache == authors.authors_folder()
    assert sorted(p.name for p in folder.iterdir()) == sorted(NAMES)  # nothing else left
    for kind, data in FAKE.items():
        assert (folder / f"{kind}-model.pth").read_bytes() == data
    assert requests == [f"/files/{name}" for name in NAMES]
    assert [a[0] for a in seen if a[1] == 0] == NAMES  # each file's bar starts at 0
    assert (NAMES[-1], len(FAKE["color"]), len(FAKE["color"])) == seen[-1]
    assert authors.authors_weights() == folder and len(requests) == 3  # cached: no request


def test_files_in_the_cache_touch_no_network(offline, cache):
    fill(cache)
    assert authors.authors_weights(progress=lambda *a: pytest.fail("no download")) == cache


def test_only_missing_files_are_downloaded(server, cache):
    _, requests = server
    fill(cache)
    (cache / "depth-model.pth").unlink()
    authors.authors_weights()
    assert requests == ["/files/depth-model.pth"]


def test_a_file_of_another_sum_in_the_cache_is_refused_and_left_alone(server, cache):
    _, requests = server
    fill(cache)
    (cache / "depth-model.pth").write_bytes(b"my own depth net")
    digest = hashlib.sha256(b"my own depth net").hexdigest()
    with pytest.raises(InputError) as err:
        authors.authors_weights()
    message = str(err.value)
    assert message.startswith(f"{cache / 'depth-model.pth'} is not the authors' "
                              f"depth-model.pth: its SHA-256 is {digest}, expected "
                              f"{weights.OFFICIAL_SHA256['depth']}; photo3d did not write it")
    assert "move it elsewhere or delete it" in message and "\n" not in message
    assert (cache / "depth-model.pth").read_bytes() == b"my own depth net"
    assert requests == []  # checked before any download


def test_a_served_file_of_another_sum_is_refused_and_not_saved(server, cache, monkeypatch):
    served, _ = server
    (served / "depth-model.pth").write_bytes(b"a changed depth net")
    with pytest.raises(InputError) as err:
        authors.authors_weights()
    message = str(err.value)
    assert message.startswith("refused http://127.0.0.1:") and "\n" not in message
    assert message.endswith("(not the authors' depth-model.pth: nothing was saved; check "
                            "PHOTO3D_AUTHORS_URL)")
    assert sorted(p.name for p in cache.iterdir()) == ["edge-model.pth"]  # verified, kept


def test_offline_is_one_line_naming_the_files_the_url_and_the_folder(offline, cache):
    with pytest.raises(InputError) as err:
        authors.authors_weights()
    message = str(err.value)
    assert message.startswith(f"cannot download {offline}edge-model.pth: ")
    assert message.endswith(f"(offline?); put the authors' edge-model.pth, depth-model.pth "
                            f"and color-model.pth (from {offline}) into {cache}, or run the "
                            "small nets shipped with photo3d: --weights compact")
    assert "\n" not in message and not cache.exists()


def test_a_missing_file_on_the_server_says_where_to_put_it(server, cache):
    served, _ = server
    (served / "color-model.pth").unlink()
    with pytest.raises(InputError, match=r"color-model.pth: HTTP Error 404: .*; put the "
                                         r"authors' .* into " + str(cache)):
        authors.authors_weights()


def test_a_mirror_url_must_be_a_url(cache, monkeypatch):
    monkeypatch.setenv(authors.URL_ENV, "filebox.example/model")
    with pytest.raises(InputError, match="PHOTO3D_AUTHORS_URL must be an http://, https:// "
                                         "or file:// URL, got 'filebox.example/model'"):
        authors.authors_weights()
    monkeypatch.setenv(authors.URL_ENV, (Path(cache).parent / "mirror").as_uri())
    fill(Path(cache).parent / "mirror")
    assert authors.authors_weights() == cache  # a local folder works as a mirror


def parse(*argv: str):
    return make_options(build_parser().parse_args(list(argv)))


@pytest.mark.parametrize("command", [["make", "photo.png"], ["batch", "photos"]])
def test_weights_authors_is_the_cache_folder_to_make_and_batch(server, cache, command):
    learned = [*command, "-o", "out", "--inpainter", "learned", "-q"]
    assert parse(*learned, "--weights", "authors") == parse(*learned, "--weights", str(cache))
    assert parse(*learned, "--weights", "authors").weights() == cache


def test_a_folder_named_authors_is_still_a_folder(offline):
    options = parse("make", "p.png", "-o", "o", "--inpainter", "learned", "--weights",
                    "./authors")
    assert options.weights() == Path("authors")  # no download asked for


def test_weights_authors_without_the_learned_inpainter_downloads_nothing(server):
    _, requests = server
    with pytest.raises(ConfigError, match="--weights only apply to --inpainter learned"):
        parse("make", "p.png", "-o", "o", "--weights", "authors")
    assert requests == []


@pytest.fixture
def photo(tmp_path):
    from PIL import Image

    Image.fromarray(np.full((32, 48, 3), 128, np.uint8)).save(tmp_path / "photo.png")
    np.save(tmp_path / "depth.npy", np.ones((32, 48), np.float32))
    return tmp_path


def make(photo: Path, *extra: str) -> int:
    return main(["make", str(photo / "photo.png"), "--depth", str(photo / "depth.npy"),
                 "-o", str(photo / "out"), "--size", "48", "--no-video", "--inpainter",
                 "learned", "--weights", "authors", *extra])


def test_make_offline_says_where_to_put_the_files_in_one_line(photo, offline, cache, capsys):
    assert make(photo) == 2
    err = capsys.readouterr().err
    assert err.startswith("photo3d: error: cannot download ") and err.count("\n") == 1
    assert f"(from {offline}) into {cache}" in err and not (photo / "out").exists()


def test_make_downloads_then_loads_through_the_weights_loader(photo, server, cache, capsys):
    assert make(photo) == 2  # the fake files are no state dicts: the loader says so
    err = capsys.readouterr().err.splitlines()
    assert err[0] == (f"downloading the authors' weights from {authors.authors_url()} "
                      f"into {cache}")
    assert err[-1].startswith("photo3d: error: cannot read edge-model.pth: not a PyTorch "
                              "state dict")
    assert sorted(p.name for p in cache.iterdir()) == sorted(NAMES)
    assert make(photo, "-q") == 2 and capsys.readouterr().err.count("\n") == 1  # quiet
