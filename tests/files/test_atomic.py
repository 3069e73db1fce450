"""Single files written atomically (photo3d.files.atomic), and every writer using it.

Each case checks that the old file survives a failed or interrupted write unchanged
and that no temporary file is left beside it.
"""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from filetree import tree
from PIL import Image

from photo3d.errors import OutputError
from photo3d.files.atomic import (
    PendingFile,
    atomic_path,
    atomic_write,
    check_writable,
    write_bytes,
    write_json,
    write_text,
)
from photo3d.files.temps import is_temp_of, remove_temp_files


def names(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


@pytest.fixture
def old(tmp_path) -> Path:
    """``tmp/old.txt`` holding ``"old"``."""
    path = tmp_path / "old.txt"
    path.write_text("old")
    return path


def test_an_interrupted_write_leaves_the_old_file_and_no_temporary(old):
    with pytest.raises(KeyboardInterrupt), atomic_write(old, "w") as f:
        f.write("new, half")
        f.flush()
        assert len(os.listdir(old.parent)) == 2  # the temporary file exists meanwhile
        raise KeyboardInterrupt
    assert old.read_text() == "old" and names(old.parent) == ["old.txt"]


@pytest.mark.parametrize("raised", [ValueError("a bug"), KeyboardInterrupt()])
def test_any_exception_in_atomic_path_leaves_the_old_file(old, raised):
    with pytest.raises(type(raised)), atomic_path(old) as tmp:
        tmp.write_text("new, half")
        raise raised
    assert old.read_text() == "old" and names(old.parent) == ["old.txt"]


def test_a_successful_write_replaces_the_file_with_the_umask_permissions(old):
    old.chmod(0o600)
    mask = os.umask(0o027)
    try:
        write_text(old, "new")
    finally:
        os.umask(mask)
    assert old.read_text() == "new" and names(old.parent) == ["old.txt"]
    assert old.stat().st_mode & 0o777 == 0o640


def test_write_helpers_write_exactly_their_value(tmp_path):
    assert write_bytes(tmp_path / "a.bin", b"\x00\xff").read_bytes() == b"\x00\xff"
    assert write_text(tmp_path / "a.txt", "é\n").read_bytes() == "é\n".encode()
    value = {"b": [1, 2.5], "a": None}
    assert json.loads(write_json(tmp_path / "a.json", value).read_text()) == value
    assert (tmp_path / "a.json").read_text() == json.dumps(value, indent=2)
    with pytest.raises(ValueError, match="mode must be"), atomic_write(tmp_path / "x", "a"):
        pass
    assert names(tmp_path) == ["a.bin", "a.json", "a.txt"]


def test_atomic_path_keeps_the_suffix_libraries_infer_the_format_from(tmp_path):
    with atomic_path(tmp_path / "arrays.npz") as tmp:
        assert tmp.name.startswith(".arrays.npz.") and tmp.name.endswith(".tmp.npz")
        np.savez(tmp, a=np.arange(3))  # would append .npz to any other name
    with atomic_path(tmp_path / "image.png") as tmp:
        Image.new("RGB", (2, 2)).save(tmp)  # the format from the suffix
    with atomic_path(tmp_path / "video.mp4", suffix=".part") as tmp:
        assert tmp.name.endswith(".tmp.part")
        tmp.write_bytes(b"v")
    assert names(tmp_path) == ["arrays.npz", "image.png", "video.mp4"]
    with np.load(tmp_path / "arrays.npz") as arrays, Image.open(tmp_path / "image.png") as im:
        assert arrays["a"].tolist() == [0, 1, 2] and im.format == "PNG"


@pytest.mark.parametrize(("target", "message"), [
    ("missing/a.txt", "the folder missing does not exist"),
    ("folder", "is a folder"),
    ("x" * 256, "File name too long"),
    ("/proc/photo3d-test.txt", "cannot write /proc/photo3d-test.txt"),
])
def test_unwritable_targets_are_refused_in_one_line_before_any_data(tmp_path, monkeypatch,
                                                                    target, message):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "folder").mkdir()
    produced = []
    for check in (check_writable, write_text):
        with pytest.raises(OutputError, match=message) as caught:
            if check is check_writable:
                check_writable(target)
            else:
                with atomic_write(target, "w") as f:
                    produced.append(f)
        assert "\n" not in str(caught.value) and ".tmp" not in str(caught.value)
    assert produced == [] and names(tmp_path) == ["folder"]


def test_errors_while_writing_name_the_target_not_the_temporary_file(old):
    with pytest.raises(OutputError) as caught, atomic_path(old) as tmp:
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp))
    assert str(caught.value) == f"cannot write {old}: No space left on device"
    with pytest.raises(OutputError) as caught, atomic_path(old) as tmp:
        raise OutputError(f"cannot write image {tmp}: disk quota exceeded")
    assert str(caught.value) == f"cannot write image {old}: disk quota exceeded"
    assert old.read_text() == "old" and names(old.parent) == ["old.txt"]


def test_a_failed_rename_leaves_the_old_file(old, monkeypatch):
    def refuse(src, dst):
        raise OSError(errno.EXDEV, "Invalid cross-device link")

    monkeypatch.setattr(os, "replace", refuse)
    with pytest.raises(OutputError, match="old.txt: Invalid cross-device link"):
        write_text(old, "new")
    assert old.read_text() == "old" and names(old.parent) == ["old.txt"]


def test_a_symbolic_link_is_refused_by_default(tmp_path):
    (tmp_path / "real.txt").write_text("old")
    (tmp_path / "link.txt").symlink_to("real.txt")
    with pytest.raises(OutputError, match="is a symbolic link; photo3d does not write"):
        write_text(tmp_path / "link.txt", "new")
    assert (tmp_path / "real.txt").read_text() == "old"
    assert names(tmp_path) == ["link.txt", "real.txt"]


def test_a_symbolic_link_is_followed_when_asked_and_stays(tmp_path):
    (tmp_path / "real.txt").write_text("old")
    (tmp_path / "link.txt").symlink_to("real.txt")
    with atomic_write(tmp_path / "link.txt", "w", follow_symlinks=True) as f:
        f.write("new")
    assert (tmp_path / "link.txt").is_symlink() and (tmp_path / "real.txt").read_text() == "new"
    assert names(tmp_path) == ["link.txt", "real.txt"]


@pytest.mark.parametrize("points_to", ["outside/real.txt", "outside/missing.txt",
                                       "inside.txt"])
def test_follow_symlinks_false_refuses_any_link_before_any_data(tmp_path, points_to):
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside" / "real.txt").write_text("theirs")
    folder = tmp_path / "folder"
    folder.mkdir()
    (folder / "inside.txt").write_text("mine")
    link = folder / "link.txt"
    link.symlink_to(tmp_path / points_to if points_to.startswith("outside") else points_to)
    before = tree(tmp_path)
    message = f"{link} is a symbolic link; photo3d does not write through links"
    produced = []
    writers = [
        lambda: check_writable(link, follow_symlinks=False),
        lambda: PendingFile(link, suffix=".part", follow_symlinks=False),
        lambda: produced.append(atomic_path(link, follow_symlinks=False).__enter__()),
        lambda: produced.append(atomic_write(link, "w", follow_symlinks=False).__enter__()),
    ]
    for write in writers:
        with pytest.raises(OutputError) as caught:
            write()
        assert str(caught.value) == message
    assert produced == [] and tree(tmp_path) == before


def test_follow_symlinks_false_writes_a_plain_file_and_replaces_a_late_link(tmp_path):
    (tmp_path / "outside.txt").write_text("theirs")
    target = tmp_path / "a.txt"
    with atomic_write(target, "w", follow_symlinks=False) as f:
        f.write("one")
    assert target.read_text() == "one" and not target.is_symlink()
    with atomic_path(target, follow_symlinks=False) as tmp:
        target.unlink()
        target.symlink_to(tmp_path / "outside.txt")  # a link appears while writing
        tmp.write_text("two")
    assert not target.is_symlink() and target.read_text() == "two"
    assert (tmp_path / "outside.txt").read_text() == "theirs"
    assert names(tmp_path) == ["a.txt", "outside.txt"]


def test_pending_file_commits_or_discards(old):
    pending = PendingFile(old)
    pending.path.write_text("new")
    assert old.read_text() == "old"  # nothing visible before the commit
    assert pending.commit() == old and old.read_text() == "new"
    with PendingFile(old) as pending:
        pending.path.write_text("newer")  # never committed
    pending.discard()  # idempotent
    assert old.read_text() == "new" and names(old.parent) == ["old.txt"]


def test_temporary_names_and_leftovers(tmp_path):
    assert is_temp_of(".a.png.0f0f0f0f.tmp", "a.png")
    assert is_temp_of(".a.png.0f0f0f0f.tmp.part", "a.png")
    assert not is_temp_of(".a.png.0f0f0f0f.tmp.part", "a.png", suffixed=False)
    for name in (".a.png.0f0f0f0f.tmp.tar.gz", ".a.png.0F0F0F0F.tmp", ".a.png.0f0f0f0.tmp",
                 ".ab.png.0f0f0f0f.tmp", ".a.png.0f0f0f0f.tmp.", "a.png", ".a.png.0f0f0f0f"):
        assert not is_temp_of(name, "a.png"), name
    long = "n" * 200 + ".png"
    with PendingFile(tmp_path / long, suffix=".png") as pending:
        assert is_temp_of(pending.path.name, long) and len(pending.path.name) < 90
    kept = [".a.png.0f0f0f0f.old", ".a.png.nothex!!.tmp", "a.png", ".b.png.0f0f0f0f.tmp"]
    for name in kept:
        (tmp_path / name).write_text("x")
    (tmp_path / ".a.png.1a2b3c4d.tmp").mkdir()  # a staged folder: staging's business
    left = [PendingFile(tmp_path / "a.png", suffix=s).path for s in ("", ".png", ".part")]
    assert sorted(remove_temp_files(tmp_path / "a.png")) == sorted(left)
    assert names(tmp_path) == sorted([*kept, ".a.png.1a2b3c4d.tmp"])


_WRITER = """
import os, signal, sys, time
from pathlib import Path
from photo3d.files.atomic import PendingFile, atomic_write
from photo3d.files.signals import handle_signals

target = Path(sys.argv[1])
if sys.argv[2] == "exit":  # never committed nor discarded: removed at exit
    PendingFile(target, suffix=".png")
    sys.exit(3)
with handle_signals(), atomic_write(target, "w") as f:
    f.write("new, half")
    f.flush()
    print("writing", flush=True)
    time.sleep(60)
"""


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
@pytest.mark.parametrize("how", ["exit", signal.SIGTERM, signal.SIGINT, signal.SIGHUP])
def test_a_killed_or_exiting_process_leaves_no_temporary(old, how):
    argv = [sys.executable, "-c", _WRITER, str(old), str(how)]
    with subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          text=True) as proc:
        try:
            if how != "exit":
                assert proc.stdout.readline() == "writing\n"
                assert len(os.listdir(old.parent)) == 2
                time.sleep(0.1)
                proc.send_signal(how)
            _, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
    # an uncaught KeyboardInterrupt ends Python with SIGINT, as the shell expects
    expected = {"exit": 3, signal.SIGINT: -signal.SIGINT}.get(how, 1)
    assert proc.returncode == expected, err
    assert old.read_text() == "old" and names(old.parent) == ["old.txt"]


# --- every writer of single files writes through files.atomic ----------------------------


@pytest.fixture
def failing_rename(monkeypatch):
    """The final rename fails as on a full or vanished file system."""
    def refuse(src, dst):
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(os, "replace", refuse)


def test_the_batch_manifest(tmp_path, failing_rename):
    from photo3d.batch.manifest import ManifestWriter, PhotoResult

    path = tmp_path / "batch.jsonl"
    path.write_text('{"name": "a", "status": "ok"}\n')
    with pytest.raises(OutputError, match="batch.jsonl: Input/output error"):
        with ManifestWriter(path) as manifest:
            manifest.add(PhotoResult("b", "ok", None, 1.0, "out/b"))
    # the appended line is kept (it was flushed), nothing else is touched
    lines = [json.loads(line)["name"] for line in path.read_text().splitlines()]
    assert lines == ["a", "b"] and names(tmp_path) == ["batch.jsonl"]


def test_depth_export_replaces_both_files_or_neither(tmp_path, monkeypatch):
    from photo3d.depth import export
    from photo3d.depth.sources import DepthEstimate

    for name in ("d.png", "d_preview.png"):
        (tmp_path / name).write_bytes(b"old")
    est = DepthEstimate(np.array([[1.0, 2.0], [4.0, 4.0]], np.float32), "depth", "test")

    def interrupted(values):
        raise KeyboardInterrupt  # after the depth PNG is written, before the preview

    with monkeypatch.context() as m:
        m.setattr(export, "colorize", interrupted)
        with pytest.raises(KeyboardInterrupt):
            export.export_depth(est, tmp_path / "d.png")
    assert names(tmp_path) == ["d.png", "d_preview.png"]
    assert all((tmp_path / n).read_bytes() == b"old" for n in names(tmp_path))
    monkeypatch.setattr("photo3d.files.atomic.os.replace", _refuse)
    with pytest.raises(OutputError, match="d_preview.png: Input/output error"):
        export.export_depth(est, tmp_path / "d.png")
    assert all((tmp_path / n).read_bytes() == b"old" for n in names(tmp_path))
    assert names(tmp_path) == ["d.png", "d_preview.png"]


def _refuse(src, dst):
    raise OSError(errno.EIO, "Input/output error")


def test_eval_reports(tmp_path, monkeypatch):
    from types import SimpleNamespace

    from photo3d.eval import report

    result = SimpleNamespace(scores={"m": {"all": {"psnr": 1.0}}}, notes={},
                             regions={"disoccluded": np.zeros((2, 2), bool)})
    pair = SimpleNamespace(left=np.zeros((2, 2, 3)))
    monkeypatch.setattr(report, "evaluate", lambda *a, **k: result)
    monkeypatch.setattr(report, "grid", lambda pair, result: np.zeros((4, 4, 3), np.float32))
    monkeypatch.setattr(report, "table", lambda result: "| table |")
    out = tmp_path / "eval"
    report.run({"p": lambda: pair}, out, methods=["m"])
    assert names(out) == ["grid_p.png", "results.json", "results.md"]
    before = {n: (out / n).read_bytes() for n in names(out)}

    def fails(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr("photo3d.io.images.write_image", fails)
    with pytest.raises(OutputError, match="exists and is not empty"):
        report.run({"p": lambda: pair}, out, methods=["m"])  # a second run needs overwrite
    with pytest.raises(OutputError, match=r"grid_p.png: No space left on device"):
        report.run({"p": lambda: pair}, out, methods=["m"], overwrite=True)
    monkeypatch.undo()
    monkeypatch.setattr(os, "replace", _refuse)
    monkeypatch.setattr(report, "evaluate", lambda *a, **k: result)
    monkeypatch.setattr(report, "grid", lambda pair, result: np.ones((4, 4, 3), np.float32))
    monkeypatch.setattr(report, "table", lambda result: "| other |")
    with pytest.raises(OutputError, match="Input/output error"):
        report.run({"p": lambda: pair}, out, methods=["m"], overwrite=True)
    assert {n: (out / n).read_bytes() for n in names(out)} == before


def test_eval_refuses_an_unwritable_folder_before_evaluating(tmp_path, monkeypatch):
    from photo3d.eval import report

    def refuse(*args, **kwargs):
        raise AssertionError("evaluated before the output was checked")

    monkeypatch.setattr(report, "evaluate", refuse)
    (tmp_path / "file").write_text("a file")
    with pytest.raises(OutputError, match="cannot create the folder"):
        report.run({"p": refuse}, tmp_path / "file" / "eval")
    with pytest.raises(OutputError, match="/proc has no results.json of photo3d eval"):
        report.run({"p": refuse}, "/proc", overwrite=True)


def test_the_training_cache_index(tmp_path, monkeypatch):
    from photo3d.train import dataset

    cache = tmp_path / "cache"
    monkeypatch.setattr(os, "replace", _refuse)
    with pytest.raises(OutputError, match=r"(pool.npz|index.json): Input/output error"):
        dataset.prepare_data([], crop=32, region_size=48, builtin_shapes=0, cache=cache)
    assert not (cache / "index.json").exists()
    assert not [p for p in cache.rglob(".*")]


def test_render_still_keeps_the_old_image_and_checks_before_rendering(tmp_path, monkeypatch,
                                                                      capsys):
    from conftest import two_planes

    from photo3d.cli import main
    from photo3d.owned import record_files

    img, disparity = two_planes(48, 64, 32)
    Image.fromarray((img * 255).astype(np.uint8)).save(tmp_path / "a.png")
    np.save(tmp_path / "a.npy", disparity)
    out = tmp_path / "out"
    assert main(["make", str(tmp_path / "a.png"), "--depth", str(tmp_path / "a.npy"), "-o",
                 str(out), "--size", "48", "--no-video", "--no-glb", "--no-viewer", "-q"]) == 0
    (out / "still.png").write_bytes(b"old still")
    record_files(out, ["still.png"])  # as if an earlier `render --still` wrote it
    before = names(out)

    def half_written(path, image, **kwargs):
        Path(path).write_bytes(b"half")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr("photo3d.io.images.write_image", half_written)
    assert main(["render", str(out), "--still", "-q"]) == 2
    err = capsys.readouterr().err
    assert err == f"photo3d: error: cannot write {out / 'still.png'}: No space left on device\n"
    assert (out / "still.png").read_bytes() == b"old still" and names(out) == before

    def refuse(*args, **kwargs):
        raise AssertionError("rendered before the output was checked")

    monkeypatch.setattr("photo3d.render.animate.render_still", refuse)
    (out / "still.png").unlink()
    (out / "still.png").mkdir()
    assert main(["render", str(out), "--still", "-q"]) == 2
    assert "is a folder" in capsys.readouterr().err and names(out) == before
