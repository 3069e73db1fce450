"""Signals as exceptions, also when they land inside C callbacks (photo3d.files.signals),
and never inside numba's compiler, where an exception leaves LLVM's objects half-owned
and the process crashes with a segmentation fault when they are freed (CI saw ``make``
end with -11 on a Ctrl-C during a cold compile)."""

from __future__ import annotations

import ctypes
import ctypes.util
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
from photo3d.files.signals import compiling, handle_signals
from photo3d.files.stop import Interrupted

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
SRC = str(Path(photo3d.__file__).parents[1])


def _sort_with_callback(on_first_call) -> None:
    """libc's qsort with a Python comparator: Python code running as a C callback,
    as numba's compiler runs it through LLVM."""
    libc = ctypes.CDLL(ctypes.util.find_library("c"))
    compare_t = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.POINTER(ctypes.c_int),
                                 ctypes.POINTER(ctypes.c_int))
    calls = []

    def compare(a, b):
        calls.append(1)
        if len(calls) == 1:
            on_first_call()
        for _ in range(1000):  # bytecode after the signal: its handler runs here
            pass
        return a[0] - b[0]

    values = (ctypes.c_int * 64)(*range(64, 0, -1))
    libc.qsort(values, len(values), ctypes.sizeof(ctypes.c_int), compare_t(compare))


def test_an_interrupt_inside_a_c_callback_is_raised_after_it_without_a_traceback(capfd):
    with pytest.raises(Interrupted) as caught, handle_signals() as guard:
        _sort_with_callback(lambda: os.kill(os.getpid(), signal.SIGTERM))
        deadline = time.monotonic() + 5  # the signal is sent again from a helper thread
        while time.monotonic() < deadline:
            time.sleep(0.01)
    assert caught.value.signum == signal.SIGTERM and guard.signum == signal.SIGTERM
    err = capfd.readouterr().err
    assert "Traceback" not in err and "Exception ignored" not in err, err


def test_other_unraisable_exceptions_still_reach_the_previous_hook():
    seen = []
    previous, sys.unraisablehook = sys.unraisablehook, seen.append
    try:
        with handle_signals():
            def fail():
                raise ValueError("in a callback")

            _sort_with_callback(fail)
        assert sys.unraisablehook == seen.append  # restored on leaving
    finally:
        sys.unraisablehook = previous
    assert [type(u.exc_value) for u in seen] == [ValueError]


def swallow_an_interrupt() -> list[int]:
    """A KeyboardInterrupt through the redelivery hook (re-arming gives SIGTERM);
    returns one entry per re-arm."""
    from types import SimpleNamespace

    from photo3d.files.signals import redeliver_swallowed

    rearmed = []
    restore = redeliver_swallowed((KeyboardInterrupt,),
                                  lambda: rearmed.append(1) or signal.SIGTERM)
    try:
        sys.unraisablehook(SimpleNamespace(exc_value=KeyboardInterrupt(), exc_type=None,
                                           exc_traceback=None, err_msg=None, object=None))
    finally:
        restore()
    return rearmed


def test_an_interrupt_at_shutdown_when_no_thread_can_start_is_dropped_quietly(
        monkeypatch, capfd):
    import threading

    def refuse(self):
        raise RuntimeError("can't create new thread at interpreter shutdown")

    monkeypatch.setattr(threading.Timer, "start", refuse)
    assert swallow_an_interrupt() == [1]
    assert capfd.readouterr().err == ""


def test_an_interrupt_while_the_redelivery_thread_starts_is_sent_again(monkeypatch, capfd):
    """The handler, re-armed, can raise inside the hook while ``Timer.start`` waits for
    its thread: that must not print a traceback, and the signal is armed again."""
    import threading

    started = []
    real_start = threading.Timer.start

    def interrupted_once(self):
        if not started:
            started.append("interrupted")
            raise KeyboardInterrupt
        started.append(self.args[1])
        self.cancel()  # the test process must not receive the signal
        real_start(self)

    monkeypatch.setattr(threading.Timer, "start", interrupted_once)
    assert swallow_an_interrupt() == [1, 1] and started == ["interrupted", signal.SIGTERM]
    assert capfd.readouterr().err == ""


_WORKER = """
import os, signal, sys, time
from photo3d.files.signals import worker_signals
from photo3d.files.stop import Interrupted

busy = sys.argv[1] == "busy"
guard = worker_signals(busy=lambda: busy)
os.kill(os.getpid(), signal.SIGINT)  # ignored: the parent stops its workers itself
try:
    print("ready", flush=True)
    time.sleep(30)
except Interrupted as err:
    os.kill(os.getpid(), signal.SIGTERM)  # a second one must not interrupt the cleanup
    time.sleep(0.2)
    print("cleaned up after", err, guard.signum == signal.SIGTERM, flush=True)
    sys.exit(5)
"""


@pytest.mark.parametrize(("state", "status", "said"), [
    ("busy", 5, "ready\ncleaned up after SIGTERM True\n"),
    ("idle", 0, "ready\n"),  # idle: ends at once, nothing to clean up
])
def test_a_pool_worker_cleans_up_when_busy_and_exits_at_once_when_idle(state, status, said):
    import subprocess

    argv = [sys.executable, "-c", _WORKER, state]
    with subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          text=True) as proc:
        try:
            first = proc.stdout.readline()
            proc.send_signal(signal.SIGTERM)
            out, err = proc.communicate(timeout=20)
        finally:
            if proc.poll() is None:
                proc.kill()
    assert (proc.returncode, first + out) == (status, said), err
    assert "Traceback" not in err


def test_sigint_is_ignored_only_inside_the_block():
    from photo3d.files.signals import sigint_ignored

    before = signal.getsignal(signal.SIGINT)
    with sigint_ignored():
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)
    assert signal.getsignal(signal.SIGINT) == before


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
