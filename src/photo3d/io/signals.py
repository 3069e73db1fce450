"""SIGINT, SIGTERM and SIGHUP as exceptions, so that cleanup code always runs.

Used by the command line around every command: a temporary output folder
(:mod:`photo3d.io.safeout`) is removed on Ctrl-C and on termination alike.
"""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterator


class Interrupted(KeyboardInterrupt):
    """Raised inside :func:`handle_signals` when a termination signal arrives.

    Attributes:
        signum: the signal number (``signal.SIGTERM``, ``signal.SIGHUP``, ...).
    """

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


class SignalGuard:
    """What :func:`handle_signals` saw: ``signum`` is the first signal received, or None."""

    signum: int | None = None


@contextlib.contextmanager
def handle_signals() -> Iterator[SignalGuard]:
    """Turn SIGINT, SIGTERM and SIGHUP into exceptions, so cleanup code runs.

    SIGINT raises :class:`KeyboardInterrupt` (as Python does), SIGTERM and SIGHUP
    raise :class:`Interrupted`; either unwinds through ``with stage_output(...)``,
    which removes its temporary folder. The guard remembers the signal, because an
    interrupt that lands inside compiled code (numba) can surface as another
    exception (``SystemError``): callers should treat any exception raised after
    ``guard.signum`` was set as the interruption. Signals ignored when the process
started stay ignored (``nohup``, background jobs). Does nothing outside the main
thread.

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

    def handler(signum, frame):
        if guard.signum is not None:  # already unwinding: let the cleanup finish, and
            for number, old in previous.items():  # a further signal act as usual
                signal.signal(number, old)
            return
        guard.signum = signum
        if signum == signal.SIGINT:
            raise KeyboardInterrupt
        raise Interrupted(signum)

    wanted = [signal.SIGINT, signal.SIGTERM] + ([signal.SIGHUP] if hasattr(signal, "SIGHUP")
                                                else [])
    try:
        for signum in wanted:
            if signal.getsignal(signum) != signal.SIG_IGN:  # nohup, background jobs
                previous[signum] = signal.signal(signum, handler)
    except ValueError:  # not the main thread: leave the handlers alone
        pass
    try:
        yield guard
    finally:
        for signum, old in previous.items():
            signal.signal(signum, old)
