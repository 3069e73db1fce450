"""files/signals.py: a signal becomes an exception in the main thread, but never inside
numba's compiler, where an exception leaves LLVM's objects half-owned and the process
crashes with a segmentation fault when they are freed (CI saw ``make`` end with -11
on a Ctrl-C during a cold compile)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
import types
from pathlib import Path

import pytest

import photo3d
from photo3d.files.signals import Interrupted, compiling, handle_signals

SRC = str(Path(photo3d.__file__).parents[1])


def in_module(name: str, fn):
    """``fn`` as if it were defined in module ``name`` (its frames say so)."""
    return types.FunctionType(fn.__code__, {**fn.__globals__, "__name__": name}, fn.__name__,
                              fn.__defaults__, fn.__closure__)


def send_and_wait(seconds: float, done: list) -> str:
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(seconds)  # the handler runs here, between two bytecodes
    done.append("compiled")
    return "returned"


def test_a_signal_inside_the_compiler_is_raised_after_it():
    compiler_step = in_module("numba.core.fake_compiler", send_and_wait)
    done, after = [], []
    with handle_signals() as guard:
        with pytest.raises(Interrupted):
            result = compiler_step(0.02, done)  # not cut
            after.append(result)  # raised before this line
    assert done == ["compiled"] and after == []
    assert guard.signum == signal.SIGTERM
    assert sys.gettrace() is None


def test_a_signal_elsewhere_is_raised_at_once():
    elsewhere = in_module("photo3d.fake", send_and_wait)
    with handle_signals(), pytest.raises(Interrupted):
        elsewhere(0.5, [])
        pytest.fail("not raised inside")


def test_compiling_sees_callers_frames():
    seen = []
    inner = in_module("photo3d.inner", lambda: seen.append(compiling(sys._getframe())))
    in_module("llvmlite.binding.fake", lambda: inner())()
    inner()
    assert seen == [True, False]


def test_ctrl_c_during_real_compiles_never_crashes():
    """Real numba compiles interrupted at random moments: the interruption is raised
    in the caller once the compile has returned, never inside numba or llvmlite (there
    one interrupt in a few hundred crashed the process later, on freeing LLVM's
    objects), and never dropped."""
    code = textwrap.dedent("""
        import os, random, signal, sys, threading, gc, traceback
        import numba, numpy as np
        from photo3d.files.signals import handle_signals
        body = ("def f{i}(a):\\n"
                "    s = 0.0\\n"
                "    for k in range(a.shape[0]):\\n"
                "        s += a[k] * {i} - np.sin(a[k] + {i}) + np.cos(a[k] * {i})\\n"
                "    return s\\n")
        random.seed(int(sys.argv[1]))
        with handle_signals():
            try:
                for i in range(40):
                    ns = {"np": np}
                    exec(body.format(i=i), ns)
                    if i == 1:
                        threading.Timer(random.uniform(0, 0.4), os.kill,
                                        (os.getpid(), signal.SIGINT)).start()
                    numba.njit(ns[f"f{i}"])(np.ones(4))
                print("never interrupted")
            except KeyboardInterrupt as err:
                gc.collect()
                inside = [f.filename for f in traceback.extract_tb(err.__traceback__)
                          if "numba" in f.filename or "llvmlite" in f.filename]
                print("interrupted at", i, "inside", inside)
    """)
    env = {**os.environ, "PYTHONPATH": SRC, "NUMBA_CACHE_DIR": "/nonexistent-cache",
           "PYTHONFAULTHANDLER": "1"}
    for seed in range(4):
        done = subprocess.run([sys.executable, "-c", code, str(seed)], capture_output=True,
                              text=True, env=env, timeout=300)
        assert done.returncode == 0, done.stderr[-3000:]
        assert done.stdout.startswith("interrupted at"), done.stdout + done.stderr[-3000:]
        assert done.stdout.endswith("inside []\n"), done.stdout  # not in the compiler
        assert "Exception ignored" not in done.stderr, done.stderr[-3000:]
