"""Which files of a 3D photo folder photo3d wrote, so it replaces only those.

A 3D photo folder (:mod:`photo3d.output`) holds fixed names (``photo3d.npz``,
``config.json``, the meshes, the viewer) and files whose names depend on what was
asked for: the videos in ``video/`` and ``render --still`` images. A user may put a
video of their own in ``video/`` or a ``still.png`` of their own beside the mesh, so
those names are not photo3d's by their pattern alone: ``config.json`` lists, under
``"written"``, every such file photo3d wrote (paths relative to the folder, ``/``
separators). ``make --overwrite`` replaces a folder only if every entry is a fixed
name or listed there, and ``render`` replaces a video or still only if listed.

Folders saved before the list existed: their videos are the ones ``config.json``'s
``save.videos`` names.
"""

from __future__ import annotations

import contextlib
import fnmatch
import os
from collections.abc import Iterable, Iterator
from pathlib import Path

from photo3d.errors import InputError, OutputError
from photo3d.files.atomic import on_commit, refuse_symlink, write_json
from photo3d.files.gate import locked
from photo3d.files.staging import owned_by_names
from photo3d.files.temps import remove_orphans_in
from photo3d.io.bounded import read_json

LDI_FILE = "photo3d.npz"
EXPORT_FILES = ("splats.ply", "splats.spz", "splats.glb", "mesh.usdz", "*_qs*x*a*.png")
"""Names ``photo3d export`` writes (:mod:`photo3d.export`; the last, Looking Glass
quilts ``NAME_qsCOLSxROWSaASPECT.png``)."""
PHOTO_FILES = (LDI_FILE, "config.json", "mesh.ply", "mesh.glb", "viewer.html", "video",
               "still.png", "still_*.png", *EXPORT_FILES)
"""Top-level names in a 3D photo folder (``render --still`` adds ``still*.png``,
``export`` the :data:`EXPORT_FILES`)."""

FINISHED_FILES = (LDI_FILE, "config.json")
"""Files every finished 3D photo folder holds (whatever else was asked for)."""

VIDEO_FILES = ("*.mp4", "*.webm", "*.gif")
"""Names of the files in a 3D photo folder's ``video/`` (one per format photo3d writes)."""

RECORDED = ("still.png", "still_*.png", "video/*", *EXPORT_FILES)
"""Entries that are photo3d's only if ``config.json`` lists them (see the module doc)."""

_by_names = owned_by_names(LDI_FILE, PHOTO_FILES, inside={"video": VIDEO_FILES})
_MAX_CONFIG = 16 << 20  # a config.json photo3d wrote is a few kB


def recorded_files(folder: str | Path) -> set[str]:
    """The names (relative to ``folder``) of the videos and stills photo3d wrote there.

    An unreadable or damaged ``config.json`` records nothing (so nothing is replaced).

    Example:
        >>> import pathlib, tempfile
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> _ = (folder / "config.json").write_text('{"written": ["video/circle.mp4"]}')
        >>> sorted(recorded_files(folder))
        ['video/circle.mp4']
    """
    meta = _config(Path(folder)) or {}
    written = meta.get("written")
    if isinstance(written, list):
        return {w for w in written if isinstance(w, str)} | _landed(Path(folder), meta)
    save = meta.get("save")  # saved before "written": the videos it asked for
    videos = save.get("videos") if isinstance(save, dict) else None
    if not isinstance(videos, list):
        return set()
    return {name for v in videos if (name := _legacy_video(v))}


def owned_photo(folder: Path) -> list[str]:
    """The reasons ``folder`` is not a 3D photo folder photo3d may replace (empty: it may).

    Only :data:`PHOTO_FILES` at the top, only :data:`VIDEO_FILES` in ``video/``, and
    every video and still listed in ``config.json`` (:func:`recorded_files`).

    Example:
        >>> import pathlib, tempfile
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> for name in ("photo3d.npz", "config.json", "still.png"): (folder / name).touch()
        >>> owned_photo(folder)
        ['holds still.png, which photo3d did not write']
    """
    reasons = _by_names(folder)
    if reasons and reasons[0].startswith("holds "):
        return reasons
    mine = recorded_files(folder)
    foreign = [name for name in _recordable(folder) if name not in mine]
    if foreign:
        shown = ", ".join(foreign[:3]) + (", ..." if len(foreign) > 3 else "")
        reasons.insert(0, f"holds {shown}, which photo3d did not write")
    return reasons


def claim_files(folder: str | Path, names: Iterable[str]) -> None:
    """Check before rendering that photo3d may write ``names`` (relative to ``folder``),
    after removing the temporary files killed writers left in it
    (:func:`photo3d.files.temps.remove_orphans_in`).

    Raises:
        OutputError: one of them is a symbolic link, or exists and photo3d did not
            write it (one line naming it).

    Example:
        >>> import pathlib, tempfile
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> (folder / "still.png").write_bytes(b"mine")
        4
        >>> try:
        ...     claim_files(folder, ["still.png"])
        ... except OutputError as err:
        ...     print(str(err).split(" exists")[0].endswith("still.png"))
        True
    """
    folder = Path(folder)
    remove_orphans_in(folder)  # what killed writers left there (their writers are gone)
    mine = recorded_files(folder)
    targets = {name: refuse_symlink(folder / name) for name in names}  # links first
    for name, target in targets.items():
        if target.exists() and name not in mine:
            raise OutputError(f"{target} exists and photo3d did not write it; move it "
                              "away or choose another name (nothing was written)")


def record_files(folder: str | Path, names: Iterable[str]) -> None:
    """Add ``names`` to the files ``config.json`` lists as photo3d's.

    The read-modify-write holds a lock on ``folder``
    (:func:`photo3d.files.gate.locked`), so processes recording at once lose no
    entry; the file is replaced atomically. A folder without ``config.json`` gets
    one holding only the list; a damaged or foreign one is left as it is (nothing
    is recorded, so nothing is replaced later).

    Example:
        >>> import pathlib, tempfile
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> _ = (folder / "config.json").write_text("{}")
        >>> record_files(folder, ["still.png"]); sorted(recorded_files(folder))
        ['still.png']
    """
    names = list(names)

    def change(meta: dict) -> None:
        meta["written"] = sorted(recorded_files(folder) | set(names))
        pending = meta.get("pending")
        if isinstance(pending, dict):
            for name in names:
                pending.pop(name, None)
            if not pending:
                del meta["pending"]

    _update_config(Path(folder), change)


def record_pending(folder: str | Path, name: str, temporary: Path) -> None:
    """Note in ``config.json`` that the file ``temporary`` is about to be moved into
    place as ``name`` (relative to ``folder``): its device, inode, size and
    modification time, which the move keeps (the file is complete by then). Should
    the process be killed (SIGKILL) after the move and before :func:`record_files`,
    :func:`recorded_files` still counts ``name`` as photo3d's while that very file is
    there, and nothing else of that name.

    Example:
        >>> import pathlib, tempfile
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> _ = (folder / "config.json").write_text("{}")
        >>> tmp = folder / ".a.ply.0123abcd.tmp"; _ = tmp.write_bytes(b"ply")
        >>> record_pending(folder, "splats.ply", tmp); tmp.rename(folder / "splats.ply")
        PosixPath('...splats.ply')
        >>> sorted(recorded_files(folder))  # killed here: still photo3d's
        ['splats.ply']
    """
    key = _identity(os.stat(temporary, follow_symlinks=False))

    def change(meta: dict) -> None:
        pending = meta.get("pending")
        meta["pending"] = {**(pending if isinstance(pending, dict) else {}), name: key}
        meta.setdefault("written", sorted(recorded_files(folder)))

    _update_config(Path(folder), change)


def _update_config(folder: Path, change) -> None:
    """Apply ``change(meta)`` to ``folder``'s ``config.json`` and write it back, under
    the folder's lock (:func:`photo3d.files.gate.locked`: processes recording at once
    lose no entry); a missing one is created, a damaged or foreign one left alone."""
    path = refuse_symlink(folder / "config.json")
    with locked(folder):
        meta = _config(folder)
        if meta is None:
            if os.path.lexists(path):
                return
            meta = {}
        change(meta)
        write_json(path, meta)


def _landed(folder: Path, meta: dict) -> set[str]:
    """The names of ``meta``'s pending files (:func:`record_pending`) that are in
    place: the same device, inode, size and modification time as noted."""
    pending = meta.get("pending")
    if not isinstance(pending, dict):
        return set()
    found = set()
    for name, key in pending.items():
        if not (isinstance(name, str) and isinstance(key, list) and len(key) == 4
                and all(type(k) is int for k in key)) or name.startswith("/") or ".." in name:
            continue
        try:
            st = os.stat(folder / name, follow_symlinks=False)
        except (OSError, ValueError):
            continue
        if _identity(st) == key:
            found.add(name)
    return found


def _identity(st: os.stat_result) -> list[int]:
    return [st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns]


@contextlib.contextmanager
def recording(folder: str | Path) -> Iterator[None]:
    """Inside the block, each file this thread moves into place in ``folder`` (or its
    ``video/``) that ``config.json`` must list (:data:`RECORDED`) is recorded there
    (:func:`record_files`) in the same step as its move: a Ctrl-C or SIGTERM never
    leaves a file in place that the record does not list. Just before the move its
    inode is noted (:func:`record_pending`), so that even a SIGKILL between the move
    and the record leaves a file the next command counts as photo3d's.

    Example:
        >>> import pathlib, tempfile
        >>> from photo3d.files.atomic import write_bytes
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> with recording(folder):
        ...     _ = write_bytes(folder / "splats.ply", b"ply")
        >>> sorted(recorded_files(folder))
        ['splats.ply']
    """
    root = os.path.realpath(folder)

    def recorded_name(final: Path) -> str | None:
        parent = os.path.realpath(final.parent)
        name = final.name if parent == root else (
            f"video/{final.name}" if parent == os.path.join(root, "video") else None)
        if name is not None and any(fnmatch.fnmatchcase(name, p) for p in RECORDED):
            return name
        return None

    def before(temporary: Path, final: Path) -> None:
        if (name := recorded_name(final)) is not None:
            record_pending(folder, name, temporary)

    def record(final: Path) -> None:
        if (name := recorded_name(final)) is not None:
            record_files(folder, [name])

    with on_commit(record, before=before):
        yield


def _recordable(folder: Path) -> list[str]:
    """Entries of ``folder`` that must be listed in config.json to be photo3d's."""
    found = [p.name for p in sorted(folder.iterdir())
             if any(fnmatch.fnmatchcase(p.name, pattern) for pattern in RECORDED)]
    video = folder / "video"
    if video.is_dir() and not video.is_symlink():
        found += [f"video/{p.name}" for p in sorted(video.iterdir())]
    return [name for name in found if name != "video"]


def _config(folder: Path) -> dict | None:
    """``config.json`` of ``folder``; None if missing, a link, too large or damaged."""
    path = folder / "config.json"
    try:
        if path.is_symlink() or not path.is_file():
            return None
        meta = read_json(path, max_bytes=_MAX_CONFIG)
    except (OSError, InputError):
        return None
    return meta if isinstance(meta, dict) else None


def _legacy_video(spec) -> str | None:
    """``video/NAME.FORMAT`` of a recorded VideoSpec dict with a preset path."""
    if not isinstance(spec, dict):
        return None
    path, fmt, stereo = spec.get("path"), spec.get("format"), spec.get("stereo")
    if not (isinstance(path, str) and isinstance(fmt, str) and "/" not in path + fmt):
        return None
    stem = f"{path}_{stereo}" if isinstance(stereo, str) else path
    return f"video/{stem}.{fmt}"
