"""Command line: ``photo3d make``, ``batch``, ``depth``, ``demo``, ``render``, ``export``,
``view``, ``ui``, ``eval``, ``train``.

Thin layer over the library: parses arguments, shows a progress bar and a timing
summary, and turns :class:`~photo3d.errors.Photo3DError` into a one-line message
with exit status 2.

One module per subcommand, each with ``add_parser(subparsers)`` (which registers
its ``run(args) -> int``); the option groups several commands share live in
:mod:`photo3d.cli.options`, the progress bars in :mod:`photo3d.cli.progress`.
Command modules import only those two (never each other, except ``demo``, which
is ``make`` on the bundled sample), so there is no import cycle.
"""

from __future__ import annotations

import argparse
import faulthandler
import gc
import os
import signal
import sys
import warnings
from pathlib import Path

from photo3d.cli import batch, demo, depth, evaluate, export, make, render, train, ui, view
from photo3d.errors import Photo3DError
from photo3d.files.gate import reading
from photo3d.files.signals import handle_signals
from photo3d.parallel import ENV, command_threads

COMMANDS = (make, batch, depth, demo, render, export, view, ui, evaluate, train)
"""Subcommand modules, in the order ``photo3d --help`` lists them."""


def build_parser() -> argparse.ArgumentParser:
    """The ``photo3d`` argument parser with every subcommand.

    >>> build_parser().parse_args(["view", "out"]).command
    'view'
    """
    parser = argparse.ArgumentParser(
        prog="photo3d",
        description="Turn a photo and its depth into a 3D photo (layered depth image, "
                    "inpainted occlusions, meshes).",
    )
    from photo3d import __version__

    parser.add_argument("--version", action="version", version=f"photo3d {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_parser(sub)
    for command in {id(p): p for p in sub.choices.values()}.values():
        if "--threads" not in command._option_string_actions:  # train words its own
            command.add_argument("--threads", type=int, metavar="N",
                                 help="threads photo3d may keep busy (default: the cores "
                                      f"this process may use, or ${ENV})")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``photo3d`` command; returns the exit status."""

    def show(message, category, filename, lineno, file=None, line=None):
        print(f"photo3d: warning: {message}", file=sys.stderr)

    if argv is None and not faulthandler.is_enabled():  # a crash in native code (numba,
        faulthandler.enable()  # torch) names the Python line that called it
    # the photo3d command: a signal after the command (its outputs complete, the process
    # about to end) is still one line and 128 + signal, not a traceback or death by it
    after = _late if argv is None else None
    try:
        with handle_signals(after=after) as guard:  # from the start: the parser imports a lot
            args = None
            try:
                args = build_parser().parse_args(argv)
                # --threads before numba or torch load; a bad PHOTO3D_THREADS is told
                # before any work; the budget is this command's only (main may run again)
                with command_threads(args.threads):
                    warnings.showwarning = show
                    with reading(*command_inputs(args)):  # no write may reach them
                        return args.run(args)
            except Photo3DError as err:  # also MissingExtra: an optional package is missing
                print(f"photo3d: error: {err}", file=sys.stderr)
                return 2
            except BaseException as err:  # noqa: B036 - only interruptions become a line
                signum = guard.signum or (signal.SIGINT if _interrupted(err) else None)
                if signum is None:
                    short = _out_of_resources(err, getattr(args, "command", None))
                    if short is not None:
                        print(f"photo3d: error: {short}", file=sys.stderr)
                        return 1
                    raise
                return _say_interrupted(signum)
            finally:
                if argv is None:  # the photo3d command: the process ends next
                    # Python's last garbage collections at exit walk numba's and torch's
                    # object graphs and free what they find (0.2-0.4 s after a make, 2.4 s
                    # after an interrupted train); frozen objects are left to the
                    # operating system (the files are written and closed, the temporary
                    # ones removed)
                    gc.freeze()
    except KeyboardInterrupt as err:  # also Interrupted: it landed as the command ended
        return _say_interrupted(getattr(err, "signum", signal.SIGINT))


def _out_of_resources(err: BaseException, command: str | None) -> str | None:
    """The one line for an error that says the process ran out of something (memory,
    file descriptors, threads) rather than a fault of photo3d's; None for any other.

    Example:
        >>> _out_of_resources(OSError(24, "Too many open files"), "make")[:20]
        'too many open files '
        >>> _out_of_resources(ValueError("a bug"), "make") is None
        True
    """
    import errno

    fewer = " or use fewer --workers" if command == "batch" else ""
    if isinstance(err, MemoryError):
        return "out of memory (try a smaller --size)"
    if isinstance(err, OSError) and err.errno in (errno.EMFILE, errno.ENFILE):
        try:
            import resource

            limit = f" (the limit, ulimit -n, is {resource.getrlimit(resource.RLIMIT_NOFILE)[0]})"
        except (ImportError, OSError, ValueError):
            limit = ""
        return f"too many open files{limit}: raise it{fewer}"
    if isinstance(err, RuntimeError) and "can't start new thread" in str(err):
        return ("cannot start a thread (out of memory or threads): use a smaller --threads"
                f"{fewer}")
    return None


def _say_interrupted(signum: int) -> int:
    """Print ``photo3d: interrupted`` (naming a signal other than SIGINT); the exit
    status, ``128 + signum``."""
    name = "" if signum == signal.SIGINT else f" ({signal.Signals(signum).name})"
    print(f"photo3d: interrupted{name}", file=sys.stderr)
    return 128 + signum


def _late(signum: int, frame) -> None:
    """The photo3d command's handler of SIGINT, SIGTERM and SIGHUP once the command has
    ended (its outputs are complete, or removed): the one line and ``128 + signum``,
    at once (nothing is left to clean up)."""
    _say_interrupted(signum)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(128 + signum)


def command_inputs(args: argparse.Namespace) -> list[Path]:
    """The files a command reads, which the write gate keeps every write away from
    (:func:`photo3d.files.gate.reading`): the photo, its depth map, right view and
    depth model, keyframe files, and a 3D photo folder's ``photo3d.npz``.

    Example:
        >>> command_inputs(argparse.Namespace(photo=Path("out"), image=None))
        [PosixPath('out/photo3d.npz')]
    """
    found = [value for name in ("image", "depth", "right", "depth_model")
             if isinstance(value := getattr(args, name, None), str | Path)
             and os.path.isfile(value)]
    found += [p for p in getattr(args, "paths", None) or () if os.path.isfile(p)]
    photo = getattr(args, "photo", None)
    if isinstance(photo, Path):
        found.append(photo / "photo3d.npz")
    return [Path(p) for p in found]


def _interrupted(err: BaseException) -> bool:
    """True if ``err`` is, or was caused by, a KeyboardInterrupt (numba wraps it)."""
    seen = set()
    while err is not None and id(err) not in seen:
        if isinstance(err, KeyboardInterrupt):
            return True
        seen.add(id(err))
        err = err.__cause__ or err.__context__
    return False

if __name__ == "__main__":
    sys.exit(main())
