"""Downloading weights once: the cache folder, verified downloads, reachability.

Weights photo3d fetches at run time (not the Hugging Face depth models, which live
in the Hugging Face cache) are kept in :func:`cache_dir`: ``$PHOTO3D_CACHE``, by
default ``~/.cache/photo3d``. :func:`download` streams a URL into a temporary
sibling of its target (:func:`photo3d.files.atomic.atomic_write`), checks its
SHA-256 and only then renames it into place: a failed, refused or interrupted
download leaves nothing behind. Nothing here unpickles anything; callers read what
they download with readers that cannot run code (``np.load(allow_pickle=False)``,
safetensors, ``torch.load(weights_only=True)``).

Example:
    >>> import hashlib, pathlib, tempfile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> (folder / "w.bin").write_bytes(b"weights")
    7
    >>> url = (folder / "w.bin").as_uri()
    >>> digest = hashlib.sha256(b"weights").hexdigest()
    >>> download(url, folder / "cache" / "w.bin", sha256=digest).read_bytes()
    b'weights'
"""

from __future__ import annotations

import hashlib
import http.client
import os
import socket
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path

from photo3d.errors import InputError
from photo3d.files.atomic import PathLike, atomic_write
from photo3d.progress import ByteProgress

CACHE_ENV = "PHOTO3D_CACHE"
"""Environment variable naming the cache folder (default ``~/.cache/photo3d``)."""


MAX_BYTES = 2 << 30
"""The largest download :func:`download` takes by default (2 GiB): a server that never
stops sending cannot fill the disk."""

_BLOCK = 1 << 20


def cache_dir() -> Path:
    """The folder of photo3d's downloaded weights: ``$PHOTO3D_CACHE`` or
    ``~/.cache/photo3d`` (not created here).

    Example:
        >>> import os
        >>> cache_dir() == Path(os.environ.get("PHOTO3D_CACHE") or
        ...                     Path.home() / ".cache" / "photo3d")
        True
    """
    return Path(os.environ.get(CACHE_ENV) or Path.home() / ".cache" / "photo3d")


def sha256_of(path: PathLike) -> str:
    """Hex SHA-256 of a file's bytes (read in 4 MB blocks).

    Example:
        >>> import pathlib, tempfile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "a.bin"
        >>> _ = path.write_bytes(b"abc")
        >>> sha256_of(path)[:16]
        'ba7816bf8f01cfea'
    """
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 22), b""):
            digest.update(block)
    return digest.hexdigest()


def download(url: str, path: PathLike, *, sha256: str, progress: ByteProgress | None = None,
             timeout: float = 30.0, max_bytes: int = MAX_BYTES) -> Path:
    """Download ``url`` to ``path`` (its folder is created), atomically and verified.

    The bytes go to a temporary sibling of ``path`` that is renamed over it only once
    they are complete and their SHA-256 is ``sha256``; on any failure, refusal or
    interruption (Ctrl-C, SIGTERM under :func:`photo3d.files.signals.handle_signals`)
    the temporary file is removed and ``path`` is left as it was.

    Args:
        url: ``https://``, ``http://`` or ``file://`` URL.
        path: the file to write.
        sha256: expected hex SHA-256 of the content.
        progress: called with ``(bytes done, total bytes or None)`` at the start and
            after every block (1 MB); the library never prints.
        timeout: seconds to wait for the server before giving up (per request, and
            per block read).
        max_bytes: refuse a file larger than this: at once if the server announces
            its size, else as soon as more arrives (default :data:`MAX_BYTES`).

    Returns:
        ``path``.

    Raises:
        InputError: the server cannot be reached or fails (offline?), the transfer
            stops early, or the content is larger than ``max_bytes`` or has another
            SHA-256 (refused: the message starts with ``refused``); one line.
        OutputError: ``path`` cannot be written.

    Example:
        >>> import pathlib, tempfile
        >>> source = pathlib.Path(tempfile.mkdtemp()) / "w.bin"
        >>> _ = source.write_bytes(b"not the weights")
        >>> download(source.as_uri(), source.with_name("copy.bin"), sha256="0" * 64)
        ... # doctest: +ELLIPSIS
        Traceback (most recent call last):
        photo3d.errors.InputError: refused file:///.../w.bin: its SHA-256 is ..., expected 000...
        >>> source.with_name("copy.bin").exists()
        False
        >>> download(source.as_uri(), source.with_name("copy.bin"), sha256="0" * 64,
        ...          max_bytes=8)  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        photo3d.errors.InputError: refused file:///.../w.bin: larger than 8 bytes, the most expected
    """
    path = Path(path)
    try:
        response = urllib.request.urlopen(url, timeout=timeout)
    except (OSError, ValueError, http.client.HTTPException) as err:
        raise InputError(f"cannot download {url}: {_reason(err)} (offline?)") from err
    with response:
        length = response.headers.get("Content-Length")
        total = int(length) if length and length.isdigit() else None
        if total is not None and total > max_bytes:
            raise InputError(_too_large(url, max_bytes))
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_write(path, "wb") as f:
            digest, done = hashlib.sha256(), 0
            if progress is not None:
                progress(done, total)
            while True:
                try:
                    block = response.read(_BLOCK)
                except (OSError, http.client.HTTPException) as err:
                    raise InputError(f"download of {url} failed after {done} bytes: "
                                     f"{_reason(err)}") from err
                if not block:
                    break
                if done + len(block) > max_bytes:  # a server that never stops
                    raise InputError(_too_large(url, max_bytes))
                f.write(block)
                digest.update(block)
                done += len(block)
                if progress is not None:
                    progress(done, total)
            if total is not None and done != total:
                raise InputError(f"download of {url} stopped after {done} of {total} bytes")
            if digest.hexdigest() != sha256.lower():
                raise InputError(f"refused {url}: its SHA-256 is {digest.hexdigest()}, "
                                 f"expected {sha256.lower()}")
    return path


def check_reachable(url: str, *, what: str, timeout: float = 5.0) -> None:
    """Raise at once if the server of ``url`` does not accept a connection.

    Clients that retry for a long time when offline (the Hugging Face hub's: about
    25 s) are checked with this first.

    Args:
        url: any URL; its host and port (default 443 for https, 80 for http).
        what: what would be downloaded, for the message (``"depth model NAME"``).
        timeout: seconds to wait for the connection.

    Raises:
        InputError: ``cannot download WHAT: HOST is not reachable (offline?)``.

    Example:
        >>> check_reachable("https://localhost:1/x", what="the weights", timeout=1)
        ... # doctest: +ELLIPSIS
        Traceback (most recent call last):
        photo3d.errors.InputError: cannot download the weights: localhost:1 is not reachable ...
    """
    parts = urllib.parse.urlsplit(url if "://" in url else f"https://{url}")
    try:
        port = parts.port or (80 if parts.scheme == "http" else 443)
        socket.create_connection((parts.hostname or "", port), timeout=timeout).close()
    except (OSError, ValueError):
        raise InputError(f"cannot download {what}: {parts.netloc} is not reachable "
                         "(offline?)") from None


def _too_large(url: str, max_bytes: int) -> str:
    size = f"{max_bytes} bytes" if max_bytes < 10**6 else f"{max_bytes / 1e6:.0f} MB"
    return f"refused {url}: larger than {size}, the most expected"


def _reason(err: BaseException) -> str:
    """One line saying why a request failed (``HTTP Error 404: Not Found``, ...)."""
    if isinstance(err, urllib.error.URLError) and not isinstance(err, urllib.error.HTTPError):
        text = str(err.reason)  # not "<urlopen error ...>"
    else:
        text = str(err)
    text = " ".join(text.split()) or type(err).__name__
    return text if len(text) <= 160 else text[:157] + "..."
