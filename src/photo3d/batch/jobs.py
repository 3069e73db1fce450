"""What a batch is made of: the photos of a folder, their depth maps, and the make options.

:func:`find_photos` lists a folder into :class:`PhotoJob` s (one output folder per
photo, named by the photo's path relative to the input folder without its
extension); :class:`~photo3d.folder.MakeOptions` (re-exported here) holds everything
``photo3d make`` takes besides the photo and its depth, so a worker process can
rebuild the same run.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from photo3d.errors import InputError
from photo3d.files.folders import PHOTO_SUFFIXES, depth_by_key, file_key, files_in
from photo3d.folder import MakeOptions

__all__ = ["PHOTO_SUFFIXES", "MakeOptions", "PhotoJob", "find_photos", "output_problem"]


@dataclass(frozen=True)
class PhotoJob:
    """One photo of a batch.

    Attributes:
        name: the photo's path relative to the input folder without its extension,
            ``/``-separated (``"a"``, ``"trip/b"``); its output folder is ``OUT/name/``.
        image: the photo file.
        depth: its depth map from the depth folder (same name), or None (then the
            embedded depth map, else the depth model).
        redo: make it even if its output folder is finished (its manifest record
            was unreadable).
    """

    name: str
    image: Path
    depth: Path | None = None
    redo: bool = False


def output_problem(name: str) -> str | None:
    """Why ``name`` cannot be a photo's output folder under OUT, or None if it can.

    A name must stay inside OUT (no empty, ``.`` or ``..`` part), must not be
    hidden (``.NAME.XXXXXXXX.tmp`` are the temporary folders of the writers) and
    must not be the batch's own files (``batch.jsonl``, ``batch.lock``, in any case).

    Example:
        >>> [output_problem(n) is None for n in ("a", "trip/b", ".", "batch.jsonl", ".x")]
        [True, True, False, False, False]
    """
    from photo3d.batch.lock import LOCK
    from photo3d.batch.manifest import MANIFEST

    parts = name.split("/")
    if any(part in ("", ".", "..") for part in parts):
        return f"its output folder {name!r} would not be a folder inside the output folder"
    if any(part.startswith(".") for part in parts):
        return f"its output folder {name!r} would be hidden (reserved for temporary folders)"
    if parts[0].lower() in (MANIFEST, LOCK):
        return f"its output folder {name!r} is the name of the batch's own {parts[0]}"
    return None


def find_photos(folder: str | Path, *, depth: str | Path | None = None,
                recursive: bool = False, skip: str | Path | None = None) -> list[PhotoJob]:
    """The photos of ``folder`` with their depth maps, sorted by name.

    Args:
        folder: the input folder.
        depth: a folder of depth maps named like the photos (the rule of
            :mod:`photo3d.files.folders`, shared with ``photo3d train --depth``).
        recursive: also take the photos of subfolders (hidden ones are left out).
        skip: a subfolder never entered (the batch's own output folder; with
            ``recursive``, it may not be ``folder`` itself).

    Raises:
        InputError: a folder is missing, there is no photo, or two photos would
            share an output folder (``a.jpg`` and ``a.png``) or nest theirs
            (``trip.jpg`` and ``trip/a.jpg``, with ``recursive``), or ``skip`` is
            ``folder`` with ``recursive``.

    Example:
        >>> import tempfile
        >>> d = Path(tempfile.mkdtemp()); (d / "depth").mkdir()
        >>> for name in ("a.jpg", "b.png", "depth/b.npy"): (d / name).touch()
        >>> [(j.name, j.depth is not None) for j in find_photos(d, depth=d / "depth")]
        [('a', False), ('b', True)]
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"input folder {folder} does not exist or is not a folder")
    if recursive and skip is not None and Path(skip).is_dir() and folder.samefile(skip):
        raise InputError(f"with --recursive the output folder cannot be the input folder "
                         f"{folder}: the files of its 3D photo folders would be read as "
                         "photos")
    photos = files_in(folder, PHOTO_SUFFIXES, recursive=recursive,
                      skip=Path(skip) if skip is not None else None)
    if not photos:
        raise InputError(f"no photos in {folder} (looked for {', '.join(PHOTO_SUFFIXES)}"
                         + ("" if recursive else "; --recursive looks in subfolders") + ")")
    depths = depth_by_key(Path(depth) if depth is not None else None, recursive=recursive)
    jobs: dict[str, PhotoJob] = {}
    for path in photos:
        name = file_key(path, folder)
        if name in jobs:
            raise InputError(f"two photos would write the same output folder {name!r}: "
                             f"{jobs[name].image.name} and {path.name} (rename one)")
        jobs[name] = PhotoJob(name, path, depths.get(name))
    for job in jobs.values():  # trip.jpg and trip/a.jpg: OUT/trip/a inside OUT/trip
        parts = job.name.split("/")
        outer = next((jobs[o] for i in range(1, len(parts))
                      if (o := "/".join(parts[:i])) in jobs), None)
        if outer is not None:
            raise InputError(f"two photos would nest their output folders: {job.name!r} of "
                             f"{job.image.relative_to(folder)} inside {outer.name!r} of "
                             f"{outer.image.name} (rename one)")
    return list(jobs.values())
