"""The batch manifest ``OUT/batch.jsonl`` and what counts as a finished photo.

One JSON object per line and per photo: ``name``, ``status`` (``ok``, ``failed``,
``skipped``: finished in an earlier run), ``error`` (the one-line message, or
null), ``seconds`` (spent in this run), ``output`` (the photo's folder),
``depth`` (where its depth came from), ``warnings`` and ``worker`` (``host:pid``).
While a batch runs, each result is appended and flushed as soon as it is known (a
crash loses nothing already done); at the end, or when interrupted, the file is
rewritten atomically (:mod:`photo3d.files.atomic`) with one line per photo, the
newest result of each.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path

from photo3d.errors import OutputError
from photo3d.files.atomic import write_text

MANIFEST = "batch.jsonl"


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
        """One manifest line (no newline).

        Example:
            >>> PhotoResult("a", "ok", None, 1.234567, "out/a").to_json()
            '{"name": "a", "status": "ok", "error": null, "seconds": 1.235, "output": "out/a", "depth": null, "warnings": [], "worker": null}'
        """  # noqa: E501
        record = asdict(self)
        record["seconds"] = round(self.seconds, 3)
        record["warnings"] = list(self.warnings)
        return json.dumps(record, ensure_ascii=False)


def read_manifest(path: str | Path) -> dict[str, dict]:
    """The newest record of each photo in a manifest (``{}`` if there is none).

    Lines that are not JSON objects with a name (a line cut short by a crash) are
    ignored.

    Example:
        >>> import tempfile
        >>> p = Path(tempfile.mkdtemp()) / "batch.jsonl"
        >>> lines = ['{"name": "a", "status": "failed"}', '{"name": "a", "status": "ok"}', '{"na']
        >>> _ = p.write_text("\\n".join(lines))
        >>> read_manifest(p)["a"]["status"]
        'ok'
    """
    path = Path(path)
    records: dict[str, dict] = {}
    if not path.is_file():
        return records
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        try:
            record = json.loads(line)
        except ValueError:
            continue
        if isinstance(record, dict) and isinstance(record.get("name"), str):
            records[record["name"]] = record
    return records


class ManifestWriter:
    """Appends results to the manifest as they come, and compacts it at the end.

    Use as a context manager; :meth:`add` after each photo. On exit (also after
    an error or Ctrl-C) the manifest is rewritten with one line per photo: the
    records of earlier runs, updated with this run's.

    Raises:
        OutputError: the manifest cannot be opened or rewritten.

    Example:
        >>> import tempfile
        >>> p = Path(tempfile.mkdtemp()) / "batch.jsonl"
        >>> _ = p.write_text('{"name": "b", "status": "failed"}\\n{"name": "a", "status": "ok"}\\n')
        >>> with ManifestWriter(p) as manifest:
        ...     manifest.add(PhotoResult("b", "ok", None, 1.0, "out/b"))
        >>> [(r["name"], r["status"]) for r in map(json.loads, p.read_text().splitlines())]
        [('a', 'ok'), ('b', 'ok')]
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.previous = read_manifest(self.path)
        self.current: dict[str, dict] = {}
        self._file = None

    def __enter__(self) -> ManifestWriter:
        try:
            self._file = open(self.path, "a", encoding="utf-8")  # noqa: SIM115
        except OSError as err:
            raise OutputError(f"cannot write the manifest {self.path}: "
                              f"{err.strerror or err}") from None
        return self

    def add(self, result: PhotoResult) -> None:
        """Record one result now (appended and flushed to disk)."""
        self.current[result.name] = json.loads(result.to_json())
        self._file.write(result.to_json() + "\n")
        self._file.flush()
        os.fsync(self._file.fileno())

    def __exit__(self, *exc) -> None:
        self._file.close()
        merged = {**self.previous, **self.current}
        write_text(self.path, "".join(json.dumps(merged[name], ensure_ascii=False) + "\n"
                                      for name in sorted(merged)))
