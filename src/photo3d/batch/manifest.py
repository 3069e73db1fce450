"""The batch manifest ``OUT/batch.jsonl`` and what counts as a finished photo.

One JSON object per line and per photo: ``name``, ``status`` (``ok``, ``failed``,
``skipped``: finished in an earlier run), ``error`` (the one-line message, or
null), ``seconds`` (spent in this run), ``output`` (the photo's folder),
``depth`` (where its depth came from), ``warnings`` and ``worker`` (``host:pid``).
While a batch runs, each result is appended and flushed as soon as it is known (a
crash loses nothing already done); at the end, or when interrupted, the file is
rewritten atomically (:mod:`photo3d.files.atomic`) with one line per photo, the
newest result of each.

File names are bytes on POSIX: a name that is not UTF-8 (``caf\\xe9.jpg`` from an
old Latin-1 disk) is written with its undecodable bytes as ``\\xNN`` escapes
(:func:`json_text`), so the manifest stays valid UTF-8 JSON. The manifest is read
leniently (:func:`read_records`): a line that is not a well-formed record is left
out and reported, and its photo is made again. But a manifest photo3d did not write
is never rewritten: a line that is neither a record (a JSON object with a ``name``
and only the keys above, well-formed or not) nor one cut short by a crash (the start
of a line photo3d writes, ``{"name": ``) makes the batch refuse in one line, before
any work (:func:`check_manifest`).
"""

from __future__ import annotations

import contextlib
import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path

from photo3d.errors import InputError, OutputError
from photo3d.files.atomic import refuse_symlink, write_text
from photo3d.files.gate import check_target
from photo3d.io.bounded import loads_json, read_bytes

MANIFEST = "batch.jsonl"
STATUSES = ("ok", "failed", "skipped")
RECORD_KEYS = ("name", "status", "error", "seconds", "output", "depth", "warnings", "worker")
"""The keys of a manifest record, in the order photo3d writes them."""
_LINK_HINT = "remove it, or choose another output folder"
_MAX_MANIFEST = 1 << 30  # a manifest line is about 200 bytes: 5 million photos
_HEAD = '{"name": '  # how every line photo3d writes starts (PhotoResult.to_json)


def json_text(text: str) -> str:
    """``text`` with ``\\`` doubled and the undecodable bytes of a file name as
    ``\\xNN`` escapes, so two different names never give the same text.

    Names from the file system hold such bytes as lone surrogates
    (:func:`os.fsdecode`), which UTF-8 cannot encode; a literal backslash is doubled,
    so ``caf\\xe9.jpg`` (those seven characters) and a name with the Latin-1 byte 0xE9
    stay apart. Every other string is returned unchanged.

    Example:
        >>> json_text(os.fsdecode(b"caf\\xe9")), json_text("café"), json_text("caf\\\\xe9")
        ('caf\\\\xe9', 'café', 'caf\\\\\\\\xe9')
    """
    if "\\" not in text:
        try:
            text.encode("utf-8")
            return text
        except UnicodeEncodeError:
            pass
    try:
        raw = os.fsencode(text).replace(b"\\", b"\\\\")
    except UnicodeEncodeError:
        raw = text.replace("\\", "\\\\").encode("utf-8", "backslashreplace")
    return raw.decode("utf-8", "backslashreplace")


@dataclass(frozen=True)
class PhotoResult:
    """What became of one photo.

    Attributes:
        name: the photo's name in the batch (its output folder under OUT).
        status: ``"ok"``, ``"failed"`` or ``"skipped"``.
        error: the one-line error message of a failed photo, else None.
        seconds: wall time spent on it in this run.
        output: its output folder.
        depth: where its depth came from (one line), when known.
        warnings: one-line warnings (doubtful depth, ...).
        worker: ``host:pid`` of the process that made it (None when skipped).
    """

    name: str
    status: str
    error: str | None
    seconds: float
    output: str
    depth: str | None = None
    warnings: tuple[str, ...] = field(default=())
    worker: str | None = None

    def to_json(self) -> str:
        """One manifest line (no newline); strings go through :func:`json_text`.

        Example:
            >>> PhotoResult("a", "ok", None, 1.234567, "out/a").to_json()
            '{"name": "a", "status": "ok", "error": null, "seconds": 1.235, "output": "out/a", "depth": null, "warnings": [], "worker": null}'
        """  # noqa: E501
        record = asdict(self)
        record["seconds"] = round(self.seconds, 3)
        record["warnings"] = [json_text(w) for w in self.warnings]
        for key, value in record.items():
            if isinstance(value, str):
                record[key] = json_text(value)
        return json.dumps(record, ensure_ascii=False)


def record_problem(record: object) -> str | None:
    """Why ``record`` (one parsed manifest line) is not a well-formed record, or None.

    Example:
        >>> record_problem({"name": "a", "status": "ok", "error": None, "seconds": 1,
        ...                 "output": "o/a", "depth": None, "warnings": None, "worker": None})
        "'warnings' is null, not a list of strings"
    """
    if not isinstance(record, dict):
        return f"a JSON {type(record).__name__}, not an object"
    checks = (("name", str, False), ("status", str, False), ("error", str, True),
              ("seconds", (int, float), False), ("output", str, False),
              ("depth", str, True), ("worker", str, True))
    for key, kind, nullable in checks:
        value = record.get(key)
        if key not in record:
            return f"no {key!r}"
        if not (isinstance(value, kind) and not isinstance(value, bool)
                or nullable and value is None):
            return f"{key!r} is {json.dumps(value)[:40]}, not {_describe(kind, nullable)}"
    if record["status"] not in STATUSES:
        return f"'status' is {json.dumps(record['status'])[:40]}, not one of {', '.join(STATUSES)}"
    warnings = record.get("warnings")
    if not isinstance(warnings, list) or not all(isinstance(w, str) for w in warnings):
        return f"'warnings' is {json.dumps(warnings)[:40]}, not a list of strings"
    return None


def _describe(kind, nullable: bool) -> str:
    name = "a string" if kind is str else "a number"
    return name + (" or null" if nullable else "")


@dataclass(frozen=True)
class ManifestRecords:
    """What a manifest holds (see :func:`read_records`).

    Attributes:
        records: the newest well-formed record of each photo, by (JSON) name.
        bad: names whose newest record is not well-formed (to make again).
        problems: one line per line left out (``line 3: not JSON``).
        foreign: one line per line photo3d did not write (``line 1: a JSON list``):
            if there is any, the file is not a photo3d manifest.
    """

    records: dict[str, dict]
    bad: frozenset[str] = frozenset()
    problems: tuple[str, ...] = ()
    foreign: tuple[str, ...] = ()


def foreign_line(line: str, record: object) -> str | None:
    """Why a manifest ``line`` (parsed as ``record``, or None if it is not JSON) is not
    one photo3d wrote, or None if it may be: a record, even damaged (a JSON object with
    a string ``name`` and only :data:`RECORD_KEYS`), or a line cut short by a crash
    (not JSON, starting like every line photo3d writes).

    Example:
        >>> [foreign_line(t, None) for t in ('{"name": "a", "sta', '{"na', 'my notes')]
        [None, None, 'not JSON, nor the start of a record']
        >>> foreign_line('{"id": 3}', {"id": 3})
        "a JSON object with the key 'id', not a record"
    """
    if record is None:
        head = line.strip()
        if head.startswith(_HEAD) or (head and _HEAD.startswith(head)):
            return None
        return "not JSON, nor the start of a record"
    if not isinstance(record, dict):
        return f"a JSON {type(record).__name__}, not a record"
    extra = sorted(set(record) - set(RECORD_KEYS))
    if extra:
        return f"a JSON object with the key {extra[0][:40]!r}, not a record"
    if not isinstance(record.get("name"), str):
        return "a JSON object without a name, not a record"
    return None


def read_records(path: str | Path) -> ManifestRecords:
    """Read a manifest leniently: bad lines are left out and described.

    A line that is not JSON (cut short by a crash, edited by hand) or not a
    well-formed record (:func:`record_problem`) is a problem; if it names a photo,
    that photo is in ``bad`` unless a later good line replaces it. A line photo3d
    did not write (:func:`foreign_line`) is also listed in ``foreign``.

    Example:
        >>> import tempfile
        >>> p = Path(tempfile.mkdtemp()) / "batch.jsonl"
        >>> good = PhotoResult("a", "ok", None, 1.0, "o/a").to_json()
        >>> _ = p.write_text(good + '\\n{"name": "b", "status": "ok"}\\n{"na\\n')
        >>> m = read_records(p)
        >>> sorted(m.records), sorted(m.bad), m.problems
        (['a'], ['b'], ("line 2: no 'error'", 'line 3: not JSON'))
    """
    path = Path(path)
    records: dict[str, dict] = {}
    bad: set[str] = set()
    problems: list[str] = []
    foreign: list[str] = []
    if not path.is_file() or path.is_symlink():
        return ManifestRecords(records)
    try:
        text = read_bytes(path, max_bytes=_MAX_MANIFEST).decode("utf-8", errors="replace")
    except InputError as err:
        raise OutputError(f"{err}".replace("cannot read", "cannot read the manifest", 1)
                          ) from None
    for number, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        try:
            record = loads_json(line, what=f"line {number}")
        except InputError:
            record = None
        why = foreign_line(line, record)
        if why is not None:
            foreign.append(f"line {number}: {why}")
        if record is None:
            problems.append(f"line {number}: not JSON")
            continue
        problem = record_problem(record)
        name = record.get("name") if isinstance(record, dict) else None
        if problem is None:
            records[name] = record
            bad.discard(name)
        else:
            problems.append(f"line {number}: {problem}")
            if isinstance(name, str):
                records.pop(name, None)
                bad.add(name)
    return ManifestRecords(records, frozenset(bad), tuple(problems), tuple(foreign))


def check_manifest(path: str | Path) -> ManifestRecords:
    """Read the manifest ``path`` (:func:`read_records`) and refuse one photo3d did not
    write: a symbolic link, or a file holding a line photo3d does not write.

    Raises:
        OutputError: one line naming the file and its first foreign line; nothing is
            written.

    Example:
        >>> import tempfile
        >>> p = Path(tempfile.mkdtemp()) / "batch.jsonl"
        >>> _ = p.write_text('{"id": 1}\\n')
        >>> try:
        ...     check_manifest(p)
        ... except OutputError as err:
        ...     print(str(err).split(": ", 1)[1])
        line 1 is a JSON object with the key 'id', not a record: photo3d did not write this file; move it away or choose another output folder (nothing was written)
    """  # noqa: E501
    path = Path(path)
    refuse_symlink(path, hint=_LINK_HINT)
    check_target(path)  # a FIFO, socket or device is not photo3d's manifest
    found = read_records(path)
    if found.foreign:
        where, _, why = found.foreign[0].partition(": ")
        raise OutputError(f"{path}: {where} is {why}: photo3d did not write this file; move "
                          "it away or choose another output folder (nothing was written)")
    return found


def read_manifest(path: str | Path) -> dict[str, dict]:
    """The newest well-formed record of each photo in a manifest (``{}`` if there is none).

    Lines that are not well-formed records (a line cut short by a crash) are
    ignored (:func:`read_records` says which).

    Example:
        >>> import tempfile
        >>> p = Path(tempfile.mkdtemp()) / "batch.jsonl"
        >>> lines = [PhotoResult("a", "failed", "bad", 0.0, "o/a").to_json(),
        ...          PhotoResult("a", "ok", None, 1.0, "o/a").to_json(), '{"na']
        >>> _ = p.write_text("\\n".join(lines))
        >>> read_manifest(p)["a"]["status"]
        'ok'
    """
    return read_records(path).records


class ManifestWriter:
    """Appends results to the manifest as they come, and compacts it at the end.

    Use as a context manager; :meth:`add` after each photo. On exit (also after
    an error or Ctrl-C) the manifest is rewritten with one line per photo: the
    well-formed records of earlier runs, updated with this run's.

    A manifest this writer created and never wrote to is removed on exit (a batch
    that stopped before its first photo leaves no empty manifest behind).

    Attributes:
        previous: the earlier runs' records (:class:`ManifestRecords`).

    Raises:
        OutputError: the manifest is a symbolic link or not photo3d's
            (:func:`check_manifest`), or cannot be opened, appended to (full disk) or
            rewritten.

    Example:
        >>> import tempfile
        >>> p = Path(tempfile.mkdtemp()) / "batch.jsonl"
        >>> _ = p.write_text(PhotoResult("b", "failed", "x", 0.0, "o/b").to_json() + "\\n"
        ...                  + PhotoResult("a", "ok", None, 0.0, "o/a").to_json() + "\\n")
        >>> with ManifestWriter(p) as manifest:
        ...     manifest.add(PhotoResult("b", "ok", None, 1.0, "out/b"))
        >>> [(r["name"], r["status"]) for r in map(json.loads, p.read_text().splitlines())]
        [('a', 'ok'), ('b', 'ok')]
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.previous = check_manifest(self.path)
        self.current: dict[str, dict] = {}
        self._file = None
        self._created = False

    def __enter__(self) -> ManifestWriter:
        flags = os.O_RDWR | os.O_APPEND | os.O_NOFOLLOW | os.O_CLOEXEC
        try:
            try:
                fd = os.open(self.path, flags | os.O_CREAT | os.O_EXCL, 0o666)
                self._created = True
            except FileExistsError:
                fd = os.open(self.path, flags)
            self._file = open(fd, "a", encoding="utf-8")  # noqa: SIM115
            size = os.fstat(fd).st_size
            if size and os.pread(fd, 1, size - 1) != b"\n":
                self._file.write("\n")  # a line cut short by a crash stays a line of its own
        except OSError as err:
            self._abandon()
            raise OutputError(f"cannot write the manifest {self.path}: "
                              f"{err.strerror or err}") from None
        return self

    def _abandon(self) -> None:
        """Close the file; remove it if this writer created it and wrote nothing."""
        try:
            if self._file is not None:
                self._file.close()
        except OSError:
            pass
        if self._created and not self.current:
            with contextlib.suppress(OSError):
                if os.lstat(self.path).st_size == 0:
                    os.unlink(self.path)

    def add(self, result: PhotoResult) -> None:
        """Record one result now (appended and flushed to disk).

        Raises:
            OutputError: the line cannot be written (full disk, ...).
        """
        line = result.to_json()
        self.current[json.loads(line)["name"]] = json.loads(line)
        try:
            self._file.write(line + "\n")
            self._file.flush()
            os.fsync(self._file.fileno())
        except OSError as err:
            raise OutputError(f"cannot write the manifest {self.path}: "
                              f"{err.strerror or err}") from None

    def __exit__(self, exc_type, exc, tb) -> None:
        self._abandon()  # the buffered tail, if it could not be written, is rewritten below
        if self._created and not self.current:
            return
        merged = {**self.previous.records, **self.current}
        text = "".join(json.dumps(merged[name], ensure_ascii=False) + "\n"
                       for name in sorted(merged))
        try:
            refuse_symlink(self.path, hint=_LINK_HINT)
            write_text(self.path, text)
        except (OSError, OutputError) as err:
            if exc is None:  # else the error already on its way says what went wrong
                if isinstance(err, OutputError):
                    raise
                raise OutputError(f"cannot write the manifest {self.path}: "
                                  f"{err.strerror or err}") from None
