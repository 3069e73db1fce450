"""The learned fill's weights for ``photo3d ui``: the paper's nets, as ``photo3d make
--inpainter learned`` runs them (:func:`photo3d.inpaint.learned.default_weights`: the
authors' published files, downloaded once into the cache and checked by SHA-256).

A request that chooses ``learned`` first makes sure they are there, showing the
download in its progress bar; requests at once download them once. Offline, the
client gets one line without the server's folders (the server's log has the full
reason); a file in the cache that is not the authors' (another SHA-256) is one line
naming it inside the cache and what to do. Nothing here imports Gradio or PyTorch.

Example:
    >>> "460 MB" in NOTE
    True
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from pathlib import Path

from photo3d.errors import InputError

log = logging.getLogger(__name__)

NOTE = ("learned: the paper's nets; the first use downloads the authors' weights "
        "(about 460 MB) into this server's cache")
"""What the page says about the ``learned`` fill."""

_download = threading.Lock()


def learned_weights(say: Callable[[str], None] | None = None) -> Path:
    """The folder of the authors' weights, downloaded first if needed.

    Args:
        say: ``say(line)`` while downloading (``downloading the learned fill's weights:
            edge-model.pth 40 %``) or waiting for another request's download; it may
            raise to stop (a cancelled request).

    Raises:
        MissingExtra: PyTorch is not installed (``photo3d[learned]``).
        InputError: they cannot be downloaded (one line for the client).
    """
    from photo3d.inpaint.learned import default_weights
    from photo3d.nets.authors import NotTheAuthors

    shown: list[object] = [None]

    def progress(name: str, done: int, total: int | None) -> None:
        percent = None if not total else int(100 * done / total)
        if say is not None and (name, percent) != shown[0]:
            shown[0] = (name, percent)
            size = f"{percent} %" if percent is not None else f"{done / 1e6:.0f} MB"
            say(f"downloading the learned fill's weights: {name} {size}")

    while not _download.acquire(timeout=0.5):  # another request is downloading them
        if say is not None:
            say("waiting for the learned fill's weights to download")
    try:
        return default_weights(progress=progress)
    except NotTheAuthors as err:
        log.warning("photo3d ui: the learned fill's weights: %s", err)
        where = f"{err.path.parent.name}/{err.path.name}"
        raise InputError(f"the learned fill's weights file {where} in this server's photo3d "
                         "cache ($PHOTO3D_CACHE, default ~/.cache/photo3d) is not the "
                         "authors': its SHA-256 checksum does not match; choose another "
                         "fill, or ask whoever runs the server to move that file elsewhere "
                         "or delete it (the next learned fill downloads the authors' "
                         "file)") from None
    except InputError as err:
        log.warning("photo3d ui: the learned fill's weights: %s", err)
        raise InputError("the learned fill needs the authors' weights (about 460 MB), "
                         "which this server cannot download now (offline?); choose "
                         "another fill, or ask whoever runs the server to run photo3d "
                         "make --inpainter learned once") from None
    finally:
        _download.release()
