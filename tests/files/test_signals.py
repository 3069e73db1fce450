"""Signals as exceptions, also when they land inside C callbacks (photo3d.files.signals)."""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal
import sys
import time

import pytest

from photo3d.files.signals import handle_signals
from photo3d.files.stop import Interrupted

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")


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
