"""Output folders that never lose a user's files and are never left half-written.

A command that writes a folder calls :func:`stage_output` *before* its work: it
checks everything that can be checked early (the location, what is already there,
the name's length, that the file system accepts a new folder) and creates a hidden
temporary sibling ``.NAME.XXXXXXXX.tmp`` to write into. At the end
:meth:`Staging.commit` moves it into place in one atomic, checked rename; on any
error, Ctrl-C or termination signal :meth:`Staging.discard` removes it.

The rules (what photo3d promises, README "Inputs"):

* The output is never the current folder, one of its parents, or a folder that
  holds an input, with or without ``overwrite``.
* ``overwrite`` only replaces a folder photo3d wrote, recognised by its files (the
  caller's ``owned`` check); any other file in it makes the run refuse up front.
* A symbolic link as output is followed: the result is written into its target (a
  link to nothing is refused).
* Two runs writing the same output: the first to finish wins; the other fails with
  :class:`~photo3d.errors.OutputError` (the final rename never replaces a folder
  that appeared or changed meanwhile).
* Signals: run the work inside :func:`photo3d.files.signals.handle_signals` so that
  SIGTERM and SIGHUP, like Ctrl-C, unwind through the ``with`` block.
* New folders get the usual permissions (``0o777`` minus the umask).
* A temporary folder is locked (``flock``) by the process writing it for as long as
  it does; the kernel drops the lock when that process ends, even killed with
  SIGKILL. The next :func:`stage_output` of the same output removes the temporary
  folders nobody holds any more (:func:`photo3d.files.temps.remove_orphans`).

Example:
    >>> import pathlib, tempfile
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "result"
    >>> with stage_output(out) as staging:
    ...     _ = (staging.path / "a.txt").write_text("hi")
    ...     final = staging.commit()
    >>> sorted(p.name for p in final.iterdir()), sorted(p.name for p in final.parent.iterdir())
    (['a.txt'], ['result'])
"""

from __future__ import annotations

import atexit
import errno
import fnmatch
import os
import shutil
import stat
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path

from photo3d.errors import OutputError
from photo3d.files.atomic import Pending
from photo3d.files.gate import issue_folder, release_folder
from photo3d.files.rename import claim, identity, swap
from photo3d.files.temps import (
    WRITER_MARK,
    hold,
    release,
    remove_orphans,
    remove_orphans_in,
    temp_entries,
    temp_sibling,
)

PathLike = str | os.PathLike[str]

_LIVE: set[Path] = set()
"""Temporary folders not yet committed or discarded (removed at exit as a last resort)."""


def owned_by_names(required: str, allowed: Sequence[str], *,
                   inside: Mapping[str, Sequence[str]] | None = None
                   ) -> Callable[[Path], list[str]]:
    """An ``owned`` check: the folder holds ``required`` and only entries the tool writes.

    Args:
        required: a file name every folder the tool wrote holds.
        allowed: glob patterns of the top-level names the tool writes.
        inside: subfolder name -> glob patterns of the files the tool writes in it;
            such a subfolder must hold only matching files (no folders). Every other
            allowed entry must be a file (a folder with a file's name is not the
            tool's).

    Returns:
        ``owned(folder) -> list[str]``: the reasons the folder may not be replaced
        (empty when it may be); foreign entries are named relative to ``folder``.

    Example:
        >>> import pathlib, tempfile
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> _ = (folder / "notes.txt").write_text("mine")
        >>> owned_by_names("photo3d.npz", ["photo3d.npz", "*.ply"])(folder)
        ['holds notes.txt', 'has no photo3d.npz']
        >>> (folder / "notes.txt").unlink(); (folder / "video").mkdir()
        >>> _ = (folder / "video" / "clip.mov").write_text("mine")
        >>> owned_by_names("video", ["video"], inside={"video": ["*.mp4"]})(folder)
        ['holds video/clip.mov']
    """
    inside = dict(inside or {})

    def owned(folder: Path) -> list[str]:
        names = sorted(p.name for p in folder.iterdir())
        foreign = [n for n in names if _foreign(folder / n, allowed, inside)]
        for sub in sorted(set(inside) & set(names)):
            if (folder / sub).is_dir() and not (folder / sub).is_symlink():
                foreign += [f"{sub}/{p.name}" for p in sorted((folder / sub).iterdir())
                            if p.is_symlink() or not p.is_file()
                            or not any(fnmatch.fnmatchcase(p.name, a) for a in inside[sub])]
        reasons = [f"holds {', '.join(foreign[:3])}{', ...' if len(foreign) > 3 else ''}"]
        return (reasons if foreign else []) + ([] if required in names
                                               else [f"has no {required}"])

    return owned


def _foreign(entry: Path, allowed: Sequence[str], inside: Mapping[str, Sequence[str]]) -> bool:
    """True if the top-level ``entry`` is not one the tool writes (by name and kind)."""
    if not any(fnmatch.fnmatchcase(entry.name, a) for a in allowed):
        return True
    if entry.name in inside:
        return entry.is_symlink() or not entry.is_dir()
    return entry.is_dir() and not entry.is_symlink()


class Staging(Pending):
    """A hidden temporary folder that becomes ``final`` on :meth:`commit`.

    Use as a context manager: leaving the block without a commit (an error, Ctrl-C)
    discards the temporary folder.

    Attributes:
        path: the temporary folder to write into.
        final: the absolute output folder (symbolic links resolved).
        out: the output as the user gave it (for messages).
    """

    def __init__(self, path: Path, final: Path, out: Path, *, seen: tuple | None,
                 owned: Callable[[Path], list[str]] | None, made: list[Path],
                 overwrite: bool) -> None:
        self.path, self.final, self.out = path, final, out
        self._seen, self._owned, self._made = seen, owned, made
        self._overwrite = overwrite
        self._done = False

    def commit(self) -> Path:
        """Move the temporary folder into place atomically; return the output path.

        Raises:
            OutputError: the output appeared or changed since :func:`stage_output`
                (another run wrote it), or the rename failed. The temporary folder
                is removed and nothing already there is touched.
        """
        release(self.path)  # its writer mark out before it moves into place
        try:
            now = identity(self.final)
            if now != self._seen and not (self._seen is None and _is_empty_dir(self.final)):
                raise OutputError(f"output {self.out} changed while photo3d was working "
                                  "(another run?); this run's result was discarded")
            if now is None:
                claim(self.path, self.final, self.out)
            elif _is_empty_dir(self.final):
                os.rmdir(self.final)
                claim(self.path, self.final, self.out)
            else:
                foreign = self._owned(self.final) if self._owned else ["is not empty"]
                if not self._overwrite:
                    foreign = ["is not empty (use --overwrite)"]
                if foreign:
                    raise OutputError(f"output {self.out} changed meanwhile and "
                                      f"{' and '.join(foreign)}; nothing replaced")
                old = swap(self.path, self.final, self.out, expected=now)
                shutil.rmtree(old, ignore_errors=True)  # the replaced photo3d folder
        except OSError as err:
            raise OutputError(f"cannot move the result to {self.out}: "
                              f"{err.strerror or err}") from None
        self._done = True
        _LIVE.discard(self.path)
        release_folder(self.path)
        return self.final

    def discard(self) -> None:
        """Remove the temporary folder (and the parents :func:`stage_output` created)."""
        self._done = True
        shutil.rmtree(self.path, ignore_errors=True)
        _LIVE.discard(self.path)
        release(self.path)
        release_folder(self.path)
        for parent in reversed(self._made):
            try:
                parent.rmdir()
            except OSError:
                break


def stage_output(out: PathLike, *, overwrite: bool = False, inputs: Iterable[PathLike] = (),
                 owned: Callable[[Path], list[str]] | None = None,
                 need_bytes: int = 0) -> Staging:
    """Check where ``out`` will go and create its temporary folder, before any work.

    Args:
        out: the output folder the user asked for (may be a symbolic link to a folder).
        overwrite: replace an existing, non-empty folder if ``owned`` accepts it.
        inputs: files the run reads; the output may not be a folder holding one.
        owned: ``owned(folder) -> list[str]``, the reasons a folder is not one photo3d
            wrote (see :func:`owned_by_names`); None: never replace a non-empty folder.
        need_bytes: refuse if the file system has less free space than this.

    Returns:
        A :class:`Staging` whose ``path`` exists and is empty.

    Raises:
        OutputError: one line naming the problem: the output is (or holds) the
            current folder or an input, exists and is not a folder, is not empty
            (without ``overwrite``) or holds files photo3d did not write, is a
            dangling link, has a name too long, or its parent cannot be written
            (permissions, read-only or full file system).

    Example:
        >>> import os
        >>> try:
        ...     stage_output(".", overwrite=True)
        ... except OutputError as err:
        ...     print(err)
        output . is the current folder or one of its parents; choose a new folder
    """
    out = Path(out)
    try:
        return _stage(out, overwrite=overwrite, inputs=inputs, owned=owned,
                      need_bytes=need_bytes)
    except OSError as err:  # e.g. a name too long for the file system
        raise OutputError(f"cannot write {out}: {err.strerror or err}") from None


def _stage(out: Path, *, overwrite, inputs, owned, need_bytes) -> Staging:
    if out.is_symlink() and not out.exists():
        raise OutputError(f"output {out} is a symbolic link to {os.readlink(out)}, "
                          "which does not exist")
    final = Path(os.path.realpath(out))
    if final.parent == final:
        raise OutputError(f"output {out} is the root of the file system")
    cwd = Path(os.path.realpath(os.getcwd()))
    if final == cwd or final in cwd.parents:
        raise OutputError(f"output {out} is the current folder or one of its parents; "
                          "choose a new folder")
    for given in inputs:
        source = Path(os.path.realpath(given))
        if final == source or final in source.parents:
            raise OutputError(f"output {out} holds the input {given}; choose a new folder")
    seen = identity(final)
    if seen is not None:
        _check_existing(final, out, overwrite=overwrite, owned=owned)
    parent = final.parent
    made = _make_parents(parent, out)
    try:
        name_max = os.pathconf(parent, "PC_NAME_MAX")
    except (OSError, ValueError):
        name_max = 255
    if len(os.fsencode(final.name)) > name_max:
        remove_made_folders(made)
        raise OutputError(f"output name {final.name[:40]}... is {len(os.fsencode(final.name))} "
                          f"bytes long; this file system allows {name_max}")
    remove_orphans(final)  # what killed writers of this output left
    try:
        tmp = _make_temp(parent, final.name)
    except OSError as err:
        remove_made_folders(made)
        raise OutputError(f"cannot write in {parent}: {err.strerror or err}") from None
    free = shutil.disk_usage(parent).free if need_bytes else 0
    if free < need_bytes:
        shutil.rmtree(tmp, ignore_errors=True)
        _LIVE.discard(tmp)
        release(tmp)
        release_folder(tmp)
        remove_made_folders(made)
        raise OutputError(f"only {_mb(free)} free in {parent}; this output needs about "
                          f"{_mb(need_bytes)}")
    return Staging(tmp, final, out, seen=seen, owned=owned, made=made, overwrite=overwrite)


def _mb(size: int) -> str:
    return f"{size / 1e6:.1f} MB" if size < 1e9 else f"{size / 1e9:.1f} GB"


def _check_existing(final: Path, out: Path, *, overwrite: bool,
                    owned: Callable[[Path], list[str]] | None) -> None:
    if not final.is_dir():
        raise OutputError(f"output {out} exists and is not a folder")
    if _is_empty_dir(final):
        return
    if not overwrite:
        raise OutputError(f"output folder {out} exists and is not empty (use --overwrite)")
    remove_orphans_in(final)  # what killed writers left inside: not the user's files
    foreign = owned(final) if owned else ["is not empty"]
    if foreign:
        raise OutputError(f"--overwrite only replaces a folder photo3d wrote, but {out} "
                          f"{' and '.join(foreign)}: choose a new folder")


def _is_empty_dir(path: Path) -> bool:
    try:
        with os.scandir(path) as entries:
            return next(entries, None) is None
    except OSError:
        return False


def _make_parents(parent: Path, out: Path) -> list[Path]:
    """Create the missing parents of the output (outermost first); return them."""
    missing = []
    for p in [parent, *parent.parents]:
        if p.exists():
            break
        missing.append(p)
    made = []
    try:
        for p in reversed(missing):
            p.mkdir()
            made.append(p)
    except OSError as err:
        remove_made_folders(made)
        raise OutputError(f"cannot create the folder {p} for {out}: "
                          f"{err.strerror or err}") from None
    if not parent.is_dir():
        raise OutputError(f"cannot write {out}: {parent} is not a folder")
    return made


def remove_made_folders(made: list[Path]) -> None:
    """Remove the folders of ``made`` (as :func:`_make_parents` lists them, outermost
    first), innermost first, while they are empty: the first that is not (someone
    wrote into it) and every folder around it stay.

    Example:
        >>> import tempfile
        >>> root = Path(tempfile.mkdtemp())
        >>> made = [root / "a", root / "a" / "b"]
        >>> for folder in made: folder.mkdir()
        >>> remove_made_folders(made); (root / "a").exists()
        False
    """
    for p in reversed(made):
        try:
            p.rmdir()
        except OSError:
            return


def _make_temp(parent: Path, name: str) -> Path:
    """A new hidden folder beside the output, with the umask's permissions."""
    for _ in range(100):
        tmp = temp_sibling(parent / name)
        try:
            os.mkdir(tmp, 0o777)  # mkdir applies the umask (mkdtemp would force 0700)
        except FileExistsError:
            continue
        _LIVE.add(tmp)
        hold(tmp)
        issue_folder(tmp)
        return tmp
    raise OSError(errno.EEXIST, "no free temporary name")


def remove_leftovers(out: PathLike) -> list[Path]:
    """Remove the temporary folders a killed writer of ``out`` left beside it.

    Only folders named as :func:`stage_output` names them (``.NAME.XXXXXXXX.tmp``,
    eight hex digits) and holding its writer's mark (:data:`~photo3d.files.temps.WRITER_MARK`;
    a folder of that name without it is not photo3d's, or was being moved into place)
    are removed; call this only when no other process is writing ``out``. Returns
    what was removed.

    Example:
        >>> import pathlib, tempfile
        >>> out = pathlib.Path(tempfile.mkdtemp()) / "result"
        >>> staging = stage_output(out)  # its writer is "killed": never committed
        >>> [p == staging.path for p in remove_leftovers(out)], staging.path.exists()
        ([True], False)
    """
    removed = []
    for tmp in temp_entries(out, suffixed=False):
        if tmp.is_dir() and not tmp.is_symlink() and _marked(tmp):
            shutil.rmtree(tmp, ignore_errors=True)
            _LIVE.discard(tmp)
            release_folder(tmp)
            removed.append(tmp)
    return removed


def _marked(folder: Path) -> bool:
    """True if ``folder`` holds a writer's mark (a file, not a link): a folder
    :func:`_make_temp` made."""
    try:
        return stat.S_ISREG(os.lstat(folder / WRITER_MARK).st_mode)
    except OSError:
        return False


@atexit.register
def _remove_leftovers() -> None:
    for tmp in list(_LIVE):
        shutil.rmtree(tmp, ignore_errors=True)
