"""Concurrency has one home (photo3d.parallel): no other module starts a thread or a
pool, counts cores or sets numba's threads; the budget follows affinity, the cgroup
quota and the user's setting; every pool's threads follow the budget."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from photo3d import parallel
from photo3d.errors import ConfigError

SRC = Path(__file__).resolve().parents[1] / "src" / "photo3d"

# what only photo3d.parallel may call or import
FORBIDDEN_CALLS = {("os", "cpu_count"), ("os", "sched_getaffinity"), ("threading", "Thread"),
                   ("threading", "Timer"),
                   ("numba", "set_num_threads"), ("torch", "set_num_threads"),
                   ("subprocess", "Popen"), ("multiprocessing", "get_context"),
                   ("multiprocessing", "Pool"), ("multiprocessing", "Process"),
                   ("multiprocessing", "active_children")}
FORBIDDEN_NAMES = {"ThreadPoolExecutor", "ProcessPoolExecutor", "Thread", "Timer", "Pool",
                   "Process",
                   "cpu_count", "set_num_threads", "sched_getaffinity", "Popen"}
FORBIDDEN_MODULES = {"multiprocessing"}
# the named exceptions: none needed today (the web servers' threads are Gradio's and
# http.server's own, Ray's are Ray's); a module listed here must say why
ALLOWED: dict[str, str] = {}


def annotations(tree: ast.AST) -> set[int]:
    """The ids of every node inside a type annotation (they start nothing)."""
    roots = []
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            roots += [node.returns] + [a.annotation for a in (
                *node.args.args, *node.args.kwonlyargs, *node.args.posonlyargs,
                node.args.vararg, node.args.kwarg) if a is not None]
        elif isinstance(node, ast.AnnAssign):
            roots.append(node.annotation)
    return {id(n) for root in roots if root is not None for n in ast.walk(root)}


def violations(file: Path) -> list[str]:
    """What ``file`` does that only photo3d.parallel may: calls, names, imports."""
    found = []
    tree = ast.parse(file.read_text())
    skip = annotations(tree)
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
            if (node.value.id, node.attr) in FORBIDDEN_CALLS:
                found.append(f"{node.value.id}.{node.attr} (line {node.lineno})")
        elif isinstance(node, ast.Import):
            found += [f"import {a.name} (line {node.lineno})" for a in node.names
                      if a.name in FORBIDDEN_MODULES]
        elif isinstance(node, ast.ImportFrom) and node.module:
            if node.module in FORBIDDEN_MODULES:
                found.append(f"from {node.module} (line {node.lineno})")
            elif node.module.split(".")[0] in ("concurrent", "threading", "os", "subprocess",
                                               "numba"):
                found += [f"from {node.module} import {a.name} (line {node.lineno})"
                          for a in node.names if a.name in FORBIDDEN_NAMES]
    return found


def test_only_the_home_of_concurrency_starts_threads_pools_or_counts_cores():
    bad = {}
    for file in SRC.rglob("*.py"):
        name = file.relative_to(SRC).as_posix()
        if name == "parallel.py" or name in ALLOWED:
            continue
        if found := violations(file):
            bad[name] = found
    assert bad == {}


def test_the_scan_finds_what_it_looks_for(tmp_path):
    # the test above can fail: each form it forbids is seen
    code = textwrap.dedent("""
        import os, threading, multiprocessing
        from concurrent.futures import ThreadPoolExecutor
        from concurrent.futures.process import ProcessPoolExecutor, BrokenProcessPool
        import numba
        os.cpu_count(); threading.Thread(target=print).start(); numba.set_num_threads(1)
        def f(t: threading.Thread) -> os.cpu_count: ...  # annotations start nothing
    """)
    (tmp_path / "m.py").write_text(code)
    found = violations(tmp_path / "m.py")
    assert len(found) == 6, found


def fake_cgroups(root: Path, *, v2: str | None = None, v1: tuple[str, str] | None = None,
                 parent_v1: tuple[str, str] | None = None) -> Path:
    """A folder that mimics /proc/self and /sys/fs/cgroup: a process in cgroup
    ``/job/step`` with cgroup v2's ``cpu.max`` = ``v2`` or v1's quota and period."""
    (root / "proc/self").mkdir(parents=True)
    if v2 is not None:
        (root / "proc/self/cgroup").write_text("0::/job/step\n")
        (root / "proc/self/mountinfo").write_text(
            "30 23 0:26 / /sys/fs/cgroup rw,nosuid - cgroup2 cgroup2 rw\n")
        step = root / "sys/fs/cgroup/job/step"
        step.mkdir(parents=True)
        (step / "cpu.max").write_text(v2 + "\n")
        (step.parent / "cpu.max").write_text("max 100000\n")
    else:
        (root / "proc/self/cgroup").write_text("4:memory:/job/step\n2:cpu,cpuacct:/job/step\n")
        (root / "proc/self/mountinfo").write_text(
            "32 31 0:29 / /sys/fs/cgroup/cpu,cpuacct rw - cgroup cgroup rw,cpu,cpuacct\n"
            "35 31 0:32 / /sys/fs/cgroup/memory rw - cgroup cgroup rw,memory\n")
        step = root / "sys/fs/cgroup/cpu,cpuacct/job/step"
        step.mkdir(parents=True)
        quota, period = v1 or ("-1", "100000")
        (step / "cpu.cfs_quota_us").write_text(quota + "\n")
        (step / "cpu.cfs_period_us").write_text(period + "\n")
        quota, period = parent_v1 or ("-1", "100000")
        (step.parent / "cpu.cfs_quota_us").write_text(quota + "\n")
        (step.parent / "cpu.cfs_period_us").write_text(period + "\n")
    return root


@pytest.mark.parametrize(("kind", "setting", "cpus"), [
    ("v2", "200000 100000", 2.0), ("v2", "150000 100000", 1.5), ("v2", "max 100000", None),
    ("v1", ("100000", "100000"), 1.0), ("v1", ("-1", "100000"), None),
    ("v1", ("50000", "100000"), 0.5)])
def test_the_cgroup_quota_is_read(tmp_path, kind, setting, cpus):
    root = fake_cgroups(tmp_path, **{kind: setting})
    assert parallel.quota(root) == cpus


def test_the_smallest_quota_on_the_way_up_counts(tmp_path):
    root = fake_cgroups(tmp_path, v1=("400000", "100000"), parent_v1=("100000", "100000"))
    assert parallel.quota(root) == 1.0
    assert parallel.quota(tmp_path / "nothing") is None


def test_cores_are_the_affinity_capped_by_the_quota_rounded_up(monkeypatch):
    monkeypatch.setattr(parallel, "affinity", lambda: set(range(64)))
    for quota, cores in ((None, 64), (2.0, 2), (1.5, 2), (0.5, 1), (100.0, 64)):
        monkeypatch.setattr(parallel, "quota", lambda quota=quota: quota)
        parallel.cores.cache_clear()
        assert parallel.cores() == cores
    parallel.cores.cache_clear()


def test_the_budget_comes_from_the_setting_else_the_environment_else_the_cores(monkeypatch):
    monkeypatch.setattr(parallel, "_budget", None)
    monkeypatch.setattr(parallel, "cores", lambda: 3)
    monkeypatch.delenv(parallel.ENV, raising=False)
    assert parallel.process_threads() == 3
    monkeypatch.setenv(parallel.ENV, "16")
    assert parallel.process_threads() == parallel.threads() == 16
    monkeypatch.setenv(parallel.ENV, "lots")
    with pytest.raises(ConfigError, match="PHOTO3D_THREADS must be a whole number"):
        parallel.process_threads()
    with pytest.raises(ConfigError, match="--threads must be a whole number"):
        parallel.set_threads(0)


def test_a_share_holds_for_its_thread_only_and_is_given_back():
    outer = parallel.threads()
    with parallel.share(1):
        assert parallel.threads() == 1
        seen = []
        parallel.start_thread(lambda: seen.append(parallel.threads()), name="t").join()
        assert seen == [parallel.process_threads()]  # another thread: the process's
    assert parallel.threads() == outer


def test_a_budget_of_one_runs_every_task_in_the_calling_thread():
    import threading

    me = threading.get_ident()
    with parallel.share(1):
        with parallel.thread_pool(8) as pool:
            assert pool.submit(threading.get_ident).result() == me
        with parallel.overlap() as side:
            assert side.submit(threading.get_ident).result() == me
        failed = parallel.thread_pool().submit(int, "x")
        assert isinstance(failed.exception(), ValueError)  # raised by result(), as a pool
        assert list(parallel.ahead(iter("ab"))) == ["a", "b"]


def test_workers_split_the_budget_and_numba_follows():
    import numba

    with parallel.share(16):
        with parallel.thread_pool(4, name="split") as pool:
            shares = list(pool.map(lambda _: (parallel.threads(), numba.get_num_threads()),
                                   range(8)))
    assert {s for s, _ in shares} == {4}
    assert {n for _, n in shares} == {min(4, numba.config.NUMBA_NUM_THREADS)}


def test_shared_steps_give_each_step_the_share_and_close_the_generator():
    closed = []

    def steps():
        try:
            yield parallel.threads()
            yield parallel.threads()
        finally:
            closed.append(True)

    wrapped = parallel.shared_steps(steps(), 1)
    assert next(wrapped) == 1
    wrapped.close()
    assert closed == [True]


def test_a_process_pool_gives_each_worker_its_share():
    with parallel.share(8), parallel.process_pool(2) as pool:
        assert pool.submit(parallel.threads).result() == 4


CHILD = textwrap.dedent("""
    import collections, json, sys, tempfile, threading
    import numpy as np
    import photo3d
    from photo3d import parallel
    from photo3d.render.animate import render_frames
    from photo3d.render.renderer import Renderer, RenderSettings
    from photo3d.camera import Camera
    from photo3d.render.renderer import output_intrinsics

    pools = collections.defaultdict(set)
    budgets = {}
    start = threading.Thread.start
    def recording(self):
        pools[self.name.rsplit("_", 1)[0]].add(self.name)
        return start(self)
    threading.Thread.start = recording
    enter = parallel._enter
    def noting(count):
        budgets[threading.current_thread().name.rsplit("_", 1)[0]] = count
        return enter(count)
    parallel._enter = noting

    rng = np.random.default_rng(0)
    image = rng.random((96, 128, 3)).astype(np.float32)
    depth = np.ones((96, 128), np.float32)
    for i in range(4):  # many small near squares: many patches in each batch
        for j in range(6):
            depth[10 + 22 * i:16 + 22 * i, 8 + 20 * j:14 + 20 * j] = 3.0
    photo = photo3d.make(image, depth=depth, config=photo3d.Config(size=None))
    photo.save(tempfile.mkdtemp() + "/out")
    with Renderer(photo.mesh(), RenderSettings(backend="numba")) as renderer:
        k = output_intrinsics(photo.ldi.intrinsics, 64, 48)
        frames = list(render_frames(renderer, [Camera(k, np.eye(4))] * 4))
    print(json.dumps({"cores": parallel.cores(), "threads": parallel.threads(),
                      "safe": parallel.thread_safe_kernels(),
                      "pools": {k: len(v) for k, v in pools.items()}, "budgets": budgets}))
""")


def child_pools(env: dict[str, str], prefix: list[str] | None = None) -> dict:
    """Run :data:`CHILD` (make, save, four frames) and return what it saw."""
    run = subprocess.run([*(prefix or []), sys.executable, "-c", CHILD], capture_output=True,
                         text=True, env={**os.environ, **env}, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    return json.loads(run.stdout.splitlines()[-1])


def test_every_pool_follows_a_budget_of_sixteen():
    seen = child_pools({parallel.ENV: "16"})
    pools = {k: v for k, v in seen["pools"].items() if k.startswith("photo3d-")}
    assert seen["threads"] == 16
    # the pools that split work: as many threads as parts, at most the budget
    assert 2 < pools["photo3d-median"] <= 16
    assert 2 < pools["photo3d-structured"] <= 16
    assert pools["photo3d-regions"] == 4  # at most 4 (each holds two lattice arrays)
    if seen["safe"]:  # numba's OpenMP or TBB layer: two frames at once, each on half
        assert pools["photo3d-frame"] == 2
        assert seen["budgets"]["photo3d-frame"] == 8
    assert seen["budgets"]["photo3d-median"] == 16 // pools["photo3d-median"]
    # the overlaps: one thread each, on one numba thread
    for name in ("photo3d-patches", "photo3d-encode", "photo3d-texture"):
        assert pools.get(name, 1) == 1
    assert all(n <= 16 for n in pools.values()), pools


def quota_group(tmp_name: str) -> Path | None:
    """A cgroup with a CPU quota of one CPU (v2 ``cpu.max`` or v1 ``cpu.cfs_quota_us``),
    None where none can be made (not root, no cgroup file system)."""
    v2 = Path("/sys/fs/cgroup/cgroup.controllers")
    try:
        if v2.exists() and "cpu" in v2.read_text().split():
            folder = Path("/sys/fs/cgroup") / tmp_name
            folder.mkdir()
            (folder / "cpu.max").write_text("100000 100000\n")
            return folder
        for base in (Path("/sys/fs/cgroup/cpu"), Path("/sys/fs/cgroup/cpu,cpuacct")):
            if (base / "cpu.cfs_quota_us").exists():
                folder = base / tmp_name
                folder.mkdir()
                (folder / "cpu.cfs_quota_us").write_text("100000\n")
                return folder
    except OSError:
        return None
    return None


@pytest.mark.parametrize("how", ["env", "taskset", "quota"])
def test_one_core_starts_no_pool_thread(how):
    # a budget of one (PHOTO3D_THREADS=1, a process bound to one core, a cgroup quota of
    # one CPU): every pool runs in the calling thread, so no pool has more threads than
    # the cores
    if how == "taskset":
        if not hasattr(os, "sched_getaffinity") or not Path("/usr/bin/taskset").exists():
            pytest.skip("no taskset")
        cpu = min(os.sched_getaffinity(0))
        seen = child_pools({}, prefix=["taskset", "-c", str(cpu)])
        assert seen["cores"] == 1
    elif how == "quota":
        group = quota_group(f"photo3d-test-{os.getpid()}")
        if group is None:
            pytest.skip("no cgroup with a CPU quota can be made here (not root?)")
        try:
            seen = child_pools({}, prefix=["/bin/sh", "-c",
                                           f'echo $$ > {group}/cgroup.procs && exec "$@"',
                                           "sh"])
        finally:
            group.rmdir()
        assert seen["cores"] == 1
    else:
        seen = child_pools({parallel.ENV: "1"})
    assert seen["threads"] == 1
    assert [k for k in seen["pools"] if k.startswith("photo3d-")] == []


def test_the_command_line_takes_threads_and_refuses_a_bad_budget(tmp_path, capsys,
                                                                monkeypatch):
    from photo3d.cli import build_parser, main

    for command in ("make", "batch", "render", "export", "demo", "ui", "train"):
        assert "--threads" in build_parser()._subparsers._group_actions[0].choices[
            command].format_help()
    assert main(["demo", "--threads", "0", "-o", str(tmp_path / "o")]) == 2
    assert "--threads must be a whole number from 1 to 1024, got 0" in capsys.readouterr().err
    monkeypatch.setenv(parallel.ENV, "two")
    assert main(["demo", "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.splitlines() == ["photo3d: error: PHOTO3D_THREADS must be a whole number "
                                "from 1 to 1024, got 'two'"]
    assert not (tmp_path / "o").exists()


def test_a_budget_beyond_any_machine_is_one_line_before_the_work(tmp_path, capsys,
                                                                 monkeypatch):
    """``--threads 99999999999999999999`` was a traceback from numpy (a work split of
    that many parts) after libgomp's own complaint; 10000 started 10006 threads for a
    64 px photo."""
    from photo3d.cli import main

    for value in ("99999999999999999999", "1025"):
        assert main(["demo", "--threads", value, "-o", str(tmp_path / "o")]) == 2
        assert capsys.readouterr().err.splitlines() == [
            f"photo3d: error: --threads must be a whole number from 1 to 1024, got {value}"]
        monkeypatch.setenv(parallel.ENV, value)
        assert main(["demo", "-o", str(tmp_path / "o")]) == 2
        assert capsys.readouterr().err.splitlines() == [
            f"photo3d: error: PHOTO3D_THREADS must be a whole number from 1 to 1024, "
            f"got '{value}'"]
        monkeypatch.delenv(parallel.ENV)
    assert not (tmp_path / "o").exists()
    with pytest.raises(ConfigError, match="from 1 to 1024"):
        parallel.set_threads(2000)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS")
def test_threads_that_cannot_start_are_one_line(tmp_path):
    """``ulimit -v 2500000`` and ``--threads 1024``: numba's pool fits, a thread pool's
    stacks do not; it was a traceback (``RuntimeError: can't start new thread``)."""
    import resource

    import numpy as np
    from PIL import Image

    Image.fromarray(np.full((48, 64, 3), 128, np.uint8)).save(tmp_path / "a.png")
    np.save(tmp_path / "a.npy", np.linspace(1, 2, 48 * 64, dtype=np.float32).reshape(48, 64))

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (2_500_000_000, 2_500_000_000))

    run = subprocess.run([sys.executable, "-m", "photo3d", "make", str(tmp_path / "a.png"),
                          "--depth", str(tmp_path / "a.npy"), "-o", str(tmp_path / "o"),
                          "--size", "64", "--no-video", "-q", "--threads", "1024"],
                         capture_output=True, text=True, preexec_fn=limit)
    err = [line for line in run.stderr.splitlines() if not line.startswith("depth: ")]
    assert run.returncode == 1 and err == [
        "photo3d: error: cannot start a thread (out of memory or threads): use a smaller "
        "--threads"], run.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.npy", "a.png"]


def test_threads_on_the_command_line_set_the_budget(monkeypatch, tmp_path):
    """``--threads`` is the command's budget while it runs, and only its: the next
    command in the same process (``main`` called from Python) has the process's."""
    from photo3d.cli import main, view

    before = parallel.process_threads()
    monkeypatch.setattr(parallel, "_budget", None)
    monkeypatch.setenv("OMP_NUM_THREADS", os.environ.get("OMP_NUM_THREADS", "1"))
    seen = []
    real = view.run

    def run(args):
        seen.append(parallel.process_threads())
        return real(args)

    monkeypatch.setattr(view, "run", run)
    try:  # the folder does not exist: view fails after the budget is set
        assert main(["view", str(tmp_path / "none"), "--threads", "3"]) == 2
        assert seen == [3]
        assert parallel.process_threads() == before
        monkeypatch.setenv(parallel.ENV, "two")  # read again: no budget left behind
        assert main(["view", str(tmp_path / "none")]) == 2
        assert seen == [3]
        with parallel.command_threads(2):  # --threads beside a bad variable: no error after
            assert parallel.process_threads() == 2
    finally:
        parallel.set_threads(before)  # numba's and torch's threads as they were
