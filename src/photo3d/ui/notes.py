"""The warnings a request raises, collected for its status line (``photo3d make``
prints them on stderr as ``photo3d: warning: ...``; the page shows them).

Python's warning filters and ``warnings.showwarning`` are shared by every thread,
and a server makes several photos at once, so :func:`collect_warnings` swaps
neither: the first call wraps :func:`warnings.warn` for good, transparently (every
warning still takes its usual path through the filters), and a thread inside
:func:`collect_warnings` also gets each message noted, once. Only the kinds the
command line shows are noted: ``UserWarning`` and ``RuntimeWarning`` (Pillow's
``DecompressionBombWarning`` is one), not deprecations.

Example:
    >>> import warnings
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")
    ...     with collect_warnings() as notes:
    ...         warnings.warn("depth resampled")
    ...         warnings.warn("depth resampled")
    ...         warnings.warn("old API", DeprecationWarning)
    >>> notes
    ['depth resampled']
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Iterator
from contextlib import contextmanager

_local = threading.local()
_install = threading.Lock()
_original = None


def _warn(message, category=None, stacklevel=1, source=None, **kwargs):
    """:func:`warnings.warn`, noting the message in a collecting thread."""
    notes = getattr(_local, "notes", None)
    if notes is not None:
        kind = category or (type(message) if isinstance(message, Warning) else UserWarning)
        text = str(message)
        if issubclass(kind, UserWarning | RuntimeWarning) and text not in notes:
            notes.append(text)
    return _original(message, category, stacklevel + 1, source, **kwargs)


@contextmanager
def collect_warnings() -> Iterator[list[str]]:
    """The messages of the warnings this thread raises inside the ``with`` block, in
    order, each once (a list filled as they come)."""
    global _original
    with _install:
        if _original is None:
            _original = warnings.warn
            warnings.warn = _warn
    outer = getattr(_local, "notes", None)
    _local.notes = notes = []
    try:
        yield notes
    finally:
        _local.notes = outer
