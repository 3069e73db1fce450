"""What photo3d promises about bad inputs and output folders (README "Inputs").

Every case checks the exit status, that the message is one line without a
traceback, that no file that existed before is lost or changed, and that nothing
partial (no hidden temporary folder, no half-written output) is left behind.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import two_planes
from PIL import Image

import photo3d
from photo3d.cli import main
from photo3d.errors import OutputError
from photo3d.io.safeout import stage_output

SRC = str(Path(photo3d.__file__).parents[1])
FAST = ["--size", "48", "--no-video", "--no-glb", "--no-viewer", "-q"]


@pytest.fixture
def photos(tmp_path, monkeypatch):
    """``tmp/photos/{a.png, a.npy, notes.txt}``; the current folder is ``tmp``."""
    folder = tmp_path / "photos"
    folder.mkdir()
    img, d = two_planes(48, 64, 32)
    Image.fromarray((img * 255).astype(np.uint8)).save(folder / "a.png")
    np.save(folder / "a.npy", d)
    (folder / "notes.txt").write_text("my notes")
    monkeypatch.chdir(tmp_path)
    return folder


def snapshot(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` (relative path -> content)."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


def leftovers(root: Path) -> list[str]:
    """Temporary files or folders of photo3d anywhere under ``root``."""
    return [str(p) for p in root.rglob(".*") if p.name.endswith((".tmp", ".old", ".part"))]


def run(capsys, *argv, status: int, message: str = "", root: Path | None = None) -> str:
    """Run the CLI in-process; check status, one line, no loss, nothing partial."""
    root = root or Path.cwd()
    before = snapshot(root)
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err.strip()
    assert code == status, err
    after = snapshot(root)
    lost = {k for k, v in before.items() if after.get(k) != v}
    assert not lost or status == 0, f"lost or changed: {lost}"
    assert not leftovers(root)
    if status != 0:
        assert len(err.splitlines()) == 1 and "Traceback" not in err, err
        assert message in err, err
        assert set(after) == set(before), "a failed run wrote files"
    return err


def make(photos: Path, out, *extra) -> list:
    return ["make", photos / "a.png", "--depth", photos / "a.npy", "-o", out, *FAST, *extra]


# --- data loss ---------------------------------------------------------------------------


@pytest.mark.parametrize("out", ["photos", ".", "photos/..", "..", "photos/sub/../.."])
def test_overwrite_never_deletes_inputs_the_cwd_or_its_parents(photos, capsys, out):
    msg = "holds the input" if out == "photos" else "current folder"
    run(capsys, *make(photos, out, "--overwrite"), status=2, message=msg,
        root=photos.parent)


def test_overwrite_only_replaces_a_folder_photo3d_wrote(photos, capsys):
    mine = photos.parent / "mine"
    mine.mkdir()
    (mine / "mesh.ply").write_text("my own mesh")  # a photo3d name, but not photo3d's folder
    run(capsys, *make(photos, "mine", "--overwrite"), status=2,
        message="only replaces a folder photo3d wrote")
    run(capsys, *make(photos, "out"), status=0)
    first = (photos.parent / "out" / "photo3d.npz").stat().st_ino
    run(capsys, *make(photos, "out"), status=2, message="not empty (use --overwrite)")
    (photos.parent / "out" / "notes.txt").write_text("added by the user")
    run(capsys, *make(photos, "out", "--overwrite"), status=2, message="holds notes.txt")
    (photos.parent / "out" / "notes.txt").unlink()
    run(capsys, *make(photos, "out", "--overwrite"), status=0)
    assert (photos.parent / "out" / "photo3d.npz").stat().st_ino != first
    assert sorted(os.listdir(photos.parent)) == ["mine", "out", "photos"]


def test_a_symlinked_output_is_written_into_its_target(photos, capsys):
    target = photos.parent / "target"
    (photos.parent / "link").symlink_to(target.name)
    run(capsys, *make(photos, "link"), status=2, message="symbolic link to target, which "
        "does not exist")
    target.mkdir()
    run(capsys, *make(photos, "link"), status=0)
    run(capsys, *make(photos, "link", "--overwrite"), status=0)
    assert (photos.parent / "link").is_symlink()
    assert (target / "photo3d.npz").is_file()
    photo3d.load(photos.parent / "link")


def test_output_folders_respect_the_umask(photos, capsys):
    for mask in (0o022, 0o002):
        old = os.umask(mask)
        try:
            run(capsys, *make(photos, f"out{mask}"), status=0)
        finally:
            os.umask(old)
        assert (photos.parent / f"out{mask}").stat().st_mode & 0o777 == 0o777 & ~mask


def test_the_final_rename_is_checked(tmp_path):
    """A folder that appears or changes while the run works is never replaced."""
    out = tmp_path / "out"
    with stage_output(out) as staging:
        out.mkdir()
        (out / "theirs.txt").write_text("another run")
        with pytest.raises(OutputError, match="changed while photo3d was working"):
            staging.commit()
    assert sorted(os.listdir(tmp_path)) == ["out"]
    assert (out / "theirs.txt").read_text() == "another run"


def _cli(*argv, cwd: Path, **kwargs) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": SRC}
    return subprocess.Popen([sys.executable, "-m", "photo3d", *map(str, argv)], cwd=cwd,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, **kwargs)


def finish(proc: subprocess.Popen, timeout: float = 120) -> tuple[int, str]:
    """``(exit status, stderr)`` of a finished :func:`_cli` process."""
    _, err = proc.communicate(timeout=timeout)
    return proc.returncode, err.strip()


def test_concurrent_runs_to_the_same_output(photos):
    procs = [_cli(*make(photos, "same"), cwd=photos.parent) for _ in range(2)]
    results = sorted(finish(p) for p in procs)
    assert [code for code, _ in results] == [0, 2], results
    err = results[1][1]
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert "another run" in err or "not empty" in err
    assert not leftovers(photos.parent)
    photo3d.load(photos.parent / "same")


@pytest.mark.parametrize(("sig", "status"), [(signal.SIGINT, 130), (signal.SIGTERM, 143),
                                             (signal.SIGHUP, 129)])
def test_signals_while_rendering_videos_leave_nothing(photos, sig, status):
    """Ctrl-C (or SIGTERM/SIGHUP) inside the numba rasterizer: one line, no temp folder."""
    proc = _cli("make", photos / "a.png", "--depth", photos / "a.npy", "-o", "out",
                "--size", "64", "--frames", "2000", "--video-size", "320x240", "-q",
                cwd=photos.parent)
    deadline = time.monotonic() + 180
    while not list(photos.parent.glob(".out.*.tmp/video/.*.part")):
        assert proc.poll() is None and time.monotonic() < deadline, finish(proc)
        time.sleep(0.05)
    time.sleep(0.3)
    proc.send_signal(sig)
    code, err = finish(proc)
    assert code == status and err.startswith("photo3d: interrupted"), err
    assert len(err.splitlines()) == 1
    assert sorted(os.listdir(photos.parent)) == ["photos"]


# --- the output location is checked before the work ------------------------------------


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if the pipeline starts."""
    def refuse(*args, **kwargs):
        raise AssertionError("the pipeline ran before the output was checked")

    monkeypatch.setattr("photo3d.pipeline.make", refuse)


def test_unwritable_outputs_are_refused_before_the_work(photos, capsys, no_work):
    (photos.parent / "file").write_text("a file")
    run(capsys, *make(photos, "file/out"), status=2, message="not a folder")
    run(capsys, *make(photos, "file"), status=2, message="exists and is not a folder")
    run(capsys, *make(photos, "x" * 256), status=2, message="File name too long")
    run(capsys, *make(photos, "/proc/photo3d-out"), status=2, message="cannot write in /proc")


def _mount_tmpfs(path: Path, options: str) -> bool:
    path.mkdir()
    if os.geteuid() != 0 or not shutil.which("mount"):
        return False
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(path)],
                          capture_output=True, check=False)
    return done.returncode == 0


@pytest.mark.parametrize(("options", "message"), [("ro,size=1m", "Read-only file system"),
                                                  ("size=64k", "MB free")])
def test_read_only_and_full_file_systems(photos, capsys, no_work, options, message):
    mnt = photos.parent / "mnt"
    if not _mount_tmpfs(mnt, options):
        pytest.skip("needs root to mount a small tmpfs")
    try:
        run(capsys, *make(photos, mnt / "out"), status=2, message=message)
    finally:
        subprocess.run(["umount", str(mnt)], check=True)


def test_a_disk_that_fills_up_during_the_run(photos, capsys, monkeypatch):
    """The estimate can be wrong: running out of space mid-way is one line too."""
    mnt = photos.parent / "mnt"
    if not _mount_tmpfs(mnt, "size=200k"):
        pytest.skip("needs root to mount a small tmpfs")
    monkeypatch.setattr("photo3d.cli.make.output_bytes", lambda *a: 0)
    try:
        run(capsys, "make", photos / "a.png", "--depth", photos / "a.npy", "-o", mnt / "o",
            "--size", "256", "-q", "--no-video", status=2, message="No space left on device")
        assert os.listdir(mnt) == []
    finally:
        subprocess.run(["umount", str(mnt)], check=True)


def test_a_parent_without_write_permission(photos):
    import tempfile

    base = Path(tempfile.mkdtemp())  # outside pytest's 0700 folder: readable by nobody
    try:
        _unwritable_parent(photos, base)
    finally:
        shutil.rmtree(base)


def _unwritable_parent(photos: Path, base: Path) -> None:
    shutil.copytree(photos, base / "photos")
    locked, cache = base / "locked", base / "numba-cache"
    locked.mkdir()
    cache.mkdir()
    prefix = []
    if os.geteuid() == 0:  # root writes anywhere: run as nobody
        if not shutil.which("setpriv"):
            pytest.skip("needs setpriv to drop root")
        prefix = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"]
    for p in [base, *base.rglob("*")]:
        p.chmod(0o755 if p.is_dir() else 0o644)
    locked.chmod(0o555)
    cache.chmod(0o777)
    env = {**os.environ, "PYTHONPATH": SRC, "NUMBA_CACHE_DIR": str(cache)}
    proc = subprocess.run([*prefix, sys.executable, "-m", "photo3d",
                           *map(str, make(base / "photos", locked / "out"))], cwd=base,
                          env=env, capture_output=True, text=True, check=False, timeout=120)
    err = proc.stderr.strip()
    assert proc.returncode == 2 and len(err.splitlines()) == 1, err
    assert "Permission denied" in err
    assert os.listdir(locked) == []
