"""The kernels compiled ahead (photo3d.kernels): make gives them only the declared
argument types, the helper takes the list from its end, a warm cache shows no step."""

from __future__ import annotations

import json
import subprocess
import sys
from collections import Counter
from types import SimpleNamespace

import pytest

from photo3d import kernels as ahead
from photo3d.cli.progress import StageBar

# A tiny make (the UI warm-up's photo) after compile_kernels, in a fresh process (this
# one's kernels may have met other types in other tests): any kernel of the list with
# more overloads than it declares was called with a type it does not declare.
CHILD = """
import json, tempfile
from pathlib import Path
from numba.core.sigutils import normalize_signature
from photo3d.kernels import compile_kernels, kernels
from photo3d.ui.warmup import _tiny_make

compile_kernels(helper=False)
_tiny_make(Path(tempfile.mkdtemp()) / "out")
extra = {}
for kernel, sigs in kernels():
    declared = {tuple(normalize_signature(s)[0]) for s in sigs}
    seen = set(kernel.overloads)
    if seen - declared:
        extra[kernel.py_func.__qualname__] = [str(s) for s in seen - declared]
print(json.dumps(extra))
"""


def test_make_gives_the_kernels_only_their_declared_types():
    out = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True,
                         check=True)
    extra = json.loads(out.stdout.strip().splitlines()[-1])
    assert extra == {}, f"declare these in the kernel module's KERNELS: {extra}"


def test_every_kernel_module_declares_signatures_numba_reads():
    from numba.core.sigutils import normalize_signature

    todo = ahead.kernels()
    assert len(todo) >= 10
    for kernel, sigs in todo:
        assert hasattr(kernel, "py_func") and sigs
        for sig in sigs:
            assert len(normalize_signature(sig)[0]) == kernel.py_func.__code__.co_argcount


class FakeKernel:
    """Stands in for a numba dispatcher: ``cold`` ones miss the cache once."""

    def __init__(self, cold: bool) -> None:
        self.cold = cold
        self.calls = 0
        self.stats = SimpleNamespace(cache_misses=Counter())

    def compile(self, sig) -> None:
        self.calls += 1
        if self.cold:
            self.stats.cache_misses[sig] += 1
            self.cold = False


@pytest.mark.parametrize("cold", [False, True])
def test_the_step_is_reported_only_when_something_compiles(monkeypatch, cold):
    fakes = [FakeKernel(cold=cold and i == 2) for i in range(5)]
    monkeypatch.setattr(ahead, "kernels", lambda: [(k, ("(int64,)",)) for k in fakes])
    seen = []
    assert ahead.compile_kernels(seen.append, helper=False) == int(cold)
    assert [k.calls for k in fakes] == [1] * 5
    assert seen == ([0.6, 0.8, 1.0] if cold else [])


def test_the_helper_compiles_from_the_end_until_a_claimed_kernel(tmp_path, monkeypatch):
    fakes = [FakeKernel(cold=True) for _ in range(6)]
    monkeypatch.setattr(ahead, "kernels", lambda: [(k, ("(int64,)",)) for k in fakes])
    for i in range(3):  # this process has kernels 0..2
        (tmp_path / f"{i}.claim").touch()
    ahead.compile_from_end(tmp_path)
    assert [k.calls for k in fakes] == [0, 0, 0, 1, 1, 1]
    assert sorted(p.name for p in tmp_path.glob("*.done")) == ["3.done", "4.done", "5.done"]


def test_the_bar_counts_the_compile_step_only_when_it_runs():
    warm, cold = StageBar(quiet=True), StageBar(quiet=True)
    for bar in (warm, cold):  # a bar that draws nothing but keeps its numbers
        bar.bar = SimpleNamespace(n=0.0, total=100, update=lambda v, b=bar: setattr(
            b.bar, "n", b.bar.n + v), set_description_str=lambda *a, **k: None)
    warm("load", 1.0)
    cold("compile", 1.0)
    cold("load", 1.0)
    assert "compile" not in warm.weights and warm.bar.n == warm.weights["load"]
    assert cold.bar.n == cold.weights["compile"] + cold.weights["load"]
    assert cold.bar.total == warm.bar.total + cold.weights["compile"]


def test_a_kernel_compiled_on_first_use_shows_in_the_bar():
    import numba

    labels = []
    bar = StageBar(quiet=True)
    bar.bar = SimpleNamespace(n=0.0, total=100, update=lambda v: None,
                              set_description_str=lambda s, **k: labels.append(s))
    with ahead.watch_compiles(lambda busy: bar.note("compiling, once" if busy else None)):
        bar("video", 0.5)
        assert numba.njit(lambda x: x * 2)(3) == 6
    assert labels == ["video", "compiling, once", "video"]


@pytest.mark.parametrize(("idle", "spare"), [(2.0, True), (1.8, True), (1.2, False),
                                             (0.3, False)])
def test_the_helper_starts_only_with_a_core_idle_now(monkeypatch, idle, spare):
    # this process sleeps while the idle time is measured: its own core counts as idle
    monkeypatch.setattr(ahead.parallel, "cores", lambda: 2)
    monkeypatch.setattr(ahead.parallel, "idle_cores", lambda interval: idle)
    monkeypatch.setattr(ahead.os, "getloadavg", lambda: (9.0, 9.0, 9.0))  # not read
    assert ahead.spare_core() is spare


def test_without_proc_stat_the_load_average_decides(monkeypatch):
    monkeypatch.setattr(ahead.parallel, "cores", lambda: 2)
    monkeypatch.setattr(ahead.parallel, "idle_cores", lambda interval: None)
    monkeypatch.setattr(ahead.os, "getloadavg", lambda: (0.4, 1.0, 1.0))
    assert ahead.spare_core()
    monkeypatch.setattr(ahead.os, "getloadavg", lambda: (1.4, 1.0, 1.0))
    assert not ahead.spare_core()


def test_one_core_never_starts_the_helper(monkeypatch):
    # a cgroup quota of one CPU on a machine of many: parallel.cores() says 1
    monkeypatch.setattr(ahead.parallel, "cores", lambda: 1)
    monkeypatch.setattr(ahead.parallel, "idle_cores", lambda interval: 8.0)
    assert not ahead.spare_core()
