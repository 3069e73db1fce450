"""One request without the web server: the client's options are checked, the photo
is made through ``make``'s path into the request's folder (the 3D photo first, then
its videos), errors are one line without the server's folders, and a stop removes
the partial output."""

from __future__ import annotations

import threading
import zipfile

import numpy as np
import pytest
from conftest import two_planes
from PIL import Image
from uikit import check_glb

from photo3d.errors import ConfigError
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
    (dict(size=100_000), "size must be 0 (the photo's size) or 64..4096"),
    (dict(size=10.5), "size must be 0"),
    (dict(fill="../../evil"), "unknown fill '../../evil'"),
    (dict(source="file"), "unknown depth source 'file'"),
    (dict(videos=True, paths=[]), "videos are on but no camera path is chosen"),
])
def test_options_a_client_may_not_choose(options, message):
    with pytest.raises(ConfigError) as err:
        JobOptions(**options)
    assert str(err.value).startswith(message)


def test_the_options_become_makes_options():
    make = JobOptions(size=0, fill="structured", videos=False, ply=True).make_options()
    save = make.save
    assert (make.config.size, make.config.inpainter, save.videos, save.ply, save.glb,
            save.viewer) == (None, "structured", (), "binary", True, True)
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
    with zipfile.ZipFile(final.zip) as z:
        assert "video/swing.mp4" in z.namelist() and "depth_preview.png" in z.namelist()
    with Image.open(final.depth_preview) as preview:
        assert preview.size == (96, 64) and preview.mode == "RGB"
    values = [f for f, _ in reports]
    assert values == sorted(values) and values[-1] == 1.0
    assert {"inpaint", "video", "zip"} <= {label for _, label in reports}


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
