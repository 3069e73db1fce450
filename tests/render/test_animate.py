"""render_video: frames in order, errors reach the caller, no partial file."""

from __future__ import annotations

import numpy as np
import pytest

from photo3d.errors import OutputError
from photo3d.mesh.full import build_mesh
from photo3d.render.animate import VideoSpec, path_cameras, render_frames, render_video
from photo3d.render.renderer import Renderer, RenderSettings
from photo3d.stages.ldi import from_image

pytest.importorskip("av")
from videoprobe import decode  # noqa: E402


@pytest.fixture(scope="module")
def scene():
    yy, xx = np.mgrid[0:32, 0:48] / 8.0
    image = np.stack([0.5 + 0.4 * np.sin(xx), 0.5 + 0.4 * np.cos(yy), 0.3 + 0.0 * xx], 2)
    depth = 1.0 + 0.1 * xx + 0.05 * yy
    ldi = from_image(image.astype(np.float32), depth.astype(np.float32))
    return ldi, Renderer(build_mesh(ldi), RenderSettings(backend="numba", ssaa=1))


def test_frames_are_encoded_in_order(tmp_path, scene):
    ldi, renderer = scene
    spec = VideoSpec(path="circle", size=(48, 32), frames=6, fps=10)
    out = render_video(renderer, ldi, spec, tmp_path / "circle.mp4")
    expected = list(render_frames(renderer, path_cameras(ldi, spec)))
    _, decoded = decode(out)
    assert len(decoded) == 6
    errors = [[np.abs(d.astype(int) - e).mean() for e in expected] for d in decoded]
    assert [int(np.argmin(row)) for row in errors] == list(range(6))
    assert max(min(row) for row in errors) < 6  # lossy H.264 of a 48x32 frame


def test_encoder_error_reaches_the_caller_and_leaves_no_file(tmp_path, scene, monkeypatch):
    from photo3d.io import video

    ldi, renderer = scene
    written = []
    original = video.VideoWriter.write

    def failing_write(self, frame):
        if len(written) == 3:
            raise OutputError("disk full")
        written.append(frame)
        original(self, frame)

    monkeypatch.setattr(video.VideoWriter, "write", failing_write)
    spec = VideoSpec(path="swing", size=(48, 32), frames=8, fps=10)
    with pytest.raises(OutputError, match="disk full"):
        render_video(renderer, ldi, spec, tmp_path / "swing.mp4")
    assert len(written) == 3 and list(tmp_path.iterdir()) == []


def test_render_error_leaves_no_file(tmp_path, scene, monkeypatch):
    ldi, renderer = scene
    calls = []
    original = renderer.render

    def failing_render(camera):
        calls.append(camera)
        if len(calls) == 4:
            raise RuntimeError("boom")
        return original(camera)

    monkeypatch.setattr(renderer, "render", failing_render)
    spec = VideoSpec(path="zoom-in", size=(48, 32), frames=8, fps=10)
    with pytest.raises(RuntimeError, match="boom"):
        render_video(renderer, ldi, spec, tmp_path / "zoom.mp4")
    assert list(tmp_path.iterdir()) == []


def test_frames_rendered_at_once_are_those_of_one_thread(scene, monkeypatch):
    ldi, renderer = scene
    if renderer.frame_workers() < 2:
        pytest.skip("numba has one thread or no thread-safe threading layer here")
    cameras = path_cameras(ldi, VideoSpec(path="swing", size=(48, 32), frames=7))
    threads = []
    original = renderer.render

    def recording_render(camera):
        import threading

        threads.append(threading.current_thread().name)
        return original(camera)

    monkeypatch.setattr(renderer, "render", recording_render)
    at_once = list(render_frames(renderer, cameras, stereo="sbs"))
    assert len({name for name in threads if name.startswith("photo3d-frame")}) == 2
    monkeypatch.setattr(renderer, "frame_workers", lambda: 1)
    one = list(render_frames(renderer, cameras, stereo="sbs"))
    assert len(at_once) == len(one) == 7
    assert all(np.array_equal(a, b) for a, b in zip(at_once, one, strict=True))


def _frame_threads() -> set:
    import threading

    return {t for t in threading.enumerate() if t.name.startswith("photo3d-frame")}


def test_frames_left_unread_stop_the_workers(scene):
    ldi, renderer = scene
    before = _frame_threads()
    cameras = path_cameras(ldi, VideoSpec(path="circle", size=(48, 32), frames=30))
    frames = render_frames(renderer, cameras)
    next(frames)
    assert renderer.frame_workers() == 1 or _frame_threads() - before
    frames.close()
    assert _frame_threads() - before == set()


def test_a_failed_video_stops_the_frame_workers(tmp_path, scene, monkeypatch):
    from photo3d.io import video

    ldi, renderer = scene
    before = _frame_threads()

    def failing_write(self, frame):
        raise OutputError("disk full")

    monkeypatch.setattr(video.VideoWriter, "write", failing_write)
    with pytest.raises(OutputError, match="disk full") as caught:
        render_video(renderer, ldi, VideoSpec(path="swing", size=(48, 32), frames=20),
                     tmp_path / "swing.mp4")
    # the error's traceback holds render_video's frames: closed all the same
    assert caught.value.__traceback__ is not None
    assert _frame_threads() - before == set()
