"""Folders of photos and depth maps: which files count, and how a depth map finds its photo.

One rule for ``photo3d train --depth DIR`` and ``photo3d batch --depth DIR``: a
depth map belongs to the photo with the same *key*, the file's path relative to
its folder without the extension (``a.jpg`` <-> ``a.png``; with subfolders
``trip/a.jpg`` <-> ``trip/a.npy``). Two maps with the same key are refused.
"""

from __future__ import annotations

from pathlib import Path

from photo3d.errors import InputError

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".webp")
"""Photo files (without the HEIF extensions, which need ``photo3d[heif]``)."""
HEIF_SUFFIXES = (".heic", ".heif", ".hif")
"""HEIF photo files (``photo3d[heif]``)."""
PHOTO_SUFFIXES = IMAGE_SUFFIXES + HEIF_SUFFIXES
"""Every photo file photo3d reads (:func:`photo3d.depth.sources.read_photo`): what
``batch``, ``eval --heldout`` and the UI take as photos."""
DEPTH_SUFFIXES = (".png", ".npy", ".pfm", ".tif", ".tiff")
"""Depth map files (:func:`photo3d.io.depth.read_depth`)."""


def files_in(folder: Path, suffixes: tuple[str, ...], *, recursive: bool = False,
             skip: Path | None = None) -> list[Path]:
    """Files of ``folder`` with one of ``suffixes`` (any case), sorted.

    With ``recursive``, each real folder is entered once: a symbolic link to a
    folder already visited (a link loop, two links to one folder) is not followed
    again.

    Args:
        folder: the folder.
        suffixes: lower-case extensions with their dot.
        recursive: also look in subfolders (hidden ones, starting with ``.``, and
            ``skip`` are left out).
        skip: a subfolder never entered (e.g. the output folder of a batch).

    Raises:
        InputError: a folder cannot be listed (permissions).

    Example:
        >>> import tempfile
        >>> d = Path(tempfile.mkdtemp()); (d / "s").mkdir()
        >>> for name in ("b.PNG", "a.jpg", "notes.txt", "s/c.png"): (d / name).touch()
        >>> (d / "s" / "loop").symlink_to(d)
        >>> [p.name for p in files_in(d, (".jpg", ".png"))]
        ['a.jpg', 'b.PNG']
        >>> [str(p.relative_to(d)) for p in files_in(d, (".png",), recursive=True)]
        ['b.PNG', 's/c.png']
    """
    folder = Path(folder)
    if not recursive:
        return sorted(p for p in _entries(folder) if p.is_file() and p.suffix.lower() in suffixes)
    seen: set[tuple[int, int]] = set()
    if skip is not None and skip.is_dir():
        seen.add(_identity(skip))
    found: list[Path] = []
    _walk(folder, suffixes, seen, found)
    return sorted(found, key=lambda p: p.relative_to(folder).parts)


def _identity(folder: Path) -> tuple[int, int]:
    st = folder.stat()
    return st.st_dev, st.st_ino


def _entries(folder: Path) -> list[Path]:
    try:
        return list(folder.iterdir())
    except OSError as err:
        raise InputError(f"cannot list folder {folder}: {err.strerror or err}") from None


def _walk(folder: Path, suffixes: tuple[str, ...], seen: set, found: list[Path]) -> None:
    seen.add(_identity(folder))
    # real subfolders before links to folders, so a folder keeps its own name if it can
    for p in sorted(_entries(folder), key=lambda p: (p.is_symlink(), p.name)):
        if p.is_dir():
            if not p.name.startswith(".") and _identity(p) not in seen:
                _walk(p, suffixes, seen, found)
        elif p.is_file() and p.suffix.lower() in suffixes:
            found.append(p)


def file_key(path: Path, folder: Path) -> str:
    """``path`` relative to ``folder``, without its extension, with ``/`` separators.

    Example:
        >>> file_key(Path("/photos/trip/a.jpg"), Path("/photos"))
        'trip/a'
    """
    return Path(path).relative_to(folder).with_suffix("").as_posix()


def depth_by_key(folder: Path | None, what: str = "depth", *,
                 recursive: bool = False) -> dict[str, Path]:
    """The depth maps of ``folder`` by key (see the module doc); ``{}`` for None.

    Raises:
        InputError: the folder is missing, or two maps have the same key.
    """
    if folder is None:
        return {}
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{what} folder {folder} does not exist or is not a folder")
    found: dict[str, Path] = {}
    for p in files_in(folder, DEPTH_SUFFIXES, recursive=recursive):
        key = file_key(p, folder)
        if key in found:
            raise InputError(f"{what} folder {folder} holds two maps for {key!r}: "
                             f"{found[key].name} and {p.name}")
        found[key] = p
    return found
