import subprocess
import sys

import numpy as np
import pytest
from conftest import two_planes
from PIL import Image

from photo3d.cli import main


@pytest.fixture
def files(tmp_path):
    img, d = two_planes(48, 64, 32)
    Image.fromarray((img * 255).astype(np.uint8)).save(tmp_path / "photo.png")
    Image.fromarray((d * 100).astype(np.uint16)).save(tmp_path / "depth.png")
    return tmp_path


def test_make_writes_a_3d_photo_and_a_timing_summary(files, capsys):
    out = files / "out"
    code = main(["make", str(files / "photo.png"), "--depth", str(files / "depth.png"),
                 "-o", str(out), "--size", "128"])
    assert code == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "config.json", "mesh.glb", "mesh.ply", "photo3d.npz"]
    text = capsys.readouterr().out
    assert "3D photo written to" in text and "time:" in text and "inpaint" in text


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["make", "{d}/nope.jpg", "--depth", "{d}/depth.png", "-o", "{d}/o"], "not found"),
        (["make", "{d}/photo.png", "--depth", "{d}/nope.png", "-o", "{d}/o"], "not found"),
        (["make", "{d}/photo.png", "--depth", "{d}/photo.png", "-o", "{d}/o"], "depth"),
        (["make", "{d}/photo.png", "--depth", "{d}/depth.png", "-o", "{d}"], "not empty"),
        (["make", "{d}/photo.png", "--depth", "{d}/depth.png", "-o", "{d}/o",
          "--inpainter", "magic"], "unknown inpainter"),
    ],
)
def test_user_mistakes_give_one_line_and_status_2(files, capsys, args, message):
    argv = [a.format(d=files) for a in args]
    before = sorted(p.name for p in files.iterdir())
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("photo3d: error:") and message in err[0]
    assert sorted(p.name for p in files.iterdir()) == before  # nothing half-written


def test_console_script_runs_without_traceback(files):
    proc = subprocess.run(
        [sys.executable, "-m", "photo3d", "make", str(files / "missing.png"), "--depth",
         str(files / "depth.png"), "-o", str(files / "o")],
        capture_output=True, text=True, check=False,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and "image file not found" in proc.stderr
