"""photo3d batch against hostile folders and failures: every photo is accounted for,
and nothing outside OUT (nor in OUT that the batch did not write) is touched."""

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

from photo3d.batch import find_photos, local, read_manifest
from photo3d.batch.lock import batch_lock
from photo3d.batch.manifest import record_problem
from photo3d.batch.worker import discard_partial
from photo3d.cli import main
from photo3d.errors import OutputError
from photo3d.files.temps import release
from photo3d.io.images import write_image
from photo3d.output import is_complete, stage_photo

FAST = ["--size", "64", "--no-video", "--no-glb", "--no-viewer"]


def add_photo(folder: Path | bytes, name: str | bytes, depth: Path | bytes | None,
              seed: int = 0) -> None:
    """``folder/name.png`` and, if ``depth``, ``depth/name.npy`` (names may be bytes)."""
    img, d = two_planes(48, 64, 24 + 4 * seed)
    raw = os.fsencode(name)
    write_image(os.fsdecode(os.path.join(os.fsencode(folder), raw + b".png")), img)
    if depth is not None:
        np.save(os.fsdecode(os.path.join(os.fsencode(depth), raw + b".npy")), d)


def tree(root: Path, *, leave_out: Path) -> dict[bytes, tuple]:
    """Every entry under ``root`` but ``leave_out``: (mode, size, mtime, link target)."""
    found = {}
    skip = os.fsencode(leave_out)
    for folder, dirs, files in os.walk(os.fsencode(root)):
        dirs[:] = [d for d in dirs if os.path.join(folder, d) != skip]
        for name in dirs + files:
            path = os.path.join(folder, name)
            st = os.lstat(path)
            link = os.readlink(path) if os.path.islink(path) else None
            found[path] = (st.st_mode, st.st_size, st.st_mtime_ns, link)
    return found


def records(out: Path) -> list[dict]:
    """The manifest's lines, each checked to be a well-formed record."""
    lines = [json.loads(line) for line in (out / "batch.jsonl").read_text("utf-8").splitlines()]
    assert [record_problem(r) for r in lines] == [None] * len(lines)
    return lines


@pytest.fixture
def folders(tmp_path):
    """IN (photos a, b with depth maps), DEPTH, and OUT (not made yet)."""
    src, depth = tmp_path / "in", tmp_path / "depth"
    src.mkdir()
    depth.mkdir()
    for i, name in enumerate("ab"):
        add_photo(src, name, depth, seed=i)
    return src, depth, tmp_path / "out"


def batch(src: Path, depth: Path, out: Path, *extra: str) -> list[str]:
    return ["batch", str(src), "-o", str(out), "--depth", str(depth), "--workers", "1",
            *FAST, "-q", *extra]


def test_a_file_name_that_is_not_utf8_works_and_one_that_fails_fails_alone(folders):
    src, depth, out = folders
    add_photo(src, b"caf\xe9", depth, seed=2)
    add_photo(src, "caf\\xe9", depth, seed=3)  # the escape's own text: a different photo
    (Path(os.fsdecode(os.fsencode(src) + b"/bad\xff.png"))).write_bytes(b"not a png")
    before = tree(src.parent, leave_out=out)
    run = subprocess.run([sys.executable, "-m", "photo3d", *batch(src, depth, out)],
                         capture_output=True, timeout=300)
    assert run.returncode == 1, run.stderr
    err = run.stderr.decode("utf-8", "replace").strip().splitlines()
    assert len(err) == 1 and err[0].startswith("photo3d: failed: bad"), err
    status = {r["name"]: r for r in records(out)}
    assert {n: r["status"] for n, r in status.items()} == {
        "a": "ok", "b": "ok", "caf\\xe9": "ok", "caf\\\\xe9": "ok", "bad\\xff": "failed"}
    assert status["caf\\xe9"]["output"] == str(out) + "/caf\\xe9"
    assert is_complete(Path(os.fsdecode(os.fsencode(out) + b"/caf\xe9")))
    assert tree(src.parent, leave_out=out) == before
    # a second run reads it back: the finished photo is skipped, the bad one retried
    run = subprocess.run([sys.executable, "-m", "photo3d", *batch(src, depth, out)],
                         capture_output=True, timeout=300)
    assert run.returncode == 1
    status = {r["name"]: r["status"] for r in records(out)}
    assert status == {"a": "skipped", "b": "skipped", "caf\\xe9": "skipped",
                      "caf\\\\xe9": "skipped", "bad\\xff": "failed"}


def test_recursive_visits_each_real_folder_once(folders, capsys):
    src, depth, out = folders
    (src / "sub").mkdir()
    add_photo(src / "sub", "c", None, seed=2)
    (src / "sub" / "loop").symlink_to(src)  # IN/sub/loop/sub/loop/... (~40 deep, then ELOOP)
    (depth / "sub").mkdir()
    np.save(depth / "sub" / "c.npy", two_planes(48, 64, 32)[1])
    assert [j.name for j in find_photos(src, recursive=True)] == ["a", "b", "sub/c"]
    before = tree(src.parent, leave_out=out)
    assert main(batch(src, depth, out, "--recursive")) == 0
    assert capsys.readouterr().err == ""
    assert [r["name"] for r in records(out)] == ["a", "b", "sub/c"]
    assert tree(src.parent, leave_out=out) == before
    # two links to one folder, a link to itself: the real folder's name is kept
    dup = src.parent / "dup"
    (dup / "x").mkdir(parents=True)
    add_photo(dup / "x", "d", None)
    for link in ("w", "y"):
        (dup / link).symlink_to(dup / "x")
    (dup / "x" / "self").symlink_to(".")
    assert [j.name for j in find_photos(dup, recursive=True)] == ["x/d"]


def test_names_that_would_miss_their_folder_fail_alone_in_one_line(folders, capsys):
    src, depth, out = folders
    for name in ("..png", "batch.jsonl.png", "BATCH.LOCK.png", ".hidden.png"):
        add_photo(src, name[:-4], None)
    before = tree(src.parent, leave_out=out)
    assert main(batch(src, depth, out)) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 4 and all(line.startswith("photo3d: failed: ") for line in err), err
    assert "'.' would not be a folder inside the output folder" in "\n".join(err)
    status = {r["name"]: r["status"] for r in records(out)}
    assert status == {".": "failed", "batch.jsonl": "failed", "BATCH.LOCK": "failed",
                      ".hidden": "failed", "a": "ok", "b": "ok"}
    assert sorted(p.name for p in out.iterdir()) == ["a", "b", "batch.jsonl"]
    assert tree(src.parent, leave_out=out) == before


def test_bad_manifest_records_are_reported_and_their_photos_made_again(folders, capsys):
    src, depth, out = folders
    assert main(batch(src, depth, out)) == 0
    lines = (out / "batch.jsonl").read_text().splitlines()
    broken = json.loads(lines[0])
    assert broken["name"] == "a"
    broken["warnings"] = None
    # a damaged record, and a line cut short by a crash (a line photo3d did not write at
    # all is refused: test_batch_ownership.py)
    (out / "batch.jsonl").write_text("\n".join([json.dumps(broken), lines[1], '{"name": "c"']))
    made = (out / "a" / "photo3d.npz").stat().st_mtime_ns
    kept = (out / "b" / "photo3d.npz").stat().st_mtime_ns
    assert main(batch(src, depth, out)) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("photo3d: warning: batch.jsonl: 2 bad line"), err
    assert "line 1: 'warnings' is null" in err[0] and "line 3: not JSON" in err[0]
    assert [(r["name"], r["status"]) for r in records(out)] == [("a", "ok"), ("b", "skipped")]
    assert (out / "a" / "photo3d.npz").stat().st_mtime_ns != made
    assert (out / "b" / "photo3d.npz").stat().st_mtime_ns == kept


def test_a_manifest_that_is_a_link_is_refused_before_any_work(folders, capsys):
    src, depth, out = folders
    out.mkdir()
    victim = src.parent / "victim.txt"
    victim.write_text("not yours")
    (out / "batch.jsonl").symlink_to(victim)
    before = tree(src.parent, leave_out=out)
    assert main(batch(src, depth, out)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is a symbolic link" in err[0], err
    assert sorted(p.name for p in out.iterdir()) == ["batch.jsonl"]
    assert tree(src.parent, leave_out=out) == before


def test_a_full_disk_in_the_manifest_writer_is_one_line(folders, capsys, monkeypatch):
    import errno

    from photo3d.batch import manifest

    class FullDisk:
        def __getattr__(self, name):
            return getattr(os, name)

        @staticmethod
        def fsync(fd):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    src, depth, out = folders
    monkeypatch.setattr(manifest, "os", FullDisk())
    before = tree(src.parent, leave_out=out)
    assert main(batch(src, depth, out)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot write the manifest" in err[0], err
    assert "No space left on device" in err[0]
    assert not [p.name for p in out.iterdir() if p.name.startswith(".")]
    assert all(is_complete(p) for p in out.iterdir() if p.is_dir())  # nothing partial
    assert tree(src.parent, leave_out=out) == before


def _run_or_die(job, out_dir):
    """The pool's task in the dying-worker test (runs in the worker process)."""
    marker = Path(os.environ["PHOTO3D_TEST_MARKERS"]) / job.name
    if job.name == "doomed" or job.name == "once" and not marker.exists():
        marker.touch()
        stage_photo(Path(out_dir) / job.name, overwrite=False)  # then killed mid-write
        os.kill(os.getpid(), signal.SIGKILL)
    return local._run(job, out_dir)


def test_a_killed_worker_is_retried_once_then_its_photo_fails(folders, capsys, monkeypatch,
                                                              tmp_path_factory):
    src, depth, out = folders
    for i, name in enumerate(("doomed", "once")):
        add_photo(src, name, depth, seed=i + 2)
    out.mkdir()
    leftover = stage_photo(out / "a", overwrite=False).path  # a worker killed last run
    release(leftover, keep=True)  # (its lock went with it)
    (out / ".a.notes").mkdir()  # not the batch's: kept
    monkeypatch.setenv("PHOTO3D_TEST_MARKERS", str(tmp_path_factory.mktemp("markers")))
    monkeypatch.setattr(local, "_run", _run_or_die)
    before = tree(src.parent, leave_out=out)
    assert main(batch(src, depth, out)) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("photo3d: failed: doomed: the worker"), err
    status = {r["name"]: r["status"] for r in records(out)}
    assert status == {"a": "ok", "b": "ok", "doomed": "failed", "once": "ok"}
    assert not leftover.exists() and (out / ".a.notes").is_dir()
    assert sorted(p.name for p in out.iterdir()) == [
        ".a.notes", "a", "b", "batch.jsonl", "once"]
    assert tree(src.parent, leave_out=out) == before
    # again: the summary still counts every photo (the doomed one dies twice more)
    assert main(batch(src, depth, out)[:-1]) == 1
    std = capsys.readouterr()
    assert "batch: 0 ok, 1 failed, 3 skipped" in std.out
    assert [line for line in std.err.splitlines() if "failed" in line] == [
        "[4/4] doomed: failed: the worker process making this photo died twice "
        "(out of memory?)"]


def _children(pid: int) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                found.append(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_workers_exit_with_the_batch_and_a_second_batch_is_refused(tmp_path, capsys):
    src, depth, out = tmp_path / "in", tmp_path / "depth", tmp_path / "out"
    src.mkdir()
    depth.mkdir()
    for i in range(4):
        add_photo(src, f"p{i}", depth, seed=i)
    slow = [sys.executable, "-m", "photo3d", "batch", str(src), "-o", str(out), "--depth",
            str(depth), "--workers", "2", "--size", "64", "--frames", "40", "--no-glb",
            "--no-viewer", "--path", "circle", "-q"]
    # no pipes: workers that outlived it would keep them open and hang this test
    proc = subprocess.Popen(slow, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        def writing() -> bool:
            return out.is_dir() and any(p.name.startswith(".p") for p in out.iterdir())

        assert wait_for(writing, 120), "no photo started"
        workers = _children(proc.pid)
        assert workers
        # the same OUT while the first batch runs: refused in one line, nothing of its
        # own written (its photo is not one of the first batch's, which keeps writing)
        other = tmp_path / "other"
        other.mkdir()
        add_photo(other, "zz", depth, seed=9)
        assert main(["batch", str(other), "-o", str(out), "--depth", str(depth), *FAST]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "another photo3d batch is writing" in err[0], err
        assert not [p.name for p in out.iterdir() if "zz" in p.name]
        manifest = out / "batch.jsonl"
        assert not manifest.exists() or "zz" not in manifest.read_text()
        proc.kill()  # SIGKILL: no chance to stop its workers itself
        proc.wait(timeout=30)
        assert wait_for(lambda: not any(map(_alive, workers)), 30), "workers outlived it"
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=30)
        for pid in _children(1) + _children(proc.pid):  # only ever our own orphans
            if pid in workers:
                os.kill(pid, signal.SIGKILL)
    # their temporary folders went with them; the killed batch's lock blocks nobody
    assert not [p.name for p in out.iterdir() if p.name.startswith(".")]
    assert main(["batch", str(src), "-o", str(out), "--depth", str(depth), *FAST, "-q"]) == 0
    assert {r["status"] for r in records(out)} <= {"ok", "skipped"}
    assert len(records(out)) == 4 and not (out / "batch.lock").exists()


def test_the_lock_is_released_when_the_batch_ends(folders, capsys):
    src, depth, out = folders
    out.mkdir()
    with batch_lock(out):
        assert main(batch(src, depth, out)) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "another photo3d batch is writing" in err[0]
        assert sorted(p.name for p in out.iterdir()) == ["batch.lock"]
    assert main(batch(src, depth, out)) == 0
    assert sorted(p.name for p in out.iterdir()) == ["a", "b", "batch.jsonl"]
    assert read_manifest(out / "batch.jsonl")["a"]["status"] == "ok"
    # a lock file that is a link is not written through either
    victim = src.parent / "victim.txt"
    victim.write_text("not yours")
    (out / "batch.lock").symlink_to(victim)
    assert main(batch(src, depth, out)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot create the lock file" in err[0], err
    assert victim.read_text() == "not yours" and (out / "batch.lock").is_symlink()


def test_a_batch_never_removes_what_a_live_make_is_writing_into_out(folders, capsys):
    """A ``make -o OUT/a`` running when a batch of OUT starts (or loses a worker) keeps
    its temporary folder: only those whose writer is gone are removed. The two race as
    two makes do: the first to finish wins, the other fails in one line."""
    src, depth, out = folders
    out.mkdir()
    live = stage_photo(out / "a", overwrite=False)  # this process is the live `make`
    killed = stage_photo(out / "b", overwrite=False).path
    release(killed, keep=True)  # its writer was killed: nobody holds its lock
    assert main(batch(src, depth, out)) == 0
    assert live.path.is_dir() and not killed.exists()
    with pytest.raises(OutputError, match="changed while photo3d was working"):
        live.commit()
    live.discard()
    assert sorted(p.name for p in out.iterdir()) == ["a", "b", "batch.jsonl"]
    # a worker that dies: what it staged goes, the live make's stays
    live = stage_photo(out / "c", overwrite=False)
    discard_partial(out / "c")
    assert live.path.is_dir()
    live.discard()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_NOFILE, /proc")
def test_too_few_file_descriptors_for_the_workers_is_one_line(folders):
    """``ulimit -n 16``: the pool's pipes could not open; it was a traceback."""
    import resource

    src, depth, out = folders

    def limit():
        resource.setrlimit(resource.RLIMIT_NOFILE, (16, 16))

    run = subprocess.run([sys.executable, "-m", "photo3d", *batch(src, depth, out),
                          "--workers", "2"], capture_output=True, text=True, preexec_fn=limit)
    err = run.stderr.strip().splitlines()
    assert run.returncode == 1 and len(err) == 1, run.stderr
    assert err[0] == ("photo3d: error: too many open files (the limit, ulimit -n, is 16): "
                      "raise it or use fewer --workers"), err
    assert not [p.name for p in out.iterdir()] if out.exists() else True
