"""photo3d batch: folders of photos, the manifest, resuming, failures, Ctrl-C."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import two_planes, wait_for

from photo3d.batch import MakeOptions, PhotoJob, find_photos, read_manifest, run_batch
from photo3d.batch.worker import discard_partial, is_complete
from photo3d.cli import main
from photo3d.config import Config
from photo3d.errors import InputError
from photo3d.files.temps import release
from photo3d.io.images import write_image
from photo3d.io.npz import load_npz
from photo3d.output import stage_photo
from photo3d.save_options import SaveOptions

FAST = ["--size", "64", "--no-video", "--no-glb", "--no-viewer"]


def add_photo(folder: Path, name: str, depth_folder: Path | None, seed: int = 0) -> None:
    img, d = two_planes(48, 64, 24 + 4 * seed)
    write_image(folder / f"{name}.png", img)
    if depth_folder is not None:
        np.save(depth_folder / f"{name}.npy", d)


@pytest.fixture
def photos(tmp_path):
    """Three good photos with depth maps, one broken file, one without depth."""
    src, dep = tmp_path / "photos", tmp_path / "depth"
    src.mkdir()
    dep.mkdir()
    for i, name in enumerate(("a", "b", "c")):
        add_photo(src, name, dep, seed=i)
    (src / "broken.jpg").write_bytes(b"not a jpeg")
    add_photo(src, "plain", None)
    return tmp_path


def test_find_photos_matches_depth_by_name_and_walks_subfolders(tmp_path):
    (tmp_path / "in" / "trip").mkdir(parents=True)
    (tmp_path / "in" / ".hidden").mkdir()
    (tmp_path / "d" / "trip").mkdir(parents=True)
    for name in ("in/a.jpg", "in/b.PNG", "in/notes.txt", "in/trip/c.webp", "in/.hidden/x.jpg",
                 "d/a.pfm", "d/trip/c.npy", "d/unused.png"):
        (tmp_path / name).touch()
    flat = find_photos(tmp_path / "in", depth=tmp_path / "d")
    assert [(j.name, j.depth and j.depth.name) for j in flat] == [("a", "a.pfm"), ("b", None)]
    deep = find_photos(tmp_path / "in", depth=tmp_path / "d", recursive=True)
    assert [(j.name, j.depth and j.depth.name) for j in deep] == [
        ("a", "a.pfm"), ("b", None), ("trip/c", "c.npy")]
    # the output folder inside the input folder is never taken as input
    assert [j.name for j in find_photos(tmp_path / "in", recursive=True,
                                        skip=tmp_path / "in" / "trip")] == ["a", "b"]
    # nor, with --recursive, the input folder itself (its 3D photo folders are entered)
    assert [j.name for j in find_photos(tmp_path / "in", skip=tmp_path / "in")] == ["a", "b"]
    with pytest.raises(InputError, match="the output folder cannot be the input folder"):
        find_photos(tmp_path / "in", recursive=True, skip=tmp_path / "in" / ".." / "in")


def test_find_photos_refuses_ambiguous_or_missing_input(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        find_photos(tmp_path / "nope")
    with pytest.raises(InputError, match="no photos in"):
        find_photos(tmp_path)
    (tmp_path / "a.jpg").touch()
    (tmp_path / "a.png").touch()
    with pytest.raises(InputError, match="same output folder 'a': a.jpg and a.png"):
        find_photos(tmp_path)
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "x.png").touch()
    (tmp_path / "d" / "x.npy").touch()
    (tmp_path / "a.png").unlink()
    with pytest.raises(InputError, match="two maps for 'x'"):
        find_photos(tmp_path, depth=tmp_path / "d")
    (tmp_path / "trip" / "x").mkdir(parents=True)
    (tmp_path / "trip" / "x" / "c.jpg").touch()
    (tmp_path / "trip.png").touch()  # OUT/trip would hold OUT/trip/x/c
    assert [j.name for j in find_photos(tmp_path)] == ["a", "trip"]  # not recursive: fine
    with pytest.raises(InputError, match=r"nest .* 'trip/x/c' of trip/x/c.jpg inside 'trip' "
                                         r"of trip.png \(rename one\)"):
        find_photos(tmp_path, recursive=True)


def test_batch_makes_what_make_makes_records_failures_and_resumes(photos, capsys, monkeypatch):
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")  # the plain photo: no model, one-line failure
    out = photos / "out"
    argv = ["batch", str(photos / "photos"), "-o", str(out), "--depth", str(photos / "depth"),
            "--workers", "2", *FAST]
    assert main(argv) == 1  # some failed, all others done
    std = capsys.readouterr()
    assert "batch: 3 ok, 2 failed, 0 skipped" in std.out
    lines = std.err.strip().splitlines()  # not a terminal: one plain line per photo
    assert len(lines) == 5 and all(line.startswith("[") for line in lines)
    assert any("broken: failed: cannot read image" in line for line in lines)
    manifest = [json.loads(line) for line in (out / "batch.jsonl").read_text().splitlines()]
    assert [r["name"] for r in manifest] == ["a", "b", "broken", "c", "plain"]
    status = {r["name"]: r for r in manifest}
    assert {n: r["status"] for n, r in status.items()} == {
        "a": "ok", "b": "ok", "c": "ok", "broken": "failed", "plain": "failed"}
    assert "\n" not in status["plain"]["error"]
    assert "--depth FILE, --right IMAGE or --depth-model NAME" in status["plain"]["error"]
    assert status["a"]["error"] is None and status["a"]["seconds"] > 0
    assert status["a"]["output"] == str(out / "a") and "a.npy" in status["a"]["depth"]
    # long-lived workers: at most two processes made the photos (models loaded once each)
    assert len({r["worker"] for r in manifest if r["worker"]}) <= 2
    # exactly what make writes
    ref = photos / "ref"
    assert main(["make", str(photos / "photos" / "b.png"), "--depth",
                 str(photos / "depth" / "b.npy"), "-o", str(ref), *FAST, "-q"]) == 0
    assert sorted(p.name for p in (out / "b").iterdir()) == sorted(p.name for p in ref.iterdir())
    ldi_batch, _ = load_npz(out / "b" / "photo3d.npz")
    ldi_make, _ = load_npz(ref / "photo3d.npz")
    assert np.array_equal(ldi_batch.color, ldi_make.color)
    assert np.array_equal(ldi_batch.links, ldi_make.links)
    assert not (out / "broken").exists() and not (out / "plain").exists()
    # run again: finished photos skipped, failed ones retried (the broken one is fixed now)
    (photos / "photos" / "broken.jpg").unlink()
    add_photo(photos / "photos", "broken", photos / "depth", seed=3)
    mtime = (out / "a" / "photo3d.npz").stat().st_mtime_ns
    assert main(argv) == 1
    assert "batch: 1 ok, 1 failed, 3 skipped" in capsys.readouterr().out
    records = read_manifest(out / "batch.jsonl")
    assert records["broken"]["status"] == "ok" and records["a"]["status"] == "skipped"
    assert records["a"]["depth"] == status["a"]["depth"]  # kept from the run that made it
    assert (out / "a" / "photo3d.npz").stat().st_mtime_ns == mtime
    assert len((out / "batch.jsonl").read_text().splitlines()) == 5  # one line per photo
    (photos / "photos" / "plain.png").unlink()
    assert main([*argv, "-q"]) == 0
    assert capsys.readouterr().out == ""


def test_batch_library_reports_progress_and_keeps_going(tmp_path):
    add_photo(tmp_path, "a", tmp_path)
    (tmp_path / "z.png").write_bytes(b"\x89PNG broken")
    jobs = find_photos(tmp_path) + [PhotoJob("missing", tmp_path / "missing.png")]
    jobs[0] = PhotoJob("a", tmp_path / "a.png", tmp_path / "a.npy")
    seen = []
    options = MakeOptions(config=Config(size=64),
                          save=SaveOptions(glb=False, viewer=False, ply=None))
    summary = run_batch(jobs, tmp_path / "out", options, workers=1,
                        progress=lambda r, done, total: seen.append((r.status, done, total)))
    assert (summary.ok, summary.failed, summary.skipped) == (1, 2, 0)
    assert sorted(s for s, _, _ in seen) == ["failed", "failed", "ok"]
    assert [(done, total) for _, done, total in seen] == [(1, 3), (2, 3), (3, 3)]
    assert {n for n, _ in summary.failures} == {"z", "missing"}


def test_out_dir_that_is_a_file_or_bad_options_are_refused_before_any_work(photos, capsys):
    target = photos / "file"
    target.write_text("x")
    base = ["batch", str(photos / "photos"), "--depth", str(photos / "depth")]
    for argv, message in (
        ([*base, "-o", str(target)], "exists and is not a folder"),
        ([*base, "-o", str(photos / "o"), "--workers", "0"], "--workers must be at least 1"),
        ([*base, "-o", str(photos / "o"), "--inpainter", "magic"], "unknown inpainter"),
        ([*base, "-o", str(photos / "o"), "--ray-address", "x:1"], "only applies to --engine"),
        (["batch", str(photos / "nope"), "-o", str(photos / "o")], "does not exist"),
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("photo3d: error:") and message in err[0]
    assert not (photos / "o").exists()


def test_discard_partial_removes_only_what_a_killed_writer_staged(tmp_path):
    out = tmp_path / "a"
    staged = stage_photo(out, overwrite=False).path  # a writer killed before its commit
    release(staged, keep=True)  # (its lock went with it)
    assert staged.parent == tmp_path and staged.is_dir()
    for name in (".a.old", ".ab.1a2b3c4d.tmp", ".a.1a2b3c4d", ".a.notahex!.tmp", "a"):
        (tmp_path / name).mkdir()
    (tmp_path / ".a.0f0f0f0f.tmp").write_text("a file, not a staged folder")
    (tmp_path / ".a.0123abcd.tmp").mkdir()  # a user's folder named like one: no writer mark
    (tmp_path / ".a.0123abcd.tmp" / "keep.txt").write_text("the user's")
    discard_partial(out)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        ".a.0123abcd.tmp", ".a.0f0f0f0f.tmp", ".a.1a2b3c4d", ".a.notahex!.tmp", ".a.old",
        ".ab.1a2b3c4d.tmp", "a"]


def test_discard_partial_waits_for_a_worker_letting_go_of_its_folder(tmp_path):
    """A worker the batch killed may hold its staged folder a moment longer (a Ray
    actor dying of the Ctrl-C itself): with ``wait`` it is removed once let go,
    without it a held folder stays (a live make's)."""
    import threading

    out = tmp_path / "a"
    staged = stage_photo(out, overwrite=False).path  # held by this process: alive
    discard_partial(out)
    assert staged.is_dir()
    threading.Timer(0.2, release, (staged,), {"keep": True}).start()  # its process ends
    discard_partial(out, wait=5.0)
    assert not staged.exists()


def test_ctrl_c_stops_cleanly_and_a_rerun_resumes(tmp_path):
    src, depth, out = tmp_path / "photos", tmp_path / "depth", tmp_path / "out"
    src.mkdir()
    depth.mkdir()
    for i in range(4):
        add_photo(src, f"p{i}", depth, seed=i)
    # videos make each photo take a few seconds, so Ctrl-C lands while photos are made
    argv = [sys.executable, "-m", "photo3d", "batch", str(src), "-o", str(out), "--depth",
            str(depth), "--workers", "2", "--size", "64", "--frames", "40", "--no-glb",
            "--no-viewer", "--path", "circle"]
    # default SIGINT in the child even if we were started with it ignored (background job);
    # its own process group, so Ctrl-C can reach the batch and its workers as a terminal does
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        def writing() -> bool:
            return out.is_dir() and any(p.name.startswith(".p") for p in out.iterdir())

        assert wait_for(writing, 120), "no photo started"
        os.killpg(proc.pid, signal.SIGINT)  # what Ctrl-C at a terminal does
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130
    assert "Traceback" not in stderr and stderr.strip().splitlines()[-1] == "photo3d: interrupted"
    left = sorted(p.name for p in out.iterdir())
    assert not [n for n in left if n.startswith(".") and n != ".batch.jsonl"], left
    assert all(is_complete(out / n) for n in left if n != "batch.jsonl")  # nothing partial
    finished = [n for n in left if n != "batch.jsonl"]
    assert len(finished) < 4
    # a re-run picks up where it stopped
    done = subprocess.run(argv, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert f"{4 - len(finished)} ok, 0 failed, {len(finished)} skipped" in done.stdout
    assert all(is_complete(out / f"p{i}") for i in range(4))
    assert (out / "p0" / "video" / "circle.mp4").is_file()


def test_a_finished_folder_is_defined_once():
    import photo3d.batch
    import photo3d.batch.worker
    import photo3d.folder
    import photo3d.output
    import photo3d.owned

    assert photo3d.batch.is_complete is photo3d.output.is_complete
    assert photo3d.batch.worker.is_complete is photo3d.output.is_complete
    assert set(photo3d.owned.FINISHED_FILES) <= set(photo3d.owned.PHOTO_FILES)
    assert photo3d.batch.MakeOptions is photo3d.folder.MakeOptions


def test_a_photo_without_a_depth_map_keeps_its_model_kind(tmp_path, monkeypatch):
    """--depth-kind describes the depth folder's maps; a photo without one uses the
    depth model (or its embedded map) with the model's own kind."""
    from photo3d.batch import PhotoMaker
    from photo3d.depth import sources

    seen = []

    def fake_resolve(image, **kw):
        seen.append((Path(image).name, kw["kind"], kw["depth"] is not None))
        raise InputError("stop here")

    monkeypatch.setattr(sources, "resolve_depth", fake_resolve)
    add_photo(tmp_path, "a", tmp_path)
    add_photo(tmp_path, "b", None)
    maker = PhotoMaker(MakeOptions(depth_kind="depth"))
    for job in (PhotoJob("a", tmp_path / "a.png", tmp_path / "a.npy"),
                PhotoJob("b", tmp_path / "b.png")):
        assert maker(job, tmp_path / "out").error == "stop here"
    assert seen == [("a.png", "depth", True), ("b.png", None, False)]


def test_a_photos_reader_warnings_go_into_its_record_not_onto_stderr(tmp_path, capfd):
    """A multi-page TIFF's warning was printed raw by the worker (file, line and the
    source line: two lines, not photo3d's) and left out of the manifest."""
    from PIL import Image

    from photo3d.batch import PhotoMaker

    img, d = two_planes(48, 64, 24)
    page = Image.fromarray((img * 255).astype(np.uint8))
    page.save(tmp_path / "a.tif", save_all=True, append_images=[page])
    np.save(tmp_path / "a.npy", d)
    maker = PhotoMaker(MakeOptions(config=Config(size=64),
                                   save=SaveOptions(glb=False, ply=None, viewer=False)))
    result = maker(PhotoJob("a", tmp_path / "a.tif", tmp_path / "a.npy"), tmp_path / "out")
    assert result.status == "ok", result.error
    assert result.warnings == ("a.tif has 2 pages; photo3d uses the first",)
    assert capfd.readouterr().err == ""
