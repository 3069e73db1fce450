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
out and reported, and its photo is made again.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path

from photo3d.errors import OutputError
from photo3d.files.atomic import write_text

MANIFEST = "batch.jsonl"
STATUSES = ("ok", "failed", "skipped")


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
    """

    records: dict[str, dict]
    bad: frozenset[str] = frozenset()
    problems: tuple[str, ...] = ()


def read_records(path: str | Path) -> ManifestRecords:
    """Read a manifest leniently: bad lines are left out and described.

    A line that is not JSON (cut short by a crash, edited by hand) or not a
    well-formed record (:func:`record_problem`) is a problem; if it names a photo,
    that photo is in ``bad`` unless a later good line replaces it.

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
    if not path.is_file() or path.is_symlink():
        return ManifestRecords(records)
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as err:
        raise OutputError(f"cannot read the manifest {path}: {err.strerror or err}") from None
    for number, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
        except ValueError:
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
    return ManifestRecords(records, frozenset(bad), tuple(problems))


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


def refuse_symlink(path: Path) -> None:
    """Refuse a manifest that is a symbolic link (it would be written through it).

    Raises:
        OutputError: ``path`` is a symbolic link.
    """
    if os.path.islink(path):
        raise OutputError(f"the manifest {path} is a symbolic link; photo3d batch does not "
                          "write through links (remove it, or choose another output folder)")


class ManifestWriter:
    """Appends results to the manifest as they come, and compacts it at the end.

    Use as a context manager; :meth:`add` after each photo. On exit (also after
    an error or Ctrl-C) the manifest is rewritten with one line per photo: the
    well-formed records of earlier runs, updated with this run's.

    Attributes:
        previous: the earlier runs' records (:class:`ManifestRecords`).

    Raises:
        OutputError: the manifest is a symbolic link, or cannot be opened, appended
            to (full disk) or rewritten.

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
        refuse_symlink(self.path)
        self.previous = read_records(self.path)
        self.current: dict[str, dict] = {}
        self._file = None

    def __enter__(self) -> ManifestWriter:
        try:
            fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW,
                         0o666)
            self._file = open(fd, "a", encoding="utf-8")  # noqa: SIM115
        except OSError as err:
            raise OutputError(f"cannot write the manifest {self.path}: "
                              f"{err.strerror or err}") from None
        return self

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
        try:
            self._file.close()
        except OSError:
            pass  # the buffered tail is rewritten just below
        merged = {**self.previous.records, **self.current}
        text = "".join(json.dumps(merged[name], ensure_ascii=False) + "\n"
                       for name in sorted(merged))
        try:
            refuse_symlink(self.path)
            write_text(self.path, text)
        except (OSError, OutputError) as err:
            if exc is None:  # else the error already on its way says what went wrong
                if isinstance(err, OutputError):
                    raise
                raise OutputError(f"cannot write the manifest {self.path}: "
                                  f"{err.strerror or err}") from None
