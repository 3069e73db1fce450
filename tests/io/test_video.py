"""Tests of photo3d.io.video, checked with an independent reader.

Videos are written with PyAV and read back with the ffmpeg binary that ships in the
``imageio-ffmpeg`` wheel (a separate FFmpeg build), plus a byte-level MP4 box walk
and Pillow for the GIF loop flag.
"""

from __future__ import annotations

import struct
import sys

import numpy as np
import pytest
from PIL import Image

from photo3d.errors import ConfigError, InputError, OutputError
from photo3d.io.video import VideoWriter, video_formats

pytest.importorskip("av")
from videoprobe import decode, frame_count  # noqa: E402

W, H, N, FPS = 64, 48, 48, 24


def write_video(path, frames, *, fps: float = 30, quality: int | None = None):
    """``frames`` (all one size) written with one :class:`VideoWriter`; its path."""
    frames = [np.asarray(f) for f in frames]
    with VideoWriter(path, fps=fps, size=(frames[0].shape[1], frames[0].shape[0]),
                     quality=quality) as writer:
        for frame in frames:
            writer.write(frame)
    return writer.path


def moving_bar(n: int = N, height: int = H, width: int = W) -> list[np.ndarray]:
    """``n`` frames ``(height, width, 3) uint8``: a smooth colour gradient with a bright
    Gaussian bar (sigma 2 px) whose centre moves right by 1 px per frame, from x = 8."""
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    base = np.stack(
        [0.2 + 0.3 * xx / width, 0.25 + 0.3 * yy / height, 0.4 + 0.1 * np.sin(xx / 9)], axis=2
    )
    frames = []
    for i in range(n):
        bar = 0.4 * np.exp(-0.5 * ((xx - bar_centre(i)) / 2.0) ** 2)
        frames.append(np.round(255 * (base + bar[:, :, None])).astype(np.uint8))
    return frames


def bar_centre(i: int) -> float:
    return 8.0 + i


def mean_abs_error(decoded: list[np.ndarray], written: list[np.ndarray]) -> float:
    assert len(decoded) == len(written)
    return float(
        np.mean(
            [np.abs(d.astype(np.float32) - w).mean() for d, w in zip(decoded, written, strict=True)]
        )
    )


def top_level_boxes(path) -> list[str]:
    """Names of the top-level ISO-BMFF boxes of an MP4, in file order."""
    data, names, pos = path.read_bytes(), [], 0
    while pos + 8 <= len(data):
        size, name = struct.unpack(">I4s", data[pos : pos + 8])
        if size == 1:
            size = struct.unpack(">Q", data[pos + 8 : pos + 16])[0]
        names.append(name.decode("latin-1"))
        pos += size if size else len(data)
    return names


def test_mp4_is_h264_yuv420p_faststart_with_frames_in_order(tmp_path):
    frames = moving_bar()
    path = write_video(tmp_path / "path.mp4", frames, fps=FPS)
    assert path == tmp_path / "path.mp4"
    meta, decoded = decode(path)
    assert meta["codec"] == "h264"
    assert meta["pix_fmt"] == "yuv420p(tv, bt709, progressive)"
    assert meta["size"] == (W, H)
    assert meta["fps"] == pytest.approx(FPS)
    assert frame_count(path) == N
    boxes = top_level_boxes(path)
    assert boxes.index("moov") < boxes.index("mdat")  # +faststart
    assert mean_abs_error(decoded, frames) < 6
    columns = [d.astype(np.float32).mean(axis=(0, 2)) for d in decoded]
    centres = [np.argmax(c) for c in columns]
    assert np.all(np.diff(centres) > 0)
    np.testing.assert_allclose(centres, [bar_centre(i) for i in range(N)], atol=1)


def test_webm_is_vp9(tmp_path):
    frames = moving_bar()
    path = write_video(tmp_path / "path.webm", frames, fps=FPS)
    meta, decoded = decode(path)
    assert meta["codec"] == "vp9"
    assert meta["pix_fmt"] == "yuv420p(tv, bt709)"
    assert meta["fps"] == pytest.approx(FPS)
    assert meta["size"] == (W, H)
    assert frame_count(path) == N
    assert mean_abs_error(decoded, frames) < 8


@pytest.mark.parametrize("suffix", [".mp4", ".webm"])
def test_saturated_colours_survive_the_yuv_matrix(tmp_path, suffix):
    # A BT.601 / BT.709 mix-up between encoding and the stream's colour tags moves
    # saturated colours by 10-40 levels; a correct round trip keeps them within a few.
    colours = np.array([[230, 20, 20], [20, 200, 40], [30, 40, 220], [128, 128, 128]], np.uint8)
    frame = np.repeat(np.repeat(colours[None], 32, axis=0), 16, axis=1)  # (32, 64, 3)
    path = write_video(tmp_path / f"colours{suffix}", [frame] * 4, fps=FPS)
    _, decoded = decode(path)
    for k, colour in enumerate(colours):
        block = decoded[-1][8:24, 16 * k + 4 : 16 * k + 12].reshape(-1, 3).mean(axis=0)
        np.testing.assert_allclose(block, colour, atol=4, err_msg=f"colour {colour}")


def test_gif_loops_with_every_frame_and_roughly_right_colours(tmp_path):
    frames = moving_bar()
    path = write_video(tmp_path / "path.gif", frames, fps=FPS)
    meta, decoded = decode(path)
    assert meta["codec"] == "gif"
    assert meta["size"] == (W, H)
    assert frame_count(path) == N
    assert len(decoded) == N
    assert mean_abs_error(decoded, frames) < 8
    centres = [np.argmax(d.astype(np.float32).mean(axis=(0, 2))) for d in decoded]
    np.testing.assert_allclose(centres, [bar_centre(i) for i in range(N)], atol=1)
    with Image.open(path) as gif:
        assert gif.info["loop"] == 0  # forever
        assert gif.n_frames == N
    assert b"NETSCAPE2.0" in path.read_bytes()[:2048]


def test_gif_takes_odd_sizes_and_fewer_frames_than_the_palette_needs(tmp_path):
    frames = moving_bar(n=3, height=21, width=33)
    path = write_video(tmp_path / "short.gif", frames, fps=10)
    meta, decoded = decode(path)
    assert meta["size"] == (33, 21)
    assert len(decoded) == 3
    assert mean_abs_error(decoded, frames) < 8


def test_gif_writer_copies_frames_when_the_caller_reuses_its_buffer(tmp_path):
    frames = moving_bar(n=12)
    buffer = np.empty_like(frames[0])
    with VideoWriter(tmp_path / "reuse.gif", fps=FPS, size=(W, H)) as writer:
        for frame in frames:
            buffer[:] = frame  # a renderer drawing every frame into one array
            writer.write(buffer)
    _, decoded = decode(tmp_path / "reuse.gif")
    centres = [np.argmax(d.astype(np.float32).mean(axis=(0, 2))) for d in decoded]
    np.testing.assert_allclose(centres, [bar_centre(i) for i in range(12)], atol=1)


def test_float_frames_encode_exactly_like_their_uint8_rounding(tmp_path):
    frames = moving_bar(n=8)
    frames[0][0, :2] = [[255, 0, 128], [1, 254, 7]]
    floats = [f.astype(np.float32) / 255 for f in frames]
    floats[0][0, 0] = [1.2, -0.1, 128.4 / 255]  # out of range: clipped; 128.4 rounds to 128
    floats[0][0, 1] = [0.6 / 255, 253.6 / 255, 6.5001 / 255]  # rounds, not truncates
    _, from_uint8 = decode(write_video(tmp_path / "uint8.gif", frames, fps=FPS))
    _, from_float = decode(write_video(tmp_path / "float.gif", floats, fps=FPS))
    np.testing.assert_array_equal(from_float, from_uint8)


def test_lower_quality_makes_a_smaller_file(tmp_path):
    frames = moving_bar()
    good = write_video(tmp_path / "good.mp4", frames, fps=FPS, quality=10)
    poor = write_video(tmp_path / "poor.mp4", frames, fps=FPS, quality=40)
    assert poor.stat().st_size < 0.7 * good.stat().st_size


def test_odd_size_is_refused_for_yuv420p(tmp_path):
    with pytest.raises(OutputError, match="even"):
        VideoWriter(tmp_path / "odd.mp4", size=(63, 48))
    with pytest.raises(OutputError, match="even"):
        write_video(tmp_path / "odd.webm", moving_bar(n=2, width=64, height=47))
    assert list(tmp_path.iterdir()) == []


def test_unknown_extension_names_the_supported_ones(tmp_path):
    with pytest.raises(OutputError, match=r"\.avi.*\.mp4, \.webm, \.gif"):
        VideoWriter(tmp_path / "clip.avi", size=(W, H))
    assert set(video_formats()) == {".mp4", ".webm", ".gif"}


@pytest.mark.parametrize(
    "frame",
    [
        np.zeros((H, W + 2, 3), np.uint8),
        np.zeros((H, W), np.uint8),
        np.zeros((H, W, 4), np.uint8),
        np.zeros((H, W, 3), np.uint16),
    ],
    ids=["width", "grey", "rgba", "uint16"],
)
def test_wrong_frame_is_an_input_error_and_leaves_no_file(tmp_path, frame):
    with pytest.raises(
        InputError,
        match=rf"frame 1 has shape \({frame.shape[0]}, .*expected "
        rf"\({H}, {W}, 3\)",
    ):
        with VideoWriter(tmp_path / "bad.mp4", fps=FPS, size=(W, H)) as writer:
            writer.write(moving_bar(n=1)[0])
            writer.write(frame)
    assert list(tmp_path.iterdir()) == []


def test_non_finite_float_frame_is_an_input_error(tmp_path):
    frame = np.full((H, W, 3), np.nan, np.float32)
    with pytest.raises(InputError, match="NaN"):
        write_video(tmp_path / "nan.mp4", [frame])


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_exception_inside_with_keeps_the_old_file_and_no_temp(tmp_path, suffix):
    target = tmp_path / f"clip{suffix}"
    target.write_bytes(b"previous video")
    with pytest.raises(RuntimeError, match="render failed"):
        with VideoWriter(target, fps=FPS, size=(W, H)) as writer:
            for frame in moving_bar(n=12):
                writer.write(frame)
            raise RuntimeError("render failed")
    assert list(tmp_path.iterdir()) == [target]
    assert target.read_bytes() == b"previous video"


def test_the_video_is_written_to_a_hidden_part_file_and_a_failed_rename_keeps_the_old(
        tmp_path, monkeypatch):
    from photo3d.files.temps import is_temp_of

    target = tmp_path / "clip.mp4"
    target.write_bytes(b"previous video")
    with pytest.raises(OutputError, match="clip.mp4: Input/output error"):
        with VideoWriter(target, fps=FPS, size=(W, H)) as writer:
            for frame in moving_bar(n=4):
                writer.write(frame)
            hidden = [p.name for p in tmp_path.iterdir() if p != target]
            assert len(hidden) == 1 and hidden[0].endswith(".tmp.part")
            assert is_temp_of(hidden[0], "clip.mp4")

            def refuse(src, dst):
                raise OSError(5, "Input/output error")

            monkeypatch.setattr("os.replace", refuse)
    assert list(tmp_path.iterdir()) == [target]
    assert target.read_bytes() == b"previous video"


def test_an_unwritable_location_is_refused_before_any_frame():
    with pytest.raises(OutputError, match="cannot write /proc/clip.mp4"):
        VideoWriter("/proc/clip.mp4", size=(W, H))


def test_a_writer_never_closed_leaves_no_temp_when_the_process_exits(tmp_path):
    import subprocess

    code = ("import sys, numpy as np\n"
            "from photo3d.io.video import VideoWriter\n"
            f"w = VideoWriter(sys.argv[1], size=({W}, {H}))\n"
            f"w.write(np.zeros(({H}, {W}, 3), np.uint8))\n"
            "sys.exit(3)")
    done = subprocess.run([sys.executable, "-c", code, str(tmp_path / "clip.mp4")],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 3, done.stderr
    assert list(tmp_path.iterdir()) == []


def test_successful_close_replaces_the_old_file_and_leaves_no_temp(tmp_path):
    target = tmp_path / "clip.mp4"
    target.write_bytes(b"previous video")
    with VideoWriter(target, fps=FPS, size=(W, H)) as writer:
        for frame in moving_bar(n=5):
            writer.write(frame)
    assert writer.count == 5
    assert list(tmp_path.iterdir()) == [target]
    assert frame_count(target) == 5
    with pytest.raises(OutputError, match="closed"):
        writer.write(moving_bar(n=1)[0])


def test_no_frames_is_an_input_error_and_leaves_no_file(tmp_path):
    with pytest.raises(InputError, match="no frames"):
        with VideoWriter(tmp_path / "empty.gif", size=(W, H)):
            pass
    assert list(tmp_path.iterdir()) == []


def test_bad_settings(tmp_path):
    with pytest.raises(OutputError, match="does not exist"):
        VideoWriter(tmp_path / "missing" / "clip.mp4", size=(W, H))
    with pytest.raises(ConfigError, match="fps"):
        VideoWriter(tmp_path / "clip.mp4", fps=0, size=(W, H))
    with pytest.raises(ConfigError, match="50 fps"):
        VideoWriter(tmp_path / "clip.gif", fps=60, size=(W, H))
    with pytest.raises(ConfigError, match=r"0\.\.51"):
        VideoWriter(tmp_path / "clip.mp4", size=(W, H), quality=60)
    with pytest.raises(OutputError, match="encoder 'nope'"):
        VideoWriter(tmp_path / "clip.mp4", size=(W, H), codec="nope")
    assert list(tmp_path.iterdir()) == []


def test_missing_pyav_names_the_install_command(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "av", None)
    with pytest.raises(ImportError, match="pip install av"):
        VideoWriter(tmp_path / "clip.mp4", size=(W, H))


def _swscale_yuv420(rgb: np.ndarray) -> np.ndarray:
    import av

    frame = av.VideoFrame.from_ndarray(rgb, format="rgb24")
    return frame.reformat(format="yuv420p", src_color_range="JPEG", dst_color_range="MPEG",
                          dst_colorspace="ITU709").to_ndarray()  # fmt: skip


def test_yuv_luma_and_flat_chroma_agree_with_swscale():
    from photo3d.io._yuv import rgb_to_yuv420

    rgb = (np.random.default_rng(3).random((32, 48, 3)) * 256).astype(np.uint8)
    ours, ref = rgb_to_yuv420(rgb).astype(int), _swscale_yuv420(rgb).astype(int)
    assert ours.shape == ref.shape == (48, 48)
    assert np.abs(ours[:32] - ref[:32]).max() <= 1
    for colour in ([230, 20, 20], [20, 200, 40], [30, 40, 220], [0, 0, 0], [255, 255, 255]):
        flat = np.broadcast_to(np.array(colour, np.uint8), (8, 12, 3)).copy()
        ours, ref = rgb_to_yuv420(flat).astype(int), _swscale_yuv420(flat).astype(int)
        assert np.abs(ours - ref).max() <= 1, colour


def test_yuv_is_bt709_limited_range_with_2x2_mean_chroma():
    from photo3d.io._yuv import rgb_to_yuv420

    rgb = (np.random.default_rng(4).random((6, 10, 3)) * 256).astype(np.uint8)
    r, g, b = (rgb[..., k].astype(np.float64) for k in range(3))
    luma = 0.2126 * r + 0.7152 * g + 0.0722 * b
    expected = [np.floor(16 + 219 / 255 * luma + 0.5)]
    for diff, scale in ((b - luma, 1.8556), (r - luma, 1.5748)):
        mean = diff.reshape(3, 2, 5, 2).mean(axis=(1, 3))
        expected.append(np.floor(128 + 224 / 255 / scale * mean + 0.5))
    yuv = rgb_to_yuv420(rgb).astype(np.float64)
    np.testing.assert_array_equal(yuv[:6], expected[0])
    chroma = np.concatenate([e.ravel() for e in expected[1:]])
    np.testing.assert_array_equal(yuv[6:].ravel(), chroma)
