"""photo3d batch --engine ray on signals and dead actors, as the local engine (local Ray,
2 CPUs; skipped without ray)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from test_batch import FAST, add_photo

from photo3d.batch import ray_engine
from photo3d.batch.worker import is_complete
from photo3d.cli import main

ray = pytest.importorskip("ray")


def _folders(tmp_path: Path, count: int) -> tuple[Path, Path, Path]:
    src, depth, out = tmp_path / "photos", tmp_path / "depth", tmp_path / "out"
    src.mkdir()
    depth.mkdir()
    for i in range(count):
        add_photo(src, f"p{i}", depth, seed=i)
    return src, depth, out


def _records(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "batch.jsonl").read_text().splitlines()]


def test_a_dead_actor_costs_only_its_photo(tmp_path, capsys, monkeypatch):
    """p0 kills its actor every time: tried twice, then failed; p1 kills it once: made
    again on a new actor; p2 is made as usual."""
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    src, depth, out = _folders(tmp_path, 3)
    log = tmp_path / "attempts"
    log.mkdir()

    class Crashing(ray_engine._Actor):  # a local class: Ray sends it by value
        def make(self, job, out_dir):
            tries = log / job.name
            with open(tries, "a") as f:
                f.write(f"{os.getpid()}\n")
            if job.name == "p0":
                os.kill(os.getpid(), signal.SIGKILL)
            if job.name == "p1" and len(tries.read_text().split()) == 1:
                os._exit(3)
            return super().make(job, out_dir)

    monkeypatch.setattr(ray_engine, "_Actor", Crashing)
    argv = ["batch", str(src), "-o", str(out), "--depth", str(depth), "--engine", "ray",
            "--workers", "2", *FAST]
    assert main(argv) == 1
    printed = capsys.readouterr()
    assert "batch: 2 ok, 1 failed, 0 skipped" in printed.out
    assert "Traceback" not in printed.err, printed.err
    assert not ray.is_initialized()
    records = _records(out)
    assert [(r["name"], r["status"]) for r in records] == [
        ("p0", "failed"), ("p1", "ok"), ("p2", "ok")]
    assert "died twice" in records[0]["error"] and "ActorDiedError" in records[0]["error"]
    p0, p1 = ((log / name).read_text().split() for name in ("p0", "p1"))
    assert len(p0) == 2 and len(set(p0)) == 2  # retried once, on a new actor
    assert len(p1) == 2 and records[1]["worker"].endswith(f":{p1[1]}") and p1[0] != p1[1]
    assert is_complete(out / "p1") and is_complete(out / "p2")
    assert sorted(p.name for p in out.iterdir()) == ["batch.jsonl", "p1", "p2"]  # no temp


# The batch in a child process, with actors that make p0 at once and stall in the
# inpainter (inside the photo's temporary folder) on the other photos.
_SLOW_BATCH = textwrap.dedent("""
    import sys, time
    from photo3d.batch import ray_engine
    from photo3d.cli import main

    class Stalled:
        def __init__(self, inner):
            self.inner = inner

        def __getattr__(self, name):
            return getattr(self.inner, name)

        def inpaint(self, *args, **kwargs):
            time.sleep(120)
            return self.inner.inpaint(*args, **kwargs)

    class Slow(ray_engine._Actor):
        def make(self, job, out_dir):
            if job.name != "p0" and not isinstance(self.maker.inpainter, Stalled):
                self.maker.inpainter = Stalled(self.maker.inpainter)
            return super().make(job, out_dir)

    ray_engine._Actor = Slow
    sys.exit(main(sys.argv[1:]))
""")


@pytest.mark.parametrize(("sig", "status", "line"), [
    (signal.SIGTERM, 143, "photo3d: interrupted (SIGTERM)"),
    (signal.SIGINT, 130, "photo3d: interrupted")])
def test_signals_stop_the_batch_as_the_local_engine_does(tmp_path, sig, status, line):
    src, depth, out = _folders(tmp_path, 3)
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    argv = [sys.executable, "-c", _SLOW_BATCH, "batch", str(src), "-o", str(out),
            "--depth", str(depth), "--engine", "ray", "--workers", "2", *FAST]
    # its own process group, with default SIGINT: a Ctrl-C reaches all of it, as at a terminal
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 120
        while not (is_complete(out / "p0") and (out / "batch.jsonl").is_file()
                   and any(p.name.startswith((".p1", ".p2")) for p in out.iterdir())):
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
            time.sleep(0.1)
        time.sleep(0.5)
        if sig == signal.SIGINT:
            os.killpg(proc.pid, sig)  # what Ctrl-C at a terminal does
        else:
            proc.send_signal(sig)
        _, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == status, stderr
    assert "Traceback" not in stderr and "Fatal Python" not in stderr, stderr
    assert stderr.strip().splitlines()[-1] == line, stderr
    assert [(r["name"], r["status"]) for r in _records(out)] == [("p0", "ok")]
    assert sorted(p.name for p in out.iterdir()) == ["batch.jsonl", "p0"]  # no temp folder
