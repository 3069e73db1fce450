"""Reading back what may be hostile: a file's size, and a JSON text's size and
nesting, bounded before anything is decoded.

Every file photo3d reads back (a 3D photo folder's ``config.json``, a training
run's ``checkpoints.json`` and ``state.json``, ``results.json``, a batch's
manifest lines, a GLB's JSON chunk, ``photo3d.npz``'s header) may have been
written by anyone. :func:`read_bytes` refuses what is not a regular file (a FIFO
would block for ever) or is larger than the caller's bound, before reading it;
:func:`loads_json` measures the nesting of a JSON text before ``json.loads``,
which recurses once per level (a 100 kB text of ``[`` is a ``RecursionError``).
Anything malformed is one line, a :class:`~photo3d.errors.InputError`.

Example:
    >>> loads_json(b'{"a": [1, 2]}', what="x.json")
    {'a': [1, 2]}
    >>> loads_json(b"[" * 100_000, what="x.json")
    Traceback (most recent call last):
    photo3d.io.bounded.MalformedJSON: x.json is not valid: JSON nested deeper than 64 levels
"""

from __future__ import annotations

import json
import os
import re
import stat
from pathlib import Path
from typing import Any

import numpy as np

from photo3d.errors import InputError

PathLike = str | os.PathLike[str]

MAX_DEPTH = 64
"""The deepest JSON nesting photo3d reads (its own files nest at most 6 levels)."""
MAX_JSON_BYTES = 16 << 20
"""The largest JSON file photo3d reads by default (its own are a few kB; a
checkpoint record or an eval's results at most a few hundred)."""

class MalformedJSON(InputError):
    """A JSON text that is not valid, or nested too deeply; ``reason`` says why.

    Example:
        >>> MalformedJSON("config.json", "not JSON").reason
        'not JSON'
    """

    def __init__(self, what: str, reason: str) -> None:
        super().__init__(f"{what} is not valid: {reason}")
        self.reason = reason


_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"', re.DOTALL)


def json_depth(data: bytes | str) -> int:
    """The deepest nesting of arrays and objects in the JSON text ``data``
    (brackets inside strings do not count; a malformed text gives some number).

    Example:
        >>> json_depth(b'{"a": [[1], "]]]"]}'), json_depth(b"3"), json_depth("[[[")
        (3, 0, 3)
    """
    raw = data.encode("utf-8", "surrogatepass") if isinstance(data, str) else bytes(data)
    bare = np.frombuffer(_STRING.sub(b'""', raw), np.uint8)
    step = (np.isin(bare, (0x5B, 0x7B)).astype(np.int64)
            - np.isin(bare, (0x5D, 0x7D)).astype(np.int64))
    return int(np.cumsum(step).max(initial=0))


def loads_json(data: bytes | str, *, what: str, max_depth: int = MAX_DEPTH) -> Any:
    """``json.loads(data)`` with its nesting bounded first; any malformed text is one
    line naming ``what``.

    Raises:
        MalformedJSON: ``WHAT is not valid: REASON`` (nested deeper than ``max_depth``,
            not UTF-8, not JSON, a number of more than 4300 digits).

    Example:
        >>> loads_json('{"a": 1', what="config.json")
        Traceback (most recent call last):
        photo3d.io.bounded.MalformedJSON: config.json is not valid: Expecting ',' delimiter: line 1 column 8 (char 7)
    """  # noqa: E501
    if json_depth(data) > max_depth:
        raise MalformedJSON(what, f"JSON nested deeper than {max_depth} levels")
    try:
        return json.loads(data)
    except (ValueError, RecursionError) as err:  # UnicodeDecodeError is a ValueError
        reason = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise MalformedJSON(what, reason[:200]) from None


def read_bytes(path: PathLike, *, max_bytes: int, what: str | None = None) -> bytes:
    """The bytes of the regular file ``path``, refused before reading when larger
    than ``max_bytes``.

    A FIFO, socket or device is refused without blocking (opened non-blocking,
    checked with ``fstat``).

    Raises:
        InputError: ``cannot read WHAT: REASON`` (missing, not a regular file, larger
            than ``max_bytes``, the system's reason).

    Example:
        >>> import pathlib, tempfile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "a.json"
        >>> _ = path.write_bytes(b"[1]")
        >>> read_bytes(path, max_bytes=3)
        b'[1]'
        >>> read_bytes(path, max_bytes=2)
        Traceback (most recent call last):
        photo3d.errors.InputError: cannot read ...a.json: it has 3 bytes, more than the 2 expected
    """
    what = str(path) if what is None else what
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as err:
        raise InputError(f"cannot read {what}: {err.strerror or err}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise InputError(f"cannot read {what}: it is not a regular file")
        if st.st_size > max_bytes:
            raise InputError(f"cannot read {what}: it has {st.st_size} bytes, more than "
                             f"the {max_bytes} expected")
        with os.fdopen(os.dup(fd), "rb") as file:
            data = file.read(max_bytes + 1)
    except OSError as err:
        raise InputError(f"cannot read {what}: {err.strerror or err}") from None
    finally:
        os.close(fd)
    if len(data) > max_bytes:  # it grew meanwhile
        raise InputError(f"cannot read {what}: it has more than the {max_bytes} bytes "
                         "expected")
    return data


def read_json(path: PathLike, *, what: str | None = None, max_bytes: int = MAX_JSON_BYTES,
              max_depth: int = MAX_DEPTH) -> Any:
    """The JSON value in the file ``path``, its size and nesting bounded before it is
    parsed (:func:`read_bytes`, :func:`loads_json`).

    Raises:
        InputError: one line naming ``what`` (default: ``path``).

    Example:
        >>> import pathlib, tempfile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "state.json"
        >>> _ = path.write_text('{"step": 2}')
        >>> read_json(path)["step"]
        2
    """
    what = str(Path(path)) if what is None else what
    return loads_json(read_bytes(path, max_bytes=max_bytes, what=what), what=what,
                      max_depth=max_depth)
