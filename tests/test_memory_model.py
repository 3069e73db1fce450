"""One memory model per command (issue 45, item 3, and defects 7-10).

Each command's worst case, scaled down, runs in a child process; its peak resident
memory (the largest of the process tree's sampled sum and ``wait4``'s ``ru_maxrss``)
must stay within the estimate the command checks before the work
(:mod:`photo3d.resources`). Full-size runs: ``benchmarks/bench_memory.py``.

The defects' tests (each fails on the code before its fix) check that what would
fail after the work fails before it: a still's estimate bounds its peak (7), export's
estimate counts what each format holds (8), ``depth`` of a large photo is refused
from its header (9), ``splats.spz`` beyond SPZ's limit is refused before the work
(``make --export``, ``batch``, the UI, ``export``) and a full disk during ``export``
says so (10).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image
from test_robustness import run

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import _peak  # noqa: E402 - the measurement bench_memory.py makes too

import photo3d
from photo3d.config import Config

ROOT = Path(__file__).resolve().parent.parent
SRC = Path(photo3d.__file__).resolve().parents[1]
"""The children run the code under test (this process's)."""


# --- measuring a child's peak -------------------------------------------------------------


def peak(argv: list[str], *, cwd: Path, python: str | None = None) -> int:
    """Peak resident bytes of ``python -m photo3d argv`` (or of ``python -c SCRIPT``
    when ``python`` is given), which must succeed (``benchmarks/_peak.py``: its own
    ``ru_maxrss`` through a small launcher, or its process tree's sum, sampled)."""
    cmd = [sys.executable, "-c", python] if python else [sys.executable, "-m", "photo3d",
                                                           *argv]
    measured, status, err = _peak.peak(cmd, cwd=cwd, env={**os.environ, "PYTHONPATH": str(SRC)})
    assert status == 0, err
    return measured


def within(measured: int, estimate: int) -> None:
    """``measured <= estimate`` (the message gives both)."""
    assert measured <= estimate, (f"peak {measured / 1e6:.0f} MB > estimate "
                                  f"{estimate / 1e6:.0f} MB")


# --- inputs: the worst depth map (3x3 blocks of noise) -----------------------------------


def _photo_and_noise(folder: Path, h: int = 240, w: int = 320) -> tuple[Path, Path]:
    rng = np.random.default_rng(0)
    img = (rng.random((h, w, 3)) * 255).astype(np.uint8)
    Image.fromarray(img).save(folder / "photo.png")
    blocks = rng.random((h // 3 + 1, w // 3 + 1)).repeat(3, 0).repeat(3, 1)[:h, :w]
    np.save(folder / "noise.npy", blocks.astype(np.float32))
    return folder / "photo.png", folder / "noise.npy"


MAKE_SIZE = 320


@pytest.fixture(scope="module")
def noisy(tmp_path_factory) -> tuple[Path, int]:
    """``(folder, make's measured peak)``: a 3D photo of 3x3 blocks of noise at
    :data:`MAKE_SIZE` px (its LDI at ``make``'s limit), made with splats.spz."""
    root = tmp_path_factory.mktemp("noisy")
    photo, depth = _photo_and_noise(root)
    measured = peak(["make", str(photo), "--depth", str(depth), "-o", "out", "--size",
                     str(MAKE_SIZE), "--no-video", "--export", "splats.spz", "-q"], cwd=root)
    return root / "out", measured


def _ldi_pixels(folder: Path) -> int:
    from photo3d.io.npz import ldi_pixels

    return ldi_pixels(folder / "photo3d.npz")


# --- each command's peak within its estimate ---------------------------------------------


def test_make_stays_within_its_estimate(noisy):
    from photo3d.resources import memory_estimate

    folder, measured = noisy
    assert _ldi_pixels(folder) > 1.9 * 240 / 320 * MAKE_SIZE**2  # the LDI at its limit
    within(measured, memory_estimate((240, 320), Config(size=MAKE_SIZE), ("splats.spz",)))


def test_export_of_every_format_stays_within_its_estimate(noisy):
    from photo3d.resources import export_memory_estimate
    from photo3d.save_options import EXPORT_FORMATS

    folder, _ = noisy
    measured = peak(["export", str(folder), *EXPORT_FORMATS, "-q"], cwd=folder.parent)
    within(measured, export_memory_estimate(_ldi_pixels(folder), EXPORT_FORMATS))


@pytest.mark.parametrize("args", [["--still", "--size", "1600x1600", "--ssaa", "1"],
                                  ["--still", "--size", "1200x1200", "--ssaa", "2",
                                   "--stereo", "sbs"],
                                  ["--size", "640x640", "--frames", "3", "--path", "circle"]],
                         ids=["still", "still-stereo-ssaa2", "video"])
def test_render_stays_within_its_estimate(noisy, args):
    from photo3d.resources import render_memory_estimate

    folder, _ = noisy
    measured = peak(["render", str(folder), *args, "-q"], cwd=folder.parent)
    size = tuple(int(v) for v in args[args.index("--size") + 1].split("x"))
    ssaa = int(args[args.index("--ssaa") + 1]) if "--ssaa" in args else 2
    within(measured, render_memory_estimate(_ldi_pixels(folder), size, ssaa=ssaa,
                                            views=2 if "--stereo" in args else 1,
                                            video="--still" not in args))


def test_depth_stays_within_its_estimate(tmp_path):
    from photo3d.resources import depth_memory_estimate

    n = 2000
    rng = np.random.default_rng(0)
    img = (rng.random((n // 8, n // 8, 3)) * 255).astype(np.uint8).repeat(8, 0).repeat(8, 1)
    Image.fromarray(img).save(tmp_path / "p.png")
    d = np.full((n, n), 1000, np.uint16)
    d[:, n // 2:] = 3000
    Image.fromarray(d).save(tmp_path / "d.png")
    measured = peak(["depth", "p.png", "--depth", "d.png", "-o", "out.png"], cwd=tmp_path)
    within(measured, depth_memory_estimate((n, n)))


def test_batch_stays_within_its_estimate(tmp_path):
    from photo3d.resources.make import batch_estimate

    (tmp_path / "in").mkdir()
    (tmp_path / "depth").mkdir()
    for name in ("a", "b"):
        photo, depth = _photo_and_noise(tmp_path)
        photo.rename(tmp_path / "in" / f"{name}.png")
        depth.rename(tmp_path / "depth" / f"{name}.npy")
    measured = peak(["batch", "in", "--depth", "depth", "-o", "out", "--workers", "2",
                     "--size", "160", "--no-video", "-q"], cwd=tmp_path)
    within(measured, batch_estimate(Config(size=160), workers=2).bytes)


def test_the_ui_request_stays_within_its_estimate(tmp_path):
    from photo3d.resources import memory_estimate
    from photo3d.ui.job import SPLATS

    photo, depth = _photo_and_noise(tmp_path)
    (tmp_path / "request").mkdir()
    script = ("from pathlib import Path\n"
              "from photo3d.ui.job import JobOptions, run_job\n"
              "for _ in run_job(Path('photo.png'), Path('request'), depth=Path('noise.npy'),\n"
              "                 options=JobOptions(size=256, videos=False)):\n"
              "    pass\n")
    np.save(tmp_path / "noise.npy", np.load(depth))  # run_job reads a file
    measured = peak([], cwd=tmp_path, python=script)
    within(measured, memory_estimate((240, 320), Config(size=256), (SPLATS,)))


def test_train_stays_within_its_estimate(tmp_path):
    pytest.importorskip("torch")
    sys.path.insert(0, str(ROOT / "tests" / "train"))
    from trainkit import write_folder

    from photo3d.train.bounds import train_estimate
    from photo3d.train.trainer import TrainConfig

    write_folder(tmp_path)
    args = dict(size=32, region_size=64, batch=2, width=0.125, levels=3, blocks=1)
    measured = peak(["train", "depth", "--images", "images", "--depth", "depth", "--out",
                     "run", "--steps", "2", "--size", "32", "--region-size", "64",
                     "--batch", "2", "--width", "0.125", "--levels", "3", "--blocks", "1",
                     "--device", "cpu", "--threads", "1", "-q"], cwd=tmp_path)
    config = TrainConfig("depth", **args)
    within(measured, train_estimate(config, [(48, 64)], sources=3).bytes)


# --- defect 7: a still needs more than its check estimated -------------------------------


def test_a_still_is_estimated_as_a_still_not_as_a_video_frame():
    """6000x6000 at --ssaa 1 peaked at 3.7 GB against 2.7 GB: the still's full-size
    hole filling, image and PNG encoder were not counted (measured 2000-4000 px,
    benchmarks/RESULTS.md)."""
    from photo3d.resources import render_memory_estimate

    assert render_memory_estimate(100_000, (6000, 6000), ssaa=1) >= 3.7e9
    # the documented 9000x9000 example is refused on a machine without its peak
    assert render_memory_estimate(1_500_000, (9000, 9000), ssaa=2) >= 10e9


def test_a_magnified_still_stays_within_its_estimate(tmp_path):
    """The motorcycle with noise blocks at 64 px as a 2000x2000 still: the magnified
    view leaves holes wider than the near fill reaches and the pyramid fill runs at
    full size (696 MB measured; main estimated 474 MB: 68 bytes per pixel)."""
    from photo3d.resources import render_memory_estimate
    from photo3d.sample import motorcycle

    sample = motorcycle()
    Image.fromarray(np.round(sample.left * 255).astype(np.uint8)).save(tmp_path / "left.png")
    h, w = sample.disparity.shape
    blocks = np.random.default_rng(0).random((h // 3 + 1, w // 3 + 1)).repeat(3, 0)
    np.save(tmp_path / "blocks.npy", blocks.repeat(3, 1)[:h, :w].astype(np.float32))
    peak(["make", "left.png", "--depth", "blocks.npy", "-o", "tiny", "--size", "64",
          "--no-video", "-q"], cwd=tmp_path)
    measured = peak(["render", "tiny", "--still", "--size", "2000x2000", "--ssaa", "1", "-q"],
                    cwd=tmp_path)
    within(measured, render_memory_estimate(_ldi_pixels(tmp_path / "tiny"), (2000, 2000),
                                            ssaa=1))


# --- defect 8: export checks only what loading photo3d.npz needs --------------------------


def test_export_counts_the_light_mesh_of_a_fragmented_ldi():
    """mesh.usdz of 3x3 blocks of noise at 1024 px (1.86M LDI pixels) peaked at 1.36 GB
    where the check allowed 1.13 GB (benchmarks/RESULTS.md, export)."""
    from photo3d.resources import export_memory_estimate

    assert export_memory_estimate(1_855_568, ["mesh.usdz"]) >= 1.36e9
    assert export_memory_estimate(1_855_568, ["quilt"]) >= 1.16e9


# --- defect 9: depth of a large photo ----------------------------------------------------


@pytest.fixture
def big_photo(tmp_path, monkeypatch) -> Path:
    """A 3000x3000 PNG of one colour (a small file), the current folder ``tmp_path``;
    decoding any photo fails the test."""
    Image.new("RGB", (3000, 3000), (120, 80, 40)).save(tmp_path / "big.png")
    d = np.full((3000, 3000), 1000, np.uint16)
    Image.fromarray(d).save(tmp_path / "d.png")
    monkeypatch.chdir(tmp_path)

    def decoded(*args, **kwargs):
        raise AssertionError("the photo was decoded before its memory was checked")

    monkeypatch.setattr("photo3d.io.images._read_pixels", decoded)
    return tmp_path / "big.png"


def test_depth_of_a_large_photo_is_refused_from_its_header(big_photo, capsys, monkeypatch):
    """The decoding check (48 bytes a pixel: 432 MB) passed; the depth at the photo's
    size, its checks and its PNGs took as much again (9.7 GB for 13000x13000)."""
    monkeypatch.setattr("photo3d.resources.available_memory", lambda: 600_000_000)
    monkeypatch.setattr("photo3d.io.limits.available_memory", lambda: 600_000_000)
    run(capsys, "depth", "big.png", "--depth", "d.png", "-o", "out.png", status=2,
        message="the depth map of a 3000x3000 photo needs about ")


# --- defect 10: what fails after the work fails before it --------------------------------


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if a photo is made or a 3D photo loaded; plenty of memory."""
    def work(*args, **kwargs):
        raise AssertionError("the work started before the request was checked")

    monkeypatch.setattr("photo3d.pipeline.make", work)
    monkeypatch.setattr("photo3d.batch.run_batch", work)
    monkeypatch.setattr("photo3d.export.load_npz", work)
    monkeypatch.setattr("photo3d.resources.available_memory", lambda: 10**13)
    monkeypatch.setattr("photo3d.io.limits.available_memory", lambda: 10**13)


@pytest.fixture
def square(tmp_path, monkeypatch) -> tuple[Path, Path]:
    """A 64x64 photo and its depth; the current folder ``tmp_path``."""
    rng = np.random.default_rng(0)
    Image.fromarray((rng.random((64, 64, 3)) * 255).astype(np.uint8)).save(
        tmp_path / "sq.png")
    np.save(tmp_path / "sq.npy", rng.random((64, 64)).astype(np.float32))
    monkeypatch.chdir(tmp_path)
    return tmp_path / "sq.png", tmp_path / "sq.npy"


def test_make_refuses_splats_spz_beyond_its_limit_before_the_work(square, no_work, capsys):
    """A square photo at --size 2400 can have 14.4M LDI pixels (2 per position of its
    2682x2682 lattice): before, make --export splats.spz failed after the whole make
    (207 s and 7.2 GB at the size reported), keeping nothing."""
    photo, depth = square
    run(capsys, "make", photo, "--depth", depth, "-o", "out", "--size", "2400",
        "--export", "splats.spz", "--no-video", "-q", status=2,
        message="splats.spz of a 2400x2400 working size can have up to 14,386,248 splats, "
                "more than the 10,000,000 an SPZ file holds: use --size 2000 or less")


def test_batch_refuses_splats_spz_beyond_its_limit_before_the_work(square, no_work, capsys):
    """At --size 2600 even a 16:9 photo can pass SPZ's limit: refused before any photo
    (a squarer photo at a smaller size is refused by its worker, at once)."""
    photo, _ = square
    run(capsys, "batch", photo.parent, "-o", "out", "--size", "2600", "--workers", "1",
        "--export", "splats.spz", "--no-video", "-q", status=2,
        message="splats.spz of --size 2600 can have up to 10,")


def test_a_ui_request_is_refused_before_the_work_when_its_splats_may_not_fit(square, no_work):
    """Every UI request writes splats.spz: a 2048 px request of a square photo failed
    after 181 s."""
    from photo3d.errors import ConfigError
    from photo3d.ui.job import JobOptions, run_job

    photo, depth = square
    (photo.parent / "request").mkdir()
    with pytest.raises(ConfigError, match="splats.spz of a 2048x2048 working size can have "
                                          "up to 10,469,888 splats"):
        next(run_job(photo, photo.parent / "request", depth=depth,
                     options=JobOptions(size=2048, videos=False)))


def test_export_refuses_dense_splats_spz_beyond_its_limit_before_loading(square, no_work,
                                                                          capsys, monkeypatch):
    photo, _ = square
    (photo.parent / "out").mkdir()
    (photo.parent / "out" / "photo3d.npz").write_bytes(b"stand-in")
    monkeypatch.setattr("photo3d.export.ldi_pixels", lambda path: 12_000_000)
    run(capsys, "export", "out", "splats.spz", "--splats", "dense", "-q", status=2,
        message="splats.spz of this 3D photo (dense) can have up to 12,000,000 splats, more "
                "than the 10,000,000 an SPZ file holds")


def test_export_refuses_a_disk_without_room_before_loading(square, no_work, capsys,
                                                           monkeypatch):
    (square[0].parent / "out").mkdir()
    (square[0].parent / "out" / "photo3d.npz").write_bytes(b"stand-in")
    monkeypatch.setattr("photo3d.export.ldi_pixels", lambda path: 2_000_000)
    monkeypatch.setattr("shutil.disk_usage", lambda path: SimpleNamespace(free=1_000_000))
    run(capsys, "export", "out", "splats.ply", "-q", status=2,
        message="only 1.0 MB free in out; this export needs about 30.0 MB")


@pytest.mark.skipif(os.geteuid() != 0 or sys.platform != "linux",
                    reason="mounts a small tmpfs (root on Linux)")
def test_a_full_disk_during_export_says_so(tmp_path):
    """numpy reserves a file's bytes first when it writes more than 16 MB and says "Not
    enough free space to write N bytes after offset M" (no errno; the disk is not full
    afterwards): before, that was the message. 10 MB free, above export's low estimate
    (6.7 MB); the dense PLY needs 28 MB."""
    import photo3d

    disk = tmp_path / "disk"
    disk.mkdir()
    made = photo3d.make(np.full((600, 600, 3), 0.5, np.float32),
                        depth=np.ones((600, 600), np.float32), config=Config(size=None))
    folder = made.save(tmp_path / "photo", viewer=False)
    size = sum((folder / n).stat().st_size for n in ("photo3d.npz", "config.json")) + 10**7
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs",
                              str(disk)], capture_output=True)
    if mounted.returncode:
        pytest.skip(f"cannot mount a tmpfs: {mounted.stderr.decode().strip()}")
    try:
        photo = disk / "photo"
        photo.mkdir()
        for name in ("photo3d.npz", "config.json"):
            (photo / name).write_bytes((folder / name).read_bytes())
        result = subprocess.run([sys.executable, "-m", "photo3d", "export", str(photo),
                                 "splats.ply", "--splats", "dense", "-q"],
                                env={**os.environ, "PYTHONPATH": str(SRC)},
                                capture_output=True, text=True)
        assert result.returncode == 2, result.stderr
        assert result.stderr == (f"photo3d: error: cannot write {photo}/splats.ply: "
                                 "No space left on device\n")
        assert sorted(p.name for p in photo.iterdir()) == ["config.json", "photo3d.npz"]
    finally:
        subprocess.run(["umount", str(disk)], check=False)


def test_make_refuses_a_video_larger_than_the_memory_before_the_work(square, no_work, capsys,
                                                                      monkeypatch):
    """A video of a given size is rendered after the whole make: its frames are checked
    with the pipeline's memory, before the work."""
    monkeypatch.setattr("photo3d.resources.available_memory", lambda: 2_000_000_000)
    photo, depth = square
    run(capsys, "make", photo, "--depth", depth, "-o", "out", "--size", "64",
        "--video-size", "9000x9000", "--frames", "2", "-q", status=2,
        message="rendering 9000x9000 with --ssaa 2 needs about ")


def test_batch_counts_only_the_workers_its_photos_keep_busy(square, no_work, capsys,
                                                            monkeypatch):
    """A batch of one photo runs one worker, whatever --workers or the thread budget
    say: it was refused for 8 (``PHOTO3D_THREADS=10000`` and 6 photos: 3057 GB)."""
    from photo3d.batch.run import BatchSummary
    from photo3d.resources.make import batch_estimate

    made = []
    monkeypatch.setattr("photo3d.batch.run_batch", lambda jobs, out, *a, **k: made.append(
        len(jobs)) or BatchSummary(1, 0, 0, 0.1, Path(out) / "batch.jsonl"))
    room = int(1.5 * batch_estimate(Config(size=512), workers=1).bytes)
    monkeypatch.setattr("photo3d.resources.available_memory", lambda: room)
    photo, _ = square
    run(capsys, "batch", photo.parent, "-o", "out", "--size", "512", "--workers", "8",
        "--no-video", "-q", status=0)
    assert made == [1]
    Image.open(photo).save(photo.parent / "sq2.png")  # two photos: two workers don't fit
    run(capsys, "batch", photo.parent, "-o", "out2", "--size", "512", "--workers", "8",
        "--no-video", "-q", status=2, message="2 workers at --size 512 needs at least")
