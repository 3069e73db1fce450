"""photo3d batch --engine ray on a local Ray with 2 CPUs (skipped without ray)."""

from __future__ import annotations

import json

import pytest
from test_batch import FAST, add_photo

from photo3d.cli import main

ray = pytest.importorskip("ray")


def test_batch_on_a_local_ray(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    src, depth, out = tmp_path / "photos", tmp_path / "depth", tmp_path / "out"
    src.mkdir()
    depth.mkdir()
    for i in range(3):
        add_photo(src, f"p{i}", depth, seed=i)
    (src / "zz.png").write_bytes(b"\x89PNG broken")
    argv = ["batch", str(src), "-o", str(out), "--depth", str(depth), "--engine", "ray",
            "--workers", "2", *FAST]
    assert main(argv) == 1
    assert "batch: 3 ok, 1 failed, 0 skipped" in capsys.readouterr().out
    assert not ray.is_initialized()  # the local Ray it started is shut down
    records = [json.loads(line) for line in (out / "batch.jsonl").read_text().splitlines()]
    assert [(r["name"], r["status"]) for r in records] == [
        ("p0", "ok"), ("p1", "ok"), ("p2", "ok"), ("zz", "failed")]
    assert all((out / f"p{i}" / "photo3d.npz").is_file() for i in range(3))
    # two actors made all the photos (each built its inpainter once)
    assert len({r["worker"] for r in records}) <= 2
    # resumable like the local engine; nothing to do means Ray is not even started
    (src / "zz.png").unlink()
    assert main(argv) == 0
    assert "batch: 0 ok, 0 failed, 3 skipped" in capsys.readouterr().out
