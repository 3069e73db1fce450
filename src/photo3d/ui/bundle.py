"""One zip of a 3D photo folder, for the page's download (and the API's result).

Already compressed files (``photo3d.npz``, videos, ``mesh.glb`` with its JPEG
texture, PNGs, ``splats.spz``: gzip) are stored as they are; the others
(``mesh.ply``, ``viewer.html``, ``config.json``) are deflated. The zip is written
under a temporary name and renamed into place
(:func:`photo3d.files.atomic.atomic_write`).

Example:
    >>> import tempfile, zipfile
    >>> root = Path(tempfile.mkdtemp()); (root / "out" / "video").mkdir(parents=True)
    >>> _ = (root / "out" / "config.json").write_text("{}")
    >>> _ = (root / "out" / "video" / "circle.mp4").write_bytes(b"0")
    >>> with zipfile.ZipFile(zip_folder(root / "out", root / "a.zip")) as z:
    ...     sorted(z.namelist())
    ['config.json', 'video/circle.mp4']
"""

from __future__ import annotations

import re
import zipfile
from collections.abc import Callable, Sequence
from pathlib import Path

from photo3d.files.atomic import atomic_write

STORED_SUFFIXES = (".npz", ".glb", ".png", ".jpg", ".mp4", ".webm", ".gif", ".spz")
"""Files zipped without compression (they hardly shrink)."""


def zip_folder(folder: Path, target: Path, *, extra: Sequence[Path] = (),
               progress: Callable[[float], None] | None = None) -> Path:
    """Zip every regular file under ``folder`` (paths relative to it) plus ``extra``
    files (at the top of the zip) into ``target``.

    Args:
        folder: the folder to zip (symbolic links in it are skipped).
        target: the ``.zip`` to write (replaced).
        extra: more files to add by their names.
        progress: ``progress(fraction)`` after each file, by bytes.

    Returns:
        ``target``.
    """
    files = [(p, p.relative_to(folder).as_posix()) for p in sorted(folder.rglob("*"))
             if p.is_file() and not p.is_symlink()]
    files += [(p, p.name) for p in extra]
    total = sum(p.stat().st_size for p, _ in files) or 1
    done = 0
    with atomic_write(target) as f, zipfile.ZipFile(f, "w") as zf:
        for path, name in files:
            stored = path.suffix.lower() in STORED_SUFFIXES
            zf.write(path, name, compress_type=zipfile.ZIP_STORED if stored
                     else zipfile.ZIP_DEFLATED, compresslevel=None if stored else 6)
            done += path.stat().st_size
            if progress is not None:
                progress(done / total)
    return target


def safe_stem(name: str, *, default: str = "photo") -> str:
    """A file stem made only of letters, digits, ``.``, ``_`` and ``-`` (at most 64),
    from a name a client sent.

    Example:
        >>> safe_stem("My photo (1).heic"), safe_stem("../../.."), safe_stem("é.jpg")
        ('My_photo_1', 'photo', 'photo')
    """
    stem = Path(name.replace("\\", "/")).stem if name else ""
    stem = re.sub(r"[^A-Za-z0-9._-]+", "_", stem).strip("._-")[:64]
    return stem or default
