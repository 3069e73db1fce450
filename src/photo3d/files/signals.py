"""SIGINT, SIGTERM and SIGHUP as exceptions, so that cleanup code always runs.

The one place photo3d sets signal handlers. :func:`handle_signals` is used by the
command line around every command, so a temporary output folder
(:mod:`photo3d.files.staging`) or file (:mod:`photo3d.files.atomic`) is removed on
Ctrl-C and on termination alike. The batch's pool workers use
:func:`worker_signals` for their whole life, and the batch starts them inside
:func:`sigint_ignored`. In all three a signal becomes the same exceptions
(:class:`KeyboardInterrupt` for SIGINT, :class:`Interrupted` otherwise), but never
inside numba's compiler: one that lands there is raised once the compiler has
returned (:func:`after_compiler`), one that lands inside another C callback is raised
again once the C code returns (:func:`redeliver_swallowed`), and a signal repeated
while the first one unwinds does not interrupt the cleanup.

A signal also asks the whole process to stop (:func:`stopping`): the threads of
:mod:`photo3d.parallel`'s pools call :func:`check` before each task, and long work
calls it between chunks, so worker threads stop at their next check while the main
thread unwinds; a file is never moved into place by a worker thread after a signal
(:class:`photo3d.files.atomic.PendingFile` checks). :func:`deferred` keeps a short
step whole (a file moved into place and recorded): a signal that lands inside it
is raised when it ends.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
from collections.abc import Callable, Iterator

from photo3d.files.stop import Interrupted, held, raise_for, request_stop, stopping
from photo3d.parallel import later


def redeliver_swallowed(kinds: tuple[type[BaseException], ...],
                        rearm: Callable[[], int | None]) -> Callable[[], None]:
    """Keep an interrupt that lands inside a C callback from getting lost.

    A signal handler's exception raised while Python code runs as a callback of C
    code (numba compiling through LLVM, ctypes) cannot propagate: Python prints
    "Exception ignored in ..." with a traceback and carries on. This installs a
    ``sys.unraisablehook`` that, for exceptions of ``kinds``, prints nothing, calls
    ``rearm()`` (which restores the handler and returns the signal to send, or None)
    and sends that signal to this process again 50 ms later from a helper thread, so
    that the handler runs once the C code has returned (if it lands in a callback
    again, the same happens again; during interpreter shutdown, when no thread can
    start, the process is exiting anyway and nothing is sent; a signal that arrives
    while the helper thread starts is re-armed and sent again). Other unraisable
    exceptions go to the previous hook. Returns a function that restores the previous hook.

    Example:
        >>> restore = redeliver_swallowed((KeyboardInterrupt,), lambda: None)
        >>> restore()
    """
    previous = sys.unraisablehook

    def hook(unraisable) -> None:
        if not isinstance(unraisable.exc_value, kinds):
            previous(unraisable)
            return
        for _ in range(_REDELIVER_TRIES):
            signum = rearm()
            if signum is None:
                return
            # later, so that it does not land in this hook again
            try:
                later(_REDELIVER_S, os.kill, os.getpid(), signum)
                return
            except RuntimeError:  # "can't create new thread at interpreter shutdown":
                return  # the process is exiting already, there is nothing left to stop
            except kinds:  # a signal landed while the helper thread started (its
                continue  # handler raised here, where nothing can catch it): again

    sys.unraisablehook = hook

    def restore() -> None:
        sys.unraisablehook = previous

    return restore


_REDELIVER_S = 0.05
_REDELIVER_TRIES = 3
_COMPILER = ("numba.", "llvmlite.")
"""The modules an exception must not cut through: numba's compiler and its cache
loader drive LLVM through llvmlite, and an exception between two of their calls
leaves LLVM objects half-owned, which crashes the process (a segmentation fault)
when they are freed."""


def compiling(frame) -> bool:
    """Whether ``frame`` (a signal handler's) or a frame that called it runs in
    numba's compiler or llvmlite (:data:`_COMPILER`): then a signal handler must not
    raise there, and raises once the compiler has returned (:func:`after_compiler`).

    Example:
        >>> import sys
        >>> compiling(sys._getframe())
        False
    """
    while frame is not None:
        if frame.f_globals.get("__name__", "").startswith(_COMPILER):
            return True
        frame = frame.f_back
    return False


_waiting = False  # an after_compiler() action is armed


def after_compiler(frame, action: Callable[[], None]) -> None:
    """Call ``action()`` (a signal handler's raise) in the frame that called numba's
    compiler, at its first step after the compiler has returned to it (``frame``: the
    signal handler's, which :func:`compiling` found inside the compiler).

    A trace function on that one frame does it, as a debugger stops at a line: the
    thread's global trace function (another one, a debugger's or coverage's, is kept
    and called on) traces no other frame, and both are removed at that step. Once
    armed, further calls do nothing until it has run.

    Example:
        >>> import sys
        >>> after_compiler(sys._getframe(), lambda: None)  # no compiler frame: nothing
    """
    global _waiting
    target = None
    while frame is not None:  # the caller of the outermost compiler frame
        if frame.f_globals.get("__name__", "").startswith(_COMPILER):
            target = frame.f_back
        frame = frame.f_back
    if target is None or _waiting:
        return
    previous = sys.gettrace()

    def step(frame, event, arg):
        global _waiting
        _waiting = False
        sys.settrace(previous)
        frame.f_trace = None
        action()

    def calls(frame, event, arg):
        return previous(frame, event, arg) if previous is not None else None

    _waiting = True
    target.f_trace = step
    sys.settrace(calls)


class SignalGuard:
    """What :func:`handle_signals` (or :func:`worker_signals`) saw: ``signum`` is the
    first signal received, or None."""

    signum: int | None = None


def _install(handler: Callable, signums: list[int]) -> dict[int, object]:
    """Set ``handler`` for ``signums``, except those ignored when the process started
    (``nohup``, background jobs); returns the previous handlers (none outside the
    main thread, where handlers cannot be set)."""
    previous: dict[int, object] = {}
    try:
        for signum in signums:
            if signal.getsignal(signum) != signal.SIG_IGN:
                previous[signum] = signal.signal(signum, handler)
    except ValueError:  # not the main thread: leave the handlers alone
        pass
    return previous


@contextlib.contextmanager
def handle_signals(*, after: Callable | None = None) -> Iterator[SignalGuard]:
    """Turn SIGINT, SIGTERM and SIGHUP into exceptions, so cleanup code runs.

    SIGINT raises :class:`KeyboardInterrupt` (as Python does), SIGTERM and SIGHUP
    raise :class:`Interrupted`; either unwinds through ``with stage_output(...)`` or
    ``with atomic_path(...)``, which remove their temporary folder or file. The
    guard remembers the signal, because an interrupt that lands inside compiled
    code (numba) can surface as another exception (``SystemError``): callers should
    treat any exception raised after ``guard.signum`` was set as the interruption.
    A signal that lands while numba compiles is not raised there (LLVM's objects
    would be left half-owned, and the process would crash later): it is raised in
    the compiler's caller once the compiler returns (:func:`after_compiler`); one
    raised inside another C callback, which Python would print and drop, is raised
    again once the C code returns (:func:`redeliver_swallowed`).
    Signals ignored when the process started stay ignored (``nohup``, background
    jobs). Does nothing outside the main thread.

    When the block ends, the signals get ``after`` (a handler; None: the handlers
    they had before the block) with no moment in between; one that lands while the
    block ends is not raised there but sent again, to those handlers, once they are set
    (the command line's ``after`` turns a late Ctrl-C into its one line and exit 130).

    Example:
        >>> import os, signal
        >>> with handle_signals() as guard:
        ...     try:
        ...         os.kill(os.getpid(), signal.SIGTERM)
        ...     except Interrupted as err:
        ...         print(err.signum == signal.SIGTERM, guard.signum == signal.SIGTERM)
        True True
    """
    guard = SignalGuard()

    previous: dict = {}
    ending = False  # the block is ending: a signal is for the handlers after it
    late: list[int] = []

    def handler(signum, frame):
        if ending:
            late.append(signum)
            return
        if guard.signum is not None:  # already unwinding: let the cleanup finish, and
            for number, old in previous.items():  # a further signal act as usual
                signal.signal(number, old)
            return
        request_stop(signum)  # worker threads stop at their next check()
        if compiling(frame):  # not here (a crash later): once numba's compiler returns
            after_compiler(frame, lambda: handler(signum, None))
            return
        guard.signum = signum
        if held(signum):  # inside deferred(): raised when that step ends
            return
        raise_for(signum)

    wanted = [signal.SIGINT, signal.SIGTERM] + ([signal.SIGHUP] if hasattr(signal, "SIGHUP")
                                                else [])
    previous.update(_install(handler, wanted))

    def rearm() -> int | None:  # the exception was swallowed: raise it again later
        signum, guard.signum = guard.signum, None
        return signum

    restore = redeliver_swallowed((KeyboardInterrupt,), rearm) if previous else None
    outer = stopping() is None
    try:
        yield guard
    finally:
        ending = True
        for signum, old in previous.items():
            signal.signal(signum, old if after is None else after)
        if restore is not None:
            restore()
        if outer:
            request_stop(None)
        for signum in late:  # to the handlers set now
            signal.raise_signal(signum)


def worker_signals(busy: Callable[[], bool]) -> SignalGuard:
    """Set up a pool worker process for the rest of its life (call it first in the
    pool's initializer).

    SIGINT is ignored: a Ctrl-C reaches the whole process group, and the parent,
    which gets it too, stops its workers itself with SIGTERM. SIGTERM raises
    :class:`Interrupted` while ``busy()`` is true, so the photo's temporary output
    is removed as the exception unwinds; when the worker is idle it ends the
    process at once (``os._exit(0)``: nothing of it is half-done). Further SIGTERMs
    are ignored, so they cannot interrupt that cleanup (the pool also terminates
    its workers when one of them exits); one that lands inside a C callback is
    raised again once the C code returns (:func:`redeliver_swallowed`). Returns the
    guard that records the signal.

    Example:
        >>> import subprocess, sys
        >>> code = ("import os, signal\\n"
        ...         "from photo3d.files.signals import Interrupted, worker_signals\\n"
        ...         "worker_signals(busy=lambda: True)\\n"
        ...         "try:\\n"
        ...         "    os.kill(os.getpid(), signal.SIGTERM)\\n"
        ...         "except Interrupted as err:\\n"
        ...         "    print(err)")
        >>> subprocess.run([sys.executable, "-c", code], capture_output=True,
        ...                text=True).stdout
        'SIGTERM\\n'
    """
    guard = SignalGuard()

    def handler(signum, frame):
        guard.signum = signum
        request_stop(signum)  # the worker's own threads stop at their next check()
        if not busy():
            os._exit(0)
        if compiling(frame):  # not here (a crash later): once numba's compiler returns
            after_compiler(frame, lambda: handler(signum, None))
            return
        signal.signal(signal.SIGTERM, signal.SIG_IGN)  # once is enough (see above)
        raise_for(signum)

    def rearm() -> int:  # the exception was swallowed: arm again, have it sent again
        signal.signal(signal.SIGTERM, handler)
        return signal.SIGTERM

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, handler)
    redeliver_swallowed((Interrupted,), rearm)
    return guard


@contextlib.contextmanager
def sigint_ignored() -> Iterator[None]:
    """Ignore SIGINT inside the block (outside the main thread: do nothing).

    For starting worker processes: they inherit it, so a Ctrl-C at the terminal,
    which reaches the whole process group, cannot interrupt them while they import,
    before their initializer runs (:func:`worker_signals`). The parent stops them
    itself.

    Example:
        >>> import signal
        >>> with sigint_ignored():
        ...     signal.getsignal(signal.SIGINT) == signal.SIG_IGN
        True
    """
    try:
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread: nothing to protect
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
