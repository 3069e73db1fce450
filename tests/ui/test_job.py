"""One request without the web server: the client's options are checked, the photo
is made through ``make``'s path into the request's folder (the 3D photo first, then
its videos), every warning ``make`` prints reaches the result, errors are one line
without the server's folders, a cancel stops a request and removes its folder (its
own request only), and no more than ``workers`` requests make photos at once."""

from __future__ import annotations

import sys
import threading
import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import two_planes, wait_for
from PIL import Image
from uikit import check_glb

from photo3d.errors import ConfigError, InputError
from photo3d.export.splats import build_splats
from photo3d.io.npz import load_npz
from photo3d.io.spz import read_spz
from photo3d.ui.job import JobCancelled, JobOptions, run_job
from photo3d.ui.progress import StageMeter
from photo3d.ui.runner import RequestError, Runner
from photo3d.ui.warmup import Warmup
from photo3d.ui.workspace import Workspace


@pytest.fixture
def upload(tmp_path):
    """A 64x96 photo and its disparity as uploaded files."""
    image, disparity = two_planes()
    folder = tmp_path / "uploads" / "3f9a"
    folder.mkdir(parents=True)
    Image.fromarray((image * 255).astype(np.uint8)).save(folder / "two planes.png")
    Image.fromarray((disparity * 100).astype(np.uint16)).save(folder / "depth.png")
    return folder / "two planes.png", folder / "depth.png"


@pytest.mark.parametrize(("options", "message"), [
    (dict(paths=["/etc/passwd"]), "unknown camera path '/etc/passwd'"),
    (dict(paths=["keys.json"]), "unknown camera path 'keys.json'"),
    (dict(size=100_000), "size must be 0 (the photo's size) or 64..2048, got 100000"),
    (dict(size=4096), "size must be 0 (the photo's size) or 64..2048"),  # the slider's end
    (dict(size=10.5), "size must be 0"),
    (dict(size=True), "size must be 0"),
    (dict(fill="../../evil"), "unknown fill '../../evil'"),
    (dict(fill=["learned"]), "unknown fill ['learned']"),
    (dict(source="file"), "unknown depth source 'file'"),
    (dict(videos=True, paths=[]), "videos are on but no camera path is chosen"),
    (dict(videos="no"), "videos must be true or false, got 'no'"),
    (dict(ply="yes"), "ply must be true or false, got 'yes'"),
    (dict(paths="circle"), "paths must be a list of at most 16 camera paths"),
    (dict(paths=["swing"] * 17), "paths must be a list of at most 16 camera paths"),
])
def test_options_a_client_may_not_choose(options, message):
    with pytest.raises(ConfigError) as err:
        JobOptions(**options)
    assert str(err.value).startswith(message)


def test_repeated_camera_paths_are_made_once():
    options = JobOptions(paths=["swing"] * 16 + [])
    assert options.paths == ("swing",)
    assert [v.path for v in options.make_options().save.videos] == ["swing"]
    assert JobOptions(paths=["zoom-in", "circle", "zoom-in"]).paths == ("zoom-in", "circle")


def test_the_learned_fill_gets_the_weights_it_was_given():
    make = JobOptions(fill="learned").make_options(Path("cache/authors"))
    assert make.inpainter_options == (("weights", Path("cache/authors")),)
    assert JobOptions(fill="diffusion").make_options(Path("w")).inpainter_options == ()


def test_the_options_become_makes_options():
    make = JobOptions(size=0, fill="structured", videos=False, ply=True).make_options()
    save = make.save
    assert (make.config.size, make.config.inpainter, save.videos, save.ply, save.glb,
            save.viewer, save.exports) == (None, "structured", (), "binary", True, True,
                                           ("splats.spz",))
    assert make.inpainter_options == ()  # no weights path a client could name


def test_the_progress_meter_only_moves_forward_to_one():
    meter = StageMeter(videos=True)
    seen = [meter(stage, f) for stage in ("depth", "load", "preprocess", "ldi", "inpaint",
                                          "mesh", "save", "zip", "video", "rezip")
            for f in (0.0, 0.5, 1.0)]
    values = [v for v, _ in seen]
    assert values == sorted(values) and values[-1] == 1.0 and values[0] == 0.0
    assert meter("preprocess", 0.0) == seen[-1]  # a late report does not move it back
    assert meter("video", 1.0)[1] == "zip"
    assert StageMeter(videos=False)("zip", 1.0)[0] == 1.0


def test_a_request_yields_the_3d_photo_then_its_videos(upload, tmp_path):
    photo, depth = upload
    folder = tmp_path / "request"
    folder.mkdir()
    reports = []
    options = JobOptions(size=0, paths=("swing",))
    first, final = run_job(photo, folder, options=options, depth=depth, name=photo.name,
                           progress=lambda f, label: reports.append((f, label)))
    assert first.videos == () and "rendering the videos" in first.summary
    assert final.videos == (folder / "out" / "video" / "swing.mp4",)
    assert final.videos[0].stat().st_size > 1000
    assert final.size == (96, 64) and final.zip.name == "two_planes-3d.zip"
    assert str(tmp_path) not in final.summary and "depth.png" in final.summary
    check_glb(final.glb)
    assert first.splats == final.splats == folder / "out" / "splats.spz"
    ldi, _ = load_npz(final.out / "photo3d.npz")
    assert len(read_spz(final.splats)) == len(build_splats(ldi))  # adaptive, the default
    with zipfile.ZipFile(final.zip) as z:
        assert {"video/swing.mp4", "depth_preview.png", "splats.spz"} <= set(z.namelist())
        assert z.getinfo("splats.spz").compress_type == zipfile.ZIP_STORED  # gzip already
    with Image.open(final.depth_preview) as preview:
        assert preview.size == (96, 64) and preview.mode == "RGB"
    values = [f for f, _ in reports]
    assert values == sorted(values) and values[-1] == 1.0
    assert {"inpaint", "video", "zip"} <= {label for _, label in reports}


def test_every_warning_make_prints_is_in_the_result(upload, tmp_path, monkeypatch):
    """A 16-bit colour PNG read without OpenCV (make prints a warning) and a photo
    smaller than the working size (make prints a note): both reach the status."""
    photo, depth = upload
    wide = photo.with_name("wide.png")
    pixels = (np.asarray(Image.open(photo), np.uint16) * 257)[..., :3]
    _write_png16(wide, pixels)
    monkeypatch.setitem(sys.modules, "cv2", None)  # as on a machine without OpenCV
    folder = tmp_path / "request"
    folder.mkdir()
    with pytest.warns(UserWarning, match="16-bit colour PNG read at 8 bits"):
        (result,) = run_job(wide, folder, options=JobOptions(size=256, videos=False),
                            depth=depth, name=wide.name)
    assert any("wide.png: 16-bit colour PNG read at 8 bits" in w for w in result.warnings)
    assert result.notes == ("the photo is 96x64; it is upscaled to a 256x171 working size "
                            "(size 0 keeps its size)",)
    status = result.status().splitlines()
    assert status[0].startswith("3D photo made in")
    assert status[1].startswith("warning: wide.png: 16-bit colour PNG read at 8 bits (full "
                                "precision needs OpenCV")
    assert status[-1] == "note: " + result.notes[0]
    assert str(tmp_path) not in status


def _write_png16(path: Path, rgb: np.ndarray) -> None:
    """A 16-bit RGB PNG (Pillow cannot write one), written with the standard library."""
    import struct
    import zlib

    h, w, _ = rgb.shape
    rows = b"".join(b"\0" + rgb[y].astype(">u2").tobytes() for y in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, 2,
                                                                       0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def test_a_stop_leaves_no_partial_output(upload, tmp_path):
    photo, depth = upload
    folder = tmp_path / "request"
    folder.mkdir()
    cancel = threading.Event()

    def progress(fraction, label):
        if label == "inpaint":
            cancel.set()

    with pytest.raises(JobCancelled):
        list(run_job(photo, folder, options=JobOptions(size=0), depth=depth,
                     progress=progress, cancel=cancel))
    assert [p.name for p in folder.iterdir() if p.name.startswith((".out", "out"))] == []


@pytest.fixture
def runner(upload, tmp_path):
    warm = Warmup(tmp_path)
    warm.skip()
    workspace = Workspace(tmp_path / "work", ttl=60)
    yield Runner(workspace, warm, upload_root=upload[0].parent.parent, max_bytes=10**6)
    workspace.close()


class Events:
    """What :meth:`Runner.submit` tells its listener, and a cancel on a chosen label."""

    def __init__(self, cancel_on: str | None = None) -> None:
        self.seen: list[tuple[str, object]] = []
        self.cancel_on = cancel_on
        self.cancel: threading.Event | None = None
        self.making: list[int] = []
        self.runner: Runner | None = None

    def __call__(self, kind, value) -> None:
        self.seen.append((kind, value))
        if self.runner is not None:
            self.making.append(self.runner.making)
        if kind == "progress" and value[1] == self.cancel_on and self.cancel is not None:
            self.cancel.set()

    def end(self):
        return self.seen[-1] if self.seen and self.seen[-1][0] in ("done", "error") else None


def test_a_cancelled_request_stops_and_its_folder_is_removed(runner, upload):
    photo, depth = upload
    events = Events(cancel_on="inpaint")
    events.cancel = runner.submit(str(photo), depth=str(depth), listener=events,
                                  options=JobOptions(size=0, paths=("swing",)))
    assert wait_for(lambda: events.end() is not None, timeout=120)
    kind, err = events.end()
    assert kind == "error" and str(err) == "the request was cancelled"
    assert not [e for e in events.seen if e[0] == "result"]  # stopped before the 3D photo
    assert list(runner.workspace.root.glob("request-*")) == []  # removed at once
    assert runner.making == 0


def test_a_cancel_stops_only_its_own_request_and_places_are_never_exceeded(runner, upload):
    photo, depth = upload
    first, second = Events(cancel_on="inpaint"), Events()
    first.runner = second.runner = runner
    options = JobOptions(size=0, videos=False)
    first.cancel = runner.submit(str(photo), depth=str(depth), listener=first, options=options)
    runner.submit(str(photo), depth=str(depth), listener=second, options=options)
    assert wait_for(lambda: first.end() and second.end(), timeout=120)
    assert first.end()[0] == "error" and second.end() == ("done", None)
    assert [k for k, _ in second.seen].count("result") == 1
    assert max(first.making + second.making) == 1  # one worker: never two photos at once
    assert len(list(runner.workspace.root.glob("request-*"))) == 1  # the second's only


def test_the_server_stopping_stops_every_request(runner, upload):
    photo, depth = upload
    events = Events()
    events.cancel = runner.submit(str(photo), depth=str(depth), listener=events,
                                  options=JobOptions(size=0, paths=("swing",)))
    assert wait_for(lambda: runner.making == 1, timeout=60)
    assert runner.stop(timeout=60)
    assert events.end()[0] == "error" and "the server is stopping" in str(events.end()[1])
    with pytest.raises(RequestError, match="the server is stopping"):
        list(runner.run(str(photo), options=JobOptions(), depth=str(depth)))


def test_the_learned_fill_runs_the_default_weights(runner, upload, tmp_path, monkeypatch):
    torch = pytest.importorskip("torch")
    import json

    import photo3d.inpaint.learned
    from photo3d.nets import build_net, save_safetensors

    folder = tmp_path / "authors"  # stands in for the authors' weights in the cache
    folder.mkdir()
    torch.manual_seed(0)
    for kind, cfg in {"edge": dict(width=0.125, blocks=1), "depth": dict(levels=3, width=0.125),
                      "color": dict(levels=3, width=0.125)}.items():
        save_safetensors(build_net(kind, **cfg), folder / f"{kind}.safetensors")
    asked = []
    monkeypatch.setattr(photo3d.inpaint.learned, "default_weights",
                        lambda *, progress=None: asked.append(progress) or folder)
    photo, depth = upload
    (result,) = runner.run(str(photo), options=JobOptions(fill="learned", size=0, videos=False),
                           depth=str(depth))
    meta = json.loads((result.out / "config.json").read_text())
    assert meta["inpainter"]["name"] == "learned" and len(asked) == 1
    assert meta["inpainter"]["weights"] == str(folder.resolve())


def test_the_learned_fill_offline_is_one_line_without_the_servers_folders(
        runner, upload, monkeypatch):
    import photo3d.inpaint.learned

    def offline(*, progress=None):
        raise InputError("cannot download https://example.org/edge-model.pth: no route "
                         f"(offline?); put the authors' files into {upload[0].parent}")

    monkeypatch.setattr(photo3d.inpaint.learned, "default_weights", offline)
    photo, depth = upload
    with pytest.raises(RequestError) as err:
        list(runner.run(str(photo), options=JobOptions(fill="learned"), depth=str(depth)))
    message = str(err.value)
    assert message.startswith("the learned fill needs the authors' weights (about 460 MB), "
                              "which this server cannot download now (offline?)")
    assert str(upload[0].parent) not in message and "\n" not in message


def test_a_cached_weights_file_that_is_not_the_authors_is_said_to_the_client(
        runner, upload, tmp_path, monkeypatch):
    pytest.importorskip("torch")
    cache = tmp_path / "server cache"
    (cache / "authors").mkdir(parents=True)
    (cache / "authors" / "edge-model.pth").write_bytes(b"someone else's edge net")
    monkeypatch.setenv("PHOTO3D_CACHE", str(cache))
    monkeypatch.setenv("PHOTO3D_AUTHORS_URL", (tmp_path / "nowhere").as_uri())
    photo, depth = upload
    with pytest.raises(RequestError) as err:
        list(runner.run(str(photo), options=JobOptions(fill="learned"), depth=str(depth)))
    message = str(err.value)
    assert message.startswith("the learned fill's weights file authors/edge-model.pth in "
                              "this server's photo3d cache")
    assert "SHA-256 checksum does not match" in message and "delete it" in message
    assert "offline" not in message and str(cache) not in message and "\n" not in message
    assert (cache / "authors" / "edge-model.pth").read_bytes() == b"someone else's edge net"


def test_errors_are_one_line_without_the_servers_folders(runner, upload):
    photo, depth = upload
    depth.write_bytes(b"\x89PNG\r\n\x1a\n garbage")
    with pytest.raises(RequestError) as err:
        list(runner.run(str(photo), options=JobOptions(size=0), depth=str(depth)))
    message = str(err.value)
    assert "depth.png" in message and str(depth.parent) not in message
    assert "\n" not in message


def test_a_file_the_server_did_not_receive_is_never_read(runner, tmp_path):
    secret = tmp_path / "secret.png"
    secret.write_bytes(b"secret")
    with pytest.raises(RequestError, match="the photo was not uploaded to this server"):
        list(runner.run(str(secret), options=JobOptions()))


def test_depth_and_right_view_together_are_refused(runner, upload):
    photo, depth = upload
    with pytest.raises(RequestError, match="give a depth map or a right view, not both"):
        list(runner.run(str(photo), options=JobOptions(), depth=str(depth), right=str(photo)))
