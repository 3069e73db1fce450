"""Read ``.npy`` arrays from untrusted files: the declared size is checked before allocating.

``np.load`` trusts the header: a 100-byte file declaring shape ``(100000, 100000)``
makes it allocate 37 GiB (or fail with ``MemoryError``). :func:`read_npy` reads the
header, refuses object (pickle) arrays, arrays larger than ``max_items`` or than the
available memory holds (:func:`photo3d.io.limits.check_available`) and data shorter
than declared, and only then reads the values, straight into the array.

Example:
    >>> import io
    >>> import numpy as np
    >>> buf = io.BytesIO()
    >>> np.save(buf, np.arange(6, dtype=np.int32).reshape(2, 3))
    >>> _ = buf.seek(0)
    >>> read_npy(buf, max_items=10).tolist()
    [[0, 1, 2], [3, 4, 5]]
"""

from __future__ import annotations

from typing import BinaryIO

import numpy as np

from photo3d.errors import InputError
from photo3d.io.limits import check_available

MAX_ITEMS = 2 * 89_478_485
"""Default limit on the values of one array (Pillow's decompression-bomb limit)."""
_CHUNK = 1 << 24  # bytes read at a time (a zip member's reader copies what it returns)


def read_npy_header(file: BinaryIO) -> tuple[tuple[int, ...], bool, np.dtype]:
    """Read the header of one ``.npy`` array, leaving ``file`` at the start of its data.

    Returns:
        ``(shape, fortran_order, dtype)`` as declared; nothing is allocated, so the
        caller can check the declared size first.

    Raises:
        InputError: not a ``.npy`` array, or an object (pickled) dtype.

    Example:
        >>> import io
        >>> buf = io.BytesIO()
        >>> np.save(buf, np.zeros((2, 3), np.float32))
        >>> _ = buf.seek(0)
        >>> read_npy_header(buf)
        ((2, 3), False, dtype('float32'))
    """
    try:
        version = np.lib.format.read_magic(file)
        if version == (1, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_1_0(file)
        else:
            shape, fortran, dtype = np.lib.format.read_array_header_2_0(file)
    except (ValueError, OSError, EOFError, SyntaxError) as err:
        raise InputError(f"not a .npy array ({err})") from None
    if dtype.hasobject:
        raise InputError("not a plain numeric array (pickled and object arrays are refused)")
    return shape, fortran, dtype


def read_npy(file: BinaryIO, *, max_items: int = MAX_ITEMS, size: int | None = None) -> np.ndarray:
    """Read one ``.npy`` array from an open binary file, checking its header first.

    Args:
        file: positioned at the start of the ``.npy`` data.
        max_items: largest number of values accepted.
        size: bytes available from the start (checked against the declared shape when
            given; a file or zip member shorter than declared is refused).

    Returns:
        The array (any numeric dtype, never an object array).

    Raises:
        InputError: not a ``.npy`` array, an object (pickled) dtype, more than
            ``max_items`` values, more bytes than the available memory holds, or
            truncated data.
    """
    shape, fortran, dtype = read_npy_header(file)
    count = int(np.prod(shape, dtype=np.float64)) if shape else 1
    if count > max_items:
        shown = "x".join(str(s) for s in shape)
        raise InputError(f"declared shape {shown} holds {count:,} values; "
                         f"photo3d accepts at most {max_items:,}")
    nbytes = count * dtype.itemsize
    if size is not None and size - file.tell() < nbytes:
        raise InputError(f"truncated: shape {shape} declared but the data is shorter")
    check_available(nbytes * (2 if fortran else 1),
                    f"an array of shape {'x'.join(str(s) for s in shape)} ({dtype})")
    array = np.empty(count, dtype)
    data = memoryview(array.view(np.uint8))
    done = 0
    try:
        while done < nbytes:
            chunk = file.read(min(_CHUNK, nbytes - done))
            if not chunk:
                break
            data[done:done + len(chunk)] = chunk
            done += len(chunk)
    except (OSError, EOFError, ValueError) as err:
        raise InputError(f"cannot read the data ({err})") from None
    if done < nbytes:
        raise InputError(f"truncated: shape {shape} declared but the data is shorter")
    if fortran:
        return array.reshape(shape[::-1]).transpose().copy()
    return array.reshape(shape)
