"""Small files of many pixels and sizes that would exhaust memory (issue 36, defects 3
and 4): a photo far larger than the working size is decoded reduced (``make``, the UI
through :func:`photo3d.folder.make_folder`, ``eval --heldout``); what a reader or
``render`` would need beyond the available memory is refused in one line, before the
work. The available memory is made small with monkeypatch; no test needs more than a
few hundred MB itself."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import test_robustness
from memtrace import spy_read_npy, traced_peak
from PIL import Image
from test_robustness import FAST, run


@pytest.fixture
def photos(tmp_path, monkeypatch) -> Path:
    """``tmp/photos/{a.png, a.npy, notes.txt}``, the current folder ``tmp``
    (``test_robustness.photos``)."""
    return test_robustness.photos.__wrapped__(tmp_path, monkeypatch)


def _large_pair(folder: Path, width: int = 4000, height: int = 3000) -> tuple[Path, Path]:
    """A constant photo of ``width x height`` with a darker square, as a small PNG, and
    its two-plane 16-bit depth PNG."""
    photo = np.full((height, width, 3), (200, 100, 50), np.uint8)
    photo[height // 3:2 * height // 3, width // 3:2 * width // 3] = 40
    depth = np.full((height, width), 1000, np.uint16)
    depth[:, width // 2:] = 3000
    Image.fromarray(photo).save(folder / "large.png")
    Image.fromarray(depth).save(folder / "large_depth.png")
    return folder / "large.png", folder / "large_depth.png"



# --- defect 3: a small file with many pixels ---------------------------------------------


def test_make_decodes_a_large_photo_reduced_and_says_nothing_of_it(photos, capsys,
                                                                   monkeypatch):
    """4000 x 3000 at --size 48: before, the photo was decoded to float32 (144 MB and
    copies), the depth too, and a photo above Pillow's limit printed its
    DecompressionBombWarning, also with -q (twice with a large depth map)."""
    photo, depth = _large_pair(photos)
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 10_000_000)  # 12M pixels: a "bomb"
    err, peak = traced_peak(lambda: run(capsys, "make", photo, "--depth", depth, "-o",
                                         "out", *FAST, status=0))
    assert err == ""  # no bomb warning, no "depth resampled" warning
    assert peak < 60e6, peak  # the depth map's 16-bit values and a copy: 48 MB
    config = json.loads((photos.parent / "out" / "config.json").read_text())
    assert config["config"]["size"] == 48


def test_make_folder_pairs_a_reduced_photo_with_its_full_size_depth(photos):
    from photo3d.config import Config
    from photo3d.folder import MakeOptions, make_folder
    from photo3d.save_options import SaveOptions

    photo, depth = _large_pair(photos, 2400, 1800)
    seen = {}
    options = MakeOptions(config=Config(size=64), save=SaveOptions(glb=False, ply=None,
                                                                    viewer=False))
    make_folder(photo, photos / "out", depth=depth, options=options,
                on_depth=lambda est, image: seen.update(est=est, image=image))
    est, image = seen["est"], seen["image"]
    assert image.shape == (96, 128, 3)  # io.images.decoded_shape((1800, 2400), 64)
    assert est.depth.shape == est.prepared.disparity.shape == image.shape[:2]
    assert est.warnings == ()  # the map has the file's size: resampled silently
    assert set(np.unique(est.depth)) == {1000.0, 3000.0}  # nearest: no mixed values


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs Linux's /proc")
def test_reading_a_large_photo_and_its_depth_stays_small(tmp_path):
    """Peak resident memory (Pillow's buffers too) of a child process reading what
    ``make`` reads for a 6000 x 4500 photo and depth map at working size 64
    (:func:`photo3d.depth.sources.resolve_depth`, as ``make_folder`` calls it): before,
    1.04 GB; now about 190 MB, most of it the libraries. (``VmHWM``, not
    ``ru_maxrss``, which keeps the parent's size across fork and exec.)"""
    photo, depth = _large_pair(tmp_path, 6000, 4500)
    code = ("import re, sys; from photo3d.depth.sources import resolve_depth; "
            "est = resolve_depth(sys.argv[1], depth=sys.argv[2], working_size=64); "
            "status = open('/proc/self/status').read(); "
            "print(est.photo.shape, est.warnings, re.search(r'VmHWM:\\s*(\\d+)', status)[1])")
    done = subprocess.run([sys.executable, "-c", code, str(photo), str(depth)],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0 and done.stderr == "", done.stderr
    assert done.stdout.startswith("(96, 128, 3) ()"), done.stdout
    peak = int(done.stdout.split()[-1]) * 1024  # kB
    assert peak < 400e6, peak / 1e6


def test_eval_heldout_decodes_a_large_photo_reduced(tmp_path):
    from photo3d.eval.heldout_data import load_photo

    photo, _ = _large_pair(tmp_path)
    image, peak = traced_peak(lambda: load_photo(photo, 64))
    assert image.shape == (48, 64, 3)
    assert peak < 10e6, peak  # before: 144 MB of float32 and more


def test_a_photo_beyond_the_available_memory_is_one_line(photos, capsys, monkeypatch):
    """--size 0 keeps the whole photo: decoding it would need more than is available."""
    photo, depth = _large_pair(photos)
    monkeypatch.setattr("photo3d.io.limits.available_memory", lambda: 300_000_000)
    monkeypatch.setattr("photo3d.resources.available_memory", lambda: 10**12)  # make's own
    test_robustness.no_work.__wrapped__(monkeypatch)
    run(capsys, "make", photo, "--depth", depth, "-o", "out", "--size", "0", "--no-video",
        "-q", status=2, message="large.png: decoding its 4000x3000 pixels needs about")


def test_a_depth_map_beyond_the_available_memory_is_one_line(photos, capsys, monkeypatch):
    _, depth = _large_pair(photos)
    monkeypatch.setattr("photo3d.io.limits.available_memory", lambda: 30_000_000)
    monkeypatch.setattr("photo3d.resources.available_memory", lambda: 10**12)
    test_robustness.no_work.__wrapped__(monkeypatch)
    run(capsys, "make", photos / "a.png", "--depth", depth, "-o", "out", *FAST, status=2,
        message="large_depth.png: decoding its 4000x3000 pixels needs about")


# --- defect 4: render and the LDI reader -------------------------------------------------


def _saved_ldi(folder: Path, side: int) -> Path:
    """A 3D photo folder holding the trivial LDI of a constant ``side x side`` image."""
    from photo3d.io.npz import save_npz
    from photo3d.stages.ldi import from_image

    folder.mkdir()
    ldi = from_image(np.full((side, side, 3), 0.5, np.float32),
                     np.ones((side, side), np.float32))
    save_npz(ldi, folder / "photo3d.npz", meta={"config": {"size": side}})
    return folder


def test_an_ldi_beyond_the_available_memory_is_refused_before_reading(tmp_path, capsys,
                                                                      monkeypatch):
    """The file is small (constant arrays compress well) but declares 1M pixels: its
    arrays are never read when they need more memory than is available."""
    folder = _saved_ldi(tmp_path / "photo", 1000)
    monkeypatch.setattr("photo3d.io.limits.available_memory", lambda: 200_000_000)
    sizes = spy_read_npy(monkeypatch)
    run(capsys, "render", folder, "--still", "-q", status=2, root=tmp_path,
        message="decoding its 1,000,000 LDI pixels needs about 400 MB of memory but "
                "200 MB are available")
    assert sizes == [1 << 24]  # only the JSON header was read


@pytest.fixture
def no_rendering(monkeypatch):
    """Fail the test if anything is rendered."""
    class Refuse:
        def __init__(self, *args, **kwargs):
            raise AssertionError("rendered before the memory check")

    def refuse(*args, **kwargs):
        raise AssertionError("rendered before the memory check")

    monkeypatch.setattr("photo3d.render.renderer.Renderer", Refuse)
    monkeypatch.setattr("photo3d.output.write_videos", refuse)


@pytest.mark.parametrize(("extra", "message"), [
    (["--still"], "rendering 9000x9000 with --ssaa 2 needs about 16.5 GB of memory (frames: "
                  "16.2 GB of render --still's estimate) but 2.0 GB are available: use a "
                  "smaller --size (about 2914x2914 fits) or --ssaa 1"),
    (["--frames", "2"], "rendering 9000x9000 with --ssaa 2 needs about 37.9 GB of memory "
                        "(frames: 37.6 GB of render's estimate) but 2.0 GB are available: "
                        "use a smaller --size (about 1912x1912 fits) or --ssaa 1"),
    (["--still", "--ssaa", "1", "--stereo", "sbs"],  # two views
     "rendering 9000x9000 with --ssaa 1 needs about 23.0 GB of memory (frames: 22.7 GB of "
     "render --still's estimate) but 2.0 GB are available: use a smaller --size (about "
     "2462x2462 fits)"),
])
def test_render_refuses_a_size_beyond_the_available_memory(tmp_path, capsys, monkeypatch,
                                                           no_rendering, extra, message):
    folder = _saved_ldi(tmp_path / "photo", 64)
    monkeypatch.setattr("photo3d.resources.available_memory", lambda: 2_000_000_000)
    run(capsys, "render", folder, "--size", "9000x9000", *extra, "-q", status=2,
        root=tmp_path, message=message)


def test_render_refuses_an_ldi_too_large_to_render(tmp_path, capsys, monkeypatch,
                                                   no_rendering):
    folder = _saved_ldi(tmp_path / "photo", 200)
    monkeypatch.setattr("photo3d.resources.available_memory", lambda: 210_000_000)
    run(capsys, "render", folder, "--still", "-q", status=2, root=tmp_path,
        message="the 3D photo's 40,000 LDI pixels alone need 316 MB")


def test_the_size_render_suggests_fits():
    from photo3d.resources import check_render_memory, render_memory_estimate

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr("photo3d.resources.available_memory", lambda: 3_000_000_000)
        with pytest.raises(Exception, match=r"about (\d+)x(\d+) fits") as err:
            check_render_memory(2_000_000, (7680, 4320), ssaa=3, video=True)
        width, height = (int(v) for v in err.value.args[0].split("about ")[-1].split()[0]
                         .split("x"))
        assert abs(width / height - 16 / 9) < 0.01
        need = render_memory_estimate(2_000_000, (width, height), ssaa=3, video=True)
        assert 0.97 * 3e9 < need <= 3e9
        check_render_memory(2_000_000, (width, height), ssaa=3, video=True)
