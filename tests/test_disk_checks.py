"""Issue 45, item 3: what can fail after the work fails before it; here, a disk too
full for what ``render`` and ``depth`` write (``make``, the UI and ``export`` check
theirs: tests/test_memory_model.py, tests/files/test_staging.py)."""

from __future__ import annotations

from collections import namedtuple

import numpy as np
import pytest
from PIL import Image

import photo3d
from photo3d.cli import main
from photo3d.config import Config

Usage = namedtuple("Usage", "total used free")


@pytest.fixture
def almost_full(monkeypatch):
    """The disk has 100 kB free (as photo3d's free-space check reads it)."""
    monkeypatch.setattr("photo3d.resources.outputs.shutil.disk_usage",
                        lambda path: Usage(10**9, 10**9 - 100_000, 100_000))


@pytest.fixture
def folder(tmp_path):
    made = photo3d.make(np.full((32, 48, 3), 0.5, np.float32),
                        depth=np.ones((32, 48), np.float32), config=Config(size=None))
    return made.save(tmp_path / "photo", viewer=False)


def _refused(capsys, argv, mistake: str) -> None:
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("photo3d: error: only 0.1 MB free in ") and mistake in err, err
    assert err.count("\n") == 1


def test_render_refuses_videos_the_disk_cannot_hold(folder, almost_full, capsys, monkeypatch):
    def work(*args, **kwargs):
        raise AssertionError("rendered before the disk was checked")

    monkeypatch.setattr("photo3d.output.write_videos", work)
    _refused(capsys, ["render", folder, "--size", "1920x1080", "-q"], "this render needs")
    assert not (folder / "video").exists()


def test_render_refuses_a_still_the_disk_cannot_hold(folder, almost_full, capsys):
    _refused(capsys, ["render", folder, "--still", "--size", "4000x3000", "-q"],
             "this render needs about 1.2 MB")
    assert not (folder / "still.png").exists()


def test_depth_refuses_a_map_the_disk_cannot_hold(tmp_path, almost_full, capsys, monkeypatch):
    Image.new("RGB", (1200, 1000), (120, 80, 40)).save(tmp_path / "p.png")
    np.save(tmp_path / "d.npy", np.ones((1000, 1200), np.float32))
    monkeypatch.chdir(tmp_path)
    _refused(capsys, ["depth", "p.png", "--depth", "d.npy", "-o", "out.png"],
             "this depth map (and its preview) needs")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.npy", "p.png"]


def test_a_small_render_passes_the_check(folder, almost_full, capsys):
    assert main(["render", str(folder), "--still", "-q"]) == 0
    assert (folder / "still.png").exists()
