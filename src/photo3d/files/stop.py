"""The process-wide stop request a signal makes, which worker threads obey.

:mod:`photo3d.files.signals` turns SIGINT, SIGTERM and SIGHUP into exceptions in the
main thread and records the signal here (:func:`request_stop`); the threads of
:mod:`photo3d.parallel`'s pools call :func:`check` before each task, and long work
calls it between chunks, so they stop at their next check while the main thread
unwinds. :func:`deferred` keeps a short step whole (a file moved into place and
recorded). A module of its own, below both of them, so that neither imports the other.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator


class Interrupted(KeyboardInterrupt):
    """Raised inside :func:`~photo3d.files.signals.handle_signals` when a termination
    signal arrives.

    Attributes:
        signum: the signal number (``signal.SIGTERM``, ``signal.SIGHUP``, ...).
    """

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


_stop: int | None = None
"""The signal that asked this process to stop (:func:`stopping`), or None."""
_local = threading.local()  # .deferred: depth of deferred() blocks; .pending: a signal held


def stopping() -> int | None:
    """The signal that asked this process to stop, or None: set when
    :func:`~photo3d.files.signals.handle_signals` (or
    :func:`~photo3d.files.signals.worker_signals`) receives one, cleared when the
    outermost :func:`~photo3d.files.signals.handle_signals` block ends.

    Example:
        >>> stopping() is None
        True
    """
    return _stop


def check() -> None:
    """In a worker thread, raise the interruption (:class:`KeyboardInterrupt` for
    SIGINT, :class:`Interrupted` otherwise) once a signal asked the process to stop;
    call it between chunks of long work. Does nothing in the main thread (its signal
    handler raised already, and its cleanup must run) and inside :func:`deferred`.

    Example:
        >>> check()  # no signal: nothing happens
    """
    if _stop is None or getattr(_local, "deferred", 0):
        return
    if threading.current_thread() is threading.main_thread():
        return
    raise_for(_stop)


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """A step that a signal must not cut in two (a file moved into place, then
    recorded): inside the block :func:`check` does not raise, and in the main thread
    a signal is held and raised when the block ends. Keep it short: the process
    stops only after it.

    Example:
        >>> with deferred():
        ...     pass
    """
    _local.deferred = getattr(_local, "deferred", 0) + 1
    try:
        yield
    finally:
        _local.deferred -= 1
        pending = getattr(_local, "pending", None)
        if not _local.deferred and pending is not None:
            _local.pending = None
            if sys.exc_info()[1] is None:  # else that exception unwinds already
                raise_for(pending)


def request_stop(signum: int | None) -> None:
    """Record ``signum`` as the signal that asks the process to stop (None: clear it).

    Example:
        >>> request_stop(None); stopping() is None
        True
    """
    global _stop
    _stop = signum


def raise_for(signum: int) -> None:
    """Raise the exception a signal becomes: KeyboardInterrupt for SIGINT, as Python does,
    :class:`Interrupted` otherwise.

    Example:
        >>> try:
        ...     raise_for(signal.SIGTERM)
        ... except Interrupted as err:
        ...     err.signum == signal.SIGTERM
        True
    """
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Interrupted(signum)


def held(signum: int) -> bool:
    """In the main thread's signal handler: whether a :func:`deferred` step is running
    (then ``signum`` is kept and raised when it ends).

    Example:
        >>> held(signal.SIGTERM)
        False
    """
    if not getattr(_local, "deferred", 0):
        return False
    _local.pending = signum
    return True
