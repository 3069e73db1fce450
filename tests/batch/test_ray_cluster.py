"""photo3d batch --engine ray --ray-address on a local cluster of two one-CPU nodes
(``ray.cluster_utils.Cluster``; the head has no CPU, so every actor runs on a node):
the same outputs as the local engine, one thread per actor, and a node that dies
while it holds a photo. Skipped without ray.

The worker processes of the nodes import photo3d from this process's
``sys.path`` (its ``PYTHONPATH`` is theirs), which the first test checks.
"""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import pytest
from test_batch import FAST, add_photo
from test_make_parity import same_output

import photo3d
from photo3d.batch import ray_engine
from photo3d.batch.worker import is_complete
from photo3d.cli import main

ray = pytest.importorskip("ray")
cluster_utils = pytest.importorskip("ray.cluster_utils")

_TIMEOUT_S = 240
"""Longest batch in these tests (a hung engine fails the test instead of the run)."""


@pytest.fixture(scope="module")
def cluster():
    """A head without CPUs and two nodes of one CPU each."""
    made = cluster_utils.Cluster(initialize_head=True, head_node_args={"num_cpus": 0})
    try:
        for _ in range(2):
            made.add_node(num_cpus=1)
        made.wait_for_nodes()
        yield made
    finally:
        if ray.is_initialized():
            ray.shutdown()
        made.shutdown()


@pytest.fixture
def two_nodes(cluster):
    """The cluster, with two worker nodes again if a test removed one."""
    while len(cluster.worker_nodes) < 2:
        cluster.add_node(num_cpus=1)
    cluster.wait_for_nodes()
    return cluster


def _batch(argv: list[str]) -> int:
    """``photo3d batch argv`` in a thread; its exit status, or a failed test when it
    takes more than :data:`_TIMEOUT_S` (an engine waiting forever)."""
    status: list[int] = []
    thread = threading.Thread(target=lambda: status.append(main(["batch", *argv])),
                              daemon=True)
    thread.start()
    thread.join(_TIMEOUT_S)
    assert status, f"the batch did not end within {_TIMEOUT_S} s"
    return status[0]


def _folders(tmp_path: Path, count: int) -> tuple[Path, Path]:
    src, depth = tmp_path / "photos", tmp_path / "depth"
    src.mkdir()
    depth.mkdir()
    for i in range(count):
        add_photo(src, f"p{i}", depth, seed=i)
    return src, depth


def _records(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "batch.jsonl").read_text().splitlines()]


def test_two_nodes_make_what_the_local_engine_makes(tmp_path, two_nodes, monkeypatch):
    """Both nodes make photos, each actor with one thread, photo3d from this tree, and
    the LDI of every photo is the local engine's."""
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    src, depth = _folders(tmp_path, 4)
    log = tmp_path / "where"
    log.mkdir()

    class Reporting(ray_engine._Actor):  # a local class: Ray sends it by value
        def __init__(self, *args):
            super().__init__(*args)
            (log / f"actor-{ray.get_runtime_context().get_node_id()}").touch()

        def make(self, job, out_dir):  # each photo waits for both actors to be up
            import numba

            deadline = time.monotonic() + _TIMEOUT_S / 2
            while len(list(log.glob("actor-*"))) < 2 and time.monotonic() < deadline:
                time.sleep(0.05)

            import photo3d as imported
            from photo3d import parallel

            (log / job.name).write_text(json.dumps({
                "node": ray.get_runtime_context().get_node_id(), "file": imported.__file__,
                "threads": parallel.threads(), "numba": numba.get_num_threads()}))
            return super().make(job, out_dir)

    monkeypatch.setattr(ray_engine, "_Actor", Reporting)
    common = ["--depth", str(depth), *FAST, "-q"]
    assert main(["batch", str(src), "-o", str(tmp_path / "local"), "--workers", "1",
                 *common]) == 0
    assert _batch([str(src), "-o", str(tmp_path / "ray"), "--engine", "ray",
                   "--ray-address", two_nodes.address, *common]) == 0
    assert not ray.is_initialized()  # disconnected from the cluster it connected to
    records = _records(tmp_path / "ray")
    assert [(r["name"], r["status"]) for r in records] == [(f"p{i}", "ok") for i in range(4)]
    seen = [json.loads((log / f"p{i}").read_text()) for i in range(4)]  # node, threads
    nodes = {n.node_id for n in two_nodes.worker_nodes}
    assert {s["node"] for s in seen} == nodes  # both nodes made photos
    assert len({r["worker"] for r in records}) == 2  # two actors, one per node
    assert all(s["file"] == photo3d.__file__ for s in seen)  # this tree's photo3d
    assert all(s["threads"] == 1 and s["numba"] == 1 for s in seen)  # one CPU: one thread
    for i in range(4):
        same_output(tmp_path / "local" / f"p{i}", tmp_path / "ray" / f"p{i}")


def test_a_photo_whose_node_dies_is_made_on_the_other_node(tmp_path, two_nodes, monkeypatch):
    """p0's node is killed while p0 is half-made (its temporary folder written): p0 is
    made again on the node left, the manifest says so, nothing partial is left."""
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    src, depth = _folders(tmp_path, 3)
    out, log = tmp_path / "out", tmp_path / "where"
    log.mkdir()

    class Stalled:
        def __init__(self, inner):
            self.inner = inner

        def __getattr__(self, name):
            return getattr(self.inner, name)

        def inpaint(self, *args, **kwargs):  # inside p0's temporary folder
            time.sleep(_TIMEOUT_S)
            return self.inner.inpaint(*args, **kwargs)

    class Stalling(ray_engine._Actor):
        def make(self, job, out_dir):
            node = ray.get_runtime_context().get_node_id()
            with open(log / job.name, "a") as f:
                f.write(node + "\n")
            first = len((log / job.name).read_text().split()) == 1
            if job.name == "p0" and first:
                self.maker.inpainter = Stalled(self.maker.inpainter)
            return super().make(job, out_dir)

    monkeypatch.setattr(ray_engine, "_Actor", Stalling)
    argv = [str(src), "-o", str(out), "--depth", str(depth), "--engine", "ray",
            "--ray-address", two_nodes.address, *FAST, "-q"]
    status: list[int] = []
    batch = threading.Thread(target=lambda: status.append(main(["batch", *argv])),
                             daemon=True)
    batch.start()
    deadline = time.monotonic() + _TIMEOUT_S
    while not (any(out.glob(".p0.*")) and (log / "p0").is_file()):  # p0 half-made
        assert batch.is_alive() and time.monotonic() < deadline, "p0 was never started"
        time.sleep(0.1)
    killed = (log / "p0").read_text().split()[0]
    node = next(n for n in two_nodes.worker_nodes if n.node_id == killed)
    two_nodes.remove_node(node, allow_graceful=False)  # its raylet and workers killed
    batch.join(max(0.0, deadline - time.monotonic()))
    assert status == [0], "the batch did not end" if not status else status
    records = _records(out)
    assert [(r["name"], r["status"]) for r in records] == [("p0", "ok"), ("p1", "ok"),
                                                           ("p2", "ok")]
    tries = (log / "p0").read_text().split()
    assert len(tries) == 2 and tries[0] == killed and tries[1] != killed
    assert all(is_complete(out / f"p{i}") for i in range(3))
    assert sorted(p.name for p in out.iterdir()) == ["batch.jsonl", "p0", "p1", "p2"]
