"""The authors' weights: their three published checkpoints, downloaded once.

The paper's authors publish ``edge-model.pth``, ``depth-model.pth`` and
``color-model.pth`` at :data:`AUTHORS_URL` (their repository's ``download.sh``).
:func:`authors_weights` makes sure the three are in :func:`authors_folder`
(``$PHOTO3D_CACHE/authors``, default ``~/.cache/photo3d/authors``) and returns that
folder, which :func:`photo3d.nets.weights.load_inpainting_nets` then loads like any
other weights folder. A file is accepted only if its SHA-256 is the one in
:data:`photo3d.nets.weights.OFFICIAL_SHA256`: a download with another one is refused
and nothing is saved (:func:`photo3d.files.download.download`), and a file of another
SHA-256 already in the folder is refused and left alone (photo3d never writes one, so
it is someone else's). When the three files are there, nothing touches the network.

``$PHOTO3D_AUTHORS_URL`` replaces :data:`AUTHORS_URL` (a mirror, or a local server in
tests): an ``http://``, ``https://`` or ``file://`` URL of a folder holding the three
files.

Example:
    >>> authors_folder() == cache_dir() / "authors"
    True
    >>> sorted(FILES.values())
    ['color-model.pth', 'depth-model.pth', 'edge-model.pth']
"""

from __future__ import annotations

import os
from collections.abc import Callable
from functools import partial
from pathlib import Path
from urllib.parse import urlsplit

from photo3d.errors import InputError
from photo3d.files.download import cache_dir, download, sha256_of
from photo3d.nets import weights

AUTHORS_URL = "https://filebox.ece.vt.edu/~jbhuang/project/3DPhoto/model/"
"""Where the authors publish their checkpoints (vt-vl-lab/3d-photo-inpainting,
``download.sh``)."""
URL_ENV = "PHOTO3D_AUTHORS_URL"
"""Environment variable replacing :data:`AUTHORS_URL` (a mirror)."""
FOLDER = "authors"
"""The authors' weights' folder inside :func:`~photo3d.files.download.cache_dir`."""
FILES = {kind: f"{kind}-model.pth" for kind in weights.KINDS}
"""Net kind -> the authors' file name."""

MAX_BYTES = 512 << 20
"""The largest file accepted from :func:`authors_url` (512 MiB; the largest of the
authors' files holds 25.8 M float32 parameters, about 103 MB): a mirror that never
stops sending is refused instead of filling the disk."""

FileProgress = Callable[[str, int, int | None], None]
"""``progress(file name, bytes done, total bytes or None)`` of each download."""


class NotTheAuthors(InputError):
    """A file in :func:`authors_folder` has another SHA-256 than the authors' (photo3d
    did not write it and leaves it alone).

    Attributes:
        path: that file.
    """

    def __init__(self, message: str, path: Path) -> None:
        super().__init__(message)
        self.path = path


def authors_folder() -> Path:
    """The folder of the authors' weights: ``cache_dir() / "authors"`` (not created
    here).

    Example:
        >>> authors_folder().name
        'authors'
    """
    return cache_dir() / FOLDER


def authors_url() -> str:
    """The URL of the folder the authors' files are downloaded from:
    ``$PHOTO3D_AUTHORS_URL`` if set, else :data:`AUTHORS_URL`; it ends with ``/``.

    Raises:
        InputError: ``$PHOTO3D_AUTHORS_URL`` is not an http(s):// or file:// URL.

    Example:
        >>> from unittest import mock
        >>> with mock.patch.dict(os.environ, {URL_ENV: "http://127.0.0.1:8000/mirror"}):
        ...     authors_url()
        'http://127.0.0.1:8000/mirror/'
    """
    url = os.environ.get(URL_ENV) or AUTHORS_URL
    parts = urlsplit(url)
    if parts.scheme not in ("http", "https", "file") or not (parts.netloc or parts.path):
        raise InputError(f"{URL_ENV} must be an http://, https:// or file:// URL, got {url!r}")
    return url if url.endswith("/") else url + "/"


def authors_weights(*, progress: FileProgress | None = None) -> Path:
    """The folder holding the authors' three checkpoints, downloading those missing.

    Files already in :func:`authors_folder` are checked first (SHA-256); only missing
    ones are downloaded, one after the other, from :func:`authors_url`, each
    verified before it is saved. Pass the result to
    :func:`~photo3d.nets.weights.load_inpainting_nets` (or ``LearnedInpainter(weights=)``).

    Args:
        progress: ``progress(file name, bytes done, total or None)`` during each
            download; the library never prints.

    Returns:
        :func:`authors_folder`, holding ``edge-model.pth``, ``depth-model.pth`` and
        ``color-model.pth`` with the authors' SHA-256.

    Raises:
        InputError: one line: a file in the folder is not the authors'
            (:class:`NotTheAuthors`: it is left alone; the message says what to do), a
            download was refused (another
            SHA-256: nothing is saved), or a download failed (offline: the message
            names the files, the URL and the folder to put them in, and that
            ``--weights compact`` runs the nets shipped with photo3d).

    Example:
        >>> authors_weights().name  # doctest: +SKIP
        'authors'
    """
    folder = authors_folder()
    missing = [name for name in FILES.values() if not _checked(folder / name)]
    if not missing:
        return folder
    base = authors_url()
    for name in missing:
        report = None if progress is None else partial(progress, name)
        try:
            download(base + name, folder / name, sha256=_expected(name), progress=report,
                     max_bytes=MAX_BYTES)
        except InputError as err:
            raise InputError(_failure(err, name, base, folder)) from err
    return folder


def _expected(name: str) -> str:
    """The authors' SHA-256 of file ``name`` (read when needed: tests replace them)."""
    return weights.OFFICIAL_SHA256[name.removesuffix("-model.pth")]


def _checked(path: Path) -> bool:
    """True if the authors' ``path`` is there, False if it is missing; raise if
    something else is."""
    if not path.exists():
        return False
    if not path.is_file():
        raise InputError(f"{path} is not a file; move it elsewhere so that photo3d can "
                         f"download the authors' {path.name} there")
    try:
        digest = sha256_of(path)
    except OSError as err:
        raise InputError(f"cannot read {path}: {err.strerror or err}") from err
    if digest != _expected(path.name):
        raise NotTheAuthors(f"{path} is not the authors' {path.name}: its SHA-256 is "
                            f"{digest}, expected {_expected(path.name)}; photo3d did not "
                            "write it and leaves it alone: move it elsewhere or delete it, "
                            "then run again to download the authors' file", path)
    return True


def _failure(err: InputError, name: str, base: str, folder: Path) -> str:
    """One line for a failed download of ``name``: a refusal (another SHA-256) as it
    is; anything else (offline, HTTP error, dropped) with where to put the files."""
    if str(err).startswith("refused "):  # download()'s documented refusal message
        where = f"; check {URL_ENV}" if os.environ.get(URL_ENV) else ""
        return f"{err} (not the authors' {name}: nothing was saved{where})"
    names = list(FILES.values())
    return (f"{err}; put the authors' {', '.join(names[:-1])} and {names[-1]} "
            f"(from {base}) into {folder}, or run the small nets shipped with photo3d: "
            "--weights compact")
