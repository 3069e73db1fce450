"""What a file reader may allocate: a file's declared size is checked against the memory
the machine can give before anything is decoded.

A small file can declare a huge array (a constant 13000x13000 PNG is 0.5 MB; a zip of
``.npy`` arrays declaring 67 million pixels is 2.7 MB). The readers of photos, depth
maps and 3D photos estimate what decoding needs from the header alone and refuse, in
one line, what the machine cannot hold (:func:`check_available`).
:func:`photo3d.resources.available_memory` is :func:`available_memory`.

Example:
    >>> check_available(1000, "a tiny array")  # fits on any machine
"""

from __future__ import annotations

import os

from photo3d.errors import InputError


def available_memory() -> int | None:
    """Bytes the system can give this process now (Linux ``MemAvailable``), or None
    when unknown.

    Example:
        >>> have = available_memory()
        >>> have is None or have > 0
        True
    """
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def check_available(need: float, what: str) -> None:
    """Refuse to decode what needs more than the available memory.

    Args:
        need: estimated peak bytes of the decoding.
        what: what is decoded, for the message (``"its 13000x13000 pixels"``).

    Raises:
        InputError: ``"decoding {what} needs about 9.5 GB of memory but 2.1 GB are
            available"`` (:func:`format_bytes`; nothing is raised when the available
            memory is unknown).

    Example:
        >>> try:
        ...     check_available(2.5e12, "its 1000000x1000000 pixels")
        ... except InputError as err:
        ...     print(str(err)[:64])
        decoding its 1000000x1000000 pixels needs about 2500.0 GB of mem
    """
    have = available_memory()
    if have is not None and need > have:
        raise InputError(f"decoding {what} needs about {format_bytes(need)} of memory but "
                         f"{format_bytes(have)} are available")


def format_bytes(count: float) -> str:
    """``count`` bytes for a message: MB below a gigabyte, else GB.

    Example:
        >>> format_bytes(134_217_728), format_bytes(9.46e9)
        ('134 MB', '9.5 GB')
    """
    return f"{count / 1e6:.0f} MB" if count < 1e9 else f"{count / 1e9:.1f} GB"
