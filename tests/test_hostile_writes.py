"""Issue 45, "one gate for every write": each case is a write that reached what photo3d
did not make (or lost what it made) on the code before the gate; each test fails there.

Every refusal is one line, exit status 2, before any work, and the files that were
there are unchanged (``filetree.tree``, contents compared)."""

from __future__ import annotations

import errno
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from filetree import tree

import photo3d
from photo3d.cli import main
from photo3d.errors import InputError, OutputError
from photo3d.owned import recorded_files


@pytest.fixture(scope="module")
def saved(tmp_path_factory) -> Path:
    """A small 3D photo folder (photo3d.npz, config.json, no meshes, no viewer)."""
    rng = np.random.default_rng(0)
    depth = np.ones((24, 24), np.float32)
    depth[6:18, 6:18] = 0.3
    photo = photo3d.make(rng.random((24, 24, 3)).astype(np.float32), depth=depth,
                         config=photo3d.Config(size=None))
    return photo.save(tmp_path_factory.mktemp("saved") / "o1", viewer=False, ply=None,
                      glb=False)


@pytest.fixture
def o1(saved, tmp_path) -> Path:
    """A fresh copy of :func:`saved` in ``tmp_path``."""
    out = tmp_path / "o1"
    out.mkdir()
    for p in saved.iterdir():
        (out / p.name).write_bytes(p.read_bytes())
    return out


def refused(capsys, argv: list, root: Path, message: str) -> str:
    before = tree(root)
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and message in err, err
    assert tree(root) == before
    return err


# --- defect 1: export replaces the 3D photo it is reading ------------------------------

@pytest.mark.parametrize("name", ["photo3d.npz", "config.json"])
def test_export_never_replaces_the_photo_it_reads(o1, tmp_path, capsys, name):
    refused(capsys, ["export", o1, "splats.ply", "-o", o1 / name, "--overwrite"], tmp_path,
            "photo3d")


def test_export_never_replaces_another_photos_files(o1, tmp_path, capsys):
    o2 = tmp_path / "o2"
    o2.mkdir()
    for p in o1.iterdir():
        (o2 / p.name).write_bytes(p.read_bytes())
    refused(capsys, ["export", o1, "splats.ply", "-o", o2 / "config.json", "--overwrite"],
            tmp_path, "is a file of the 3D photo folder")


def test_export_never_writes_a_hard_link_of_its_input(o1, tmp_path, capsys):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    os.link(o1 / "photo3d.npz", elsewhere / "copy.ply")
    refused(capsys, ["export", o1, "splats.ply", "-o", elsewhere / "copy.ply", "--overwrite"],
            tmp_path, "is an input of this command")


@pytest.mark.parametrize("fmt", ["splats.ply", "splats.spz", "splats.glb"])
def test_splat_writers_refuse_a_dangling_output_link(o1, tmp_path, capsys, fmt):
    """Issue 45, 12: the splat writers followed a dangling -o link."""
    link = tmp_path / f"out.{fmt.split('.')[1]}"
    link.symlink_to(tmp_path / "nowhere" / "x")
    (tmp_path / "nowhere").mkdir()
    refused(capsys, ["export", o1, fmt, "-o", link, "--overwrite"], tmp_path,
            "is a symbolic link; photo3d does not write through links")


def test_export_into_a_folder_without_config_json_keeps_its_files(o1, capsys):
    """Issue 45, 12: exporting into a folder without config.json later refused its own
    files."""
    (o1 / "config.json").unlink()
    assert main(["export", str(o1), "splats.ply", "-q"]) == 0
    assert main(["export", str(o1), "splats.ply", "-q"]) == 0, capsys.readouterr().err
    assert recorded_files(o1) == {"splats.ply"}


def test_an_export_into_a_photo_folder_is_recorded_there(o1, tmp_path):
    other = tmp_path / "other"
    assert main(["export", str(o1), "splats.spz", "-q", "-o", str(o1 / "splats.spz")]) == 0
    assert "splats.spz" in recorded_files(o1)
    assert main(["export", str(o1), "splats.spz", "-q", "-o", str(other)]) == 0



@pytest.mark.parametrize(("fmt", "name"), [
    ("splats.ply", "splats.spz"),  # the hostile round: PLY data recorded as photo3d's SPZ
    ("splats.spz", "splats.glb"), ("quilt", "mesh.usdz"),
    ("splats.glb", "../elsewhere.ply"), ("mesh.usdz", "../quilt.png"),
])
def test_export_refuses_an_output_whose_suffix_is_another_formats(o1, tmp_path, capsys, fmt,
                                                                   name):
    err = refused(capsys, ["export", o1, fmt, "-o", o1 / name], tmp_path, f"but {fmt} is")
    assert Path(name).suffix in err
    assert recorded_files(o1) == set()

# --- issue 45, 11: processes recording into one config.json at once lose entries --------

_RECORD = """
import sys, time
from photo3d.owned import record_files
start = float(sys.argv[2])
while time.time() < start:
    pass
for i in range(25):
    record_files(sys.argv[1], [f"still_{sys.argv[3]}_{i}.png"])
"""


def test_processes_recording_at_once_lose_no_entry(tmp_path):
    (tmp_path / "config.json").write_text("{}")
    start = str(__import__("time").time() + 1.0)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(Path(photo3d.__file__).parents[1]), os.environ.get("PYTHONPATH", "")])}
    procs = [subprocess.Popen([sys.executable, "-c", _RECORD, str(tmp_path), start, str(k)],
                              env=env) for k in range(4)]
    assert [p.wait(timeout=120) for p in procs] == [0] * 4
    assert len(recorded_files(tmp_path)) == 100


# --- a SIGKILL between a file's move into place and its record ----------------------------

_KILLED = """
import os, sys
from photo3d import owned
from photo3d.files.atomic import write_bytes
owned.record_files = lambda folder, names: os._exit(9)  # killed right after the move
with owned.recording(sys.argv[1]):
    write_bytes(os.path.join(sys.argv[1], "splats.ply"), b"ply")
"""


def test_a_file_killed_before_its_record_is_still_photo3ds(o1, tmp_path):
    """CI saw it: an export SIGKILLed after moving mesh.usdz into place and before
    recording it left a folder that `make --overwrite` refused as not photo3d's. The
    file's inode is noted before the move; that very file counts, another one of its
    name does not."""
    folder = tmp_path / "o"
    __import__("shutil").copytree(o1, folder)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(Path(photo3d.__file__).parents[1]), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-c", _KILLED, str(folder)], env=env, timeout=120)
    assert done.returncode == 9 and (folder / "splats.ply").read_bytes() == b"ply"
    assert "splats.ply" in recorded_files(folder)
    (folder / "splats.ply").rename(tmp_path / "kept.ply")
    (folder / "splats.ply").write_bytes(b"a user's")  # another file of that name
    assert "splats.ply" not in recorded_files(folder)
    (tmp_path / "kept.ply").replace(folder / "splats.ply")
    assert main(["export", str(folder), "quilt", "-q"]) == 0  # the folder is photo3d's
    assert {"splats.ply", "quilt_qs8x6a0.75.png"} <= recorded_files(folder)


# --- issue 45, 12: a full disk is named as one --------------------------------------------

def test_a_full_disk_during_export_says_so(o1, tmp_path, monkeypatch, capsys):
    import photo3d.io.splat_ply as splat_ply

    def full(count):
        raise OSError(f"{count * 62} requested and 0 written")  # numpy's tofile, no errno

    class Full:
        f_bavail, f_frsize = 0, 4096

    monkeypatch.setattr(splat_ply, "header", full)
    # room before the work (the free-space check passes), none once the file is written
    monkeypatch.setattr("photo3d.resources.outputs.shutil.disk_usage",
                        lambda path: SimpleNamespace(total=10**12, used=0, free=10**12))
    monkeypatch.setattr(os, "statvfs", lambda path: Full())
    assert main(["export", str(o1), "splats.ply", "-q"]) == 2
    err = capsys.readouterr().err
    assert os.strerror(errno.ENOSPC) in err and "requested" not in err, err
    assert sorted(p.name for p in o1.iterdir()) == ["config.json", "photo3d.npz"]


# --- defect 2: train writes through symbolic links in its run folder --------------------

torch = pytest.importorskip("torch")


def _data():
    from photo3d.train.dataset import Target, TrainingData
    from photo3d.train.pairs import RegionPair

    ctx = np.zeros((24, 24), bool)
    ctx[:, :10] = True
    photo = Target(np.full((32, 32, 3), 0.5, np.float32), np.full((32, 32), 0.5, np.float32),
                   np.zeros((32, 32), bool))
    return TrainingData(["a"], np.array([True]), [RegionPair(ctx, ~ctx, 1)], [photo])


def _config(steps=2):
    from photo3d.train.trainer import TrainConfig

    return TrainConfig("depth", levels=3, width=0.125, size=32, batch=2, steps=steps,
                       checkpoint_every=1, sample_every=1)


@pytest.mark.parametrize("name", ["checkpoints.json", "depth.safetensors", "losses.csv",
                                  "samples", "config.json"])
def test_train_refuses_links_in_its_run_folder(tmp_path, name):
    from photo3d.train.run import train

    run = tmp_path / "run"
    train(_data(), run, _config(1), device="cpu")
    outside = tmp_path / "outside"
    outside.mkdir()
    target = outside / name
    if name == "samples":
        target.mkdir()
    else:
        target.write_bytes((run / name).read_bytes() if (run / name).is_file() else b"mine")
    if (run / name).is_dir():
        import shutil

        shutil.rmtree(run / name)
    elif (run / name).exists():
        (run / name).unlink()
    (run / name).symlink_to(target)
    before = tree(outside)
    with pytest.raises(OutputError, match="is a symbolic link"):
        train(_data(), run, _config(3), device="cpu")
    assert tree(outside) == before


def test_two_trains_on_one_folder_do_not_both_run(tmp_path):
    from photo3d.files.gate import try_lock, unlock
    from photo3d.train.run import train

    run = tmp_path / "run"
    run.mkdir()
    fd = try_lock(run)  # as a running train holds it
    try:
        with pytest.raises(OutputError, match="another photo3d train is running in"):
            train(_data(), run, _config(1), device="cpu")
    finally:
        unlock(fd)
    assert not (run / "losses.csv").exists()
    train(_data(), run, _config(1), device="cpu")  # once it is gone


def test_a_garbage_optimizer_state_is_one_line(tmp_path):
    from photo3d.train.run import train
    from photo3d.train.run_folder import checkpoints

    run = tmp_path / "run"
    train(_data(), run, _config(1), device="cpu")
    step, folder = checkpoints(run)[-1]
    (folder / "optimizer.pt").write_bytes(b"garbage")  # torch: 5 lines "Weights only load.."
    with pytest.raises(InputError) as err:
        train(_data(), run, _config(2), device="cpu")
    assert "\n" not in str(err.value) and "optimizer.pt" in str(err.value)


def test_deeply_nested_records_are_one_line(tmp_path):
    from photo3d.train.run import train
    from photo3d.train.run_folder import RECORD, written_checkpoints

    run = tmp_path / "run"
    train(_data(), run, _config(1), device="cpu")
    (run / RECORD).write_text("[" * 200_000)
    assert written_checkpoints(run) == []
    state = run / "checkpoints" / "step_0000001" / "state.json"
    state.write_text('{"step": ' + "[" * 200_000)
    with pytest.raises(InputError) as err:
        train(_data(), run, _config(2), device="cpu")
    assert "\n" not in str(err.value) and "state.json" in str(err.value)


def test_nested_results_json_is_one_line(tmp_path):
    from photo3d.eval import report

    out = tmp_path / "eval"
    out.mkdir()
    (out / "results.json").write_text("[" * 200_000)
    with pytest.raises(OutputError, match="has no results.json of photo3d eval"):
        report.run({"p": None}, out, methods=["m"], overwrite=True)


@pytest.mark.parametrize("argv", [["export", "{o1}", "splats.ply", "-q"],
                                  ["render", "{o1}", "--still", "-q", "--size", "32x32"]])
def test_a_deeply_nested_config_json_is_never_a_traceback(o1, capsys, argv):
    (o1 / "config.json").write_text('{"written": ' + "[" * 200_000)
    status = main([a.format(o1=o1) for a in argv])
    err = capsys.readouterr().err
    assert status in (0, 2) and "Traceback" not in err and err.count("\n") <= 1, err


def test_make_overwrite_of_a_folder_with_a_nested_config_json(o1, tmp_path, capsys):
    from PIL import Image

    Image.fromarray(np.zeros((16, 16, 3), np.uint8)).save(tmp_path / "a.png")
    np.save(tmp_path / "a.npy", np.ones((16, 16), np.float32))
    (o1 / "config.json").write_text("[" * 200_000)
    status = main(["make", str(tmp_path / "a.png"), "--depth", str(tmp_path / "a.npy"),
                   "-o", str(o1), "--overwrite", "-q", "--size", "0"])
    err = capsys.readouterr().err
    assert status in (0, 2) and "Traceback" not in err and err.count("\n") <= 1, err
