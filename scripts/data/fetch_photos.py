"""Fetch real, freely licensed photographs for training and held-out evaluation.

Offline sources only (issue 28): Debian packages that ship photographs (desktop
wallpapers, educational games, demo albums), downloaded with ``apt-get download``
into a cache and unpacked with ``dpkg-deb -x``, plus scikit-image's sample photos.
Every file kept was looked at and is listed below in :data:`SOURCES` with a one-word
subject; everything else is dropped with a one-word reason (art, render, logo, ...).
A photo is kept only if the package's ``copyright`` file (DEP-5) gives it a licence
that allows training and redistributing weights (:func:`licence_ok`).

Output (default ``data/photos`` in the repository, which git must ignore):

* ``train/`` and ``heldout/``: ``<package>--<stem>.png``, RGB, shorter side at most
  768 px (aspect kept, never enlarged);
* ``SOURCES.tsv``: name, split, package, original path, licence, width, height,
  sha256 (of the PNG), version, licence_from; ``DROPPED.tsv``: what was left out, why.

The split: a photo is held out when ``sha256(name) mod 10 == 0`` (about 10 %,
independent of which packages are present), and *every* photo of scikit-image,
matplotlib and scikit-learn is held out: they are photo3d's evaluation photos.
Near-duplicates (the same photo at several sizes, or in two packages) are kept once,
the largest: a 64-bit difference hash of the prepared photo, confirmed by its 16x16
thumbnail.

Usage: nice .venv/bin/python scripts/data/fetch_photos.py [--out DIR] [--update] [--list]
"""

from __future__ import annotations

import argparse
import fnmatch
import hashlib
import importlib.metadata
import importlib.util
import io
import json
import os
import re
import shutil
import struct
import subprocess
import sys
import tarfile
import tempfile
import time
import zlib
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import numpy as np
from PIL import Image

from photo3d.errors import InputError, OutputError, Photo3DError
from photo3d.io.images import read_image

sys.path.insert(0, str(Path(__file__).parent))
from _photo_sources import (  # noqa: E402  (the reviewed lists: _photo_sources.py)
    ART_ONLY,
    SOURCES,
    Source,
)

REPO = Path(__file__).resolve().parents[2]
MAX_SHORT_SIDE = 768
"""Prepared photos have their shorter side at most this many pixels."""
MIN_SHORT_SIDE = 300
"""Candidates whose shorter side is smaller are dropped as ``small``."""
HELDOUT_MODULUS = 10
"""A photo is held out when ``sha256(name) % HELDOUT_MODULUS == 0``."""
DUPLICATE_BITS = 6
"""Two photos are one when their difference hashes differ in at most this many of 64
bits, their aspect ratios by at most 5 % and their 16x16 thumbnails by at most
:data:`DUPLICATE_MEAN` (mean absolute difference, 0..1): the hash alone confuses dark,
smooth photos (a misty lake and a night sky)."""
DUPLICATE_MEAN = 0.03
MARKER = ".photo3d-photos"
"""File that marks a folder this script made (and may rebuild with ``--update``)."""
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".webp", ".tga", ".bmp", ".gif")


# --- licences ---------------------------------------------------------------------------

_FREE = re.compile(
    r"CC0(-1\.0)?|CC-BY(-SA)?-[1-4]\.[05]|[AL]?GPL-[123](\.[01])?\+?|public-domain|PD|Expat|MIT"
    r"|BSD-[234]-clause|Apache-2\.0|MPL-2\.0|GFDL(-NIV)?(-1\.[123]\+?)?|Zlib|ISC|free-art",
    re.IGNORECASE)


def licence_ok(expression: str) -> bool:
    """Whether a DEP-5 licence expression allows training and sharing the weights.

    Free licences only: CC0, CC-BY(-SA), GPL/LGPL/AGPL, GFDL, public domain, BSD, MIT,
    Apache, MPL. ``A or B`` needs one side free, ``A and B`` both; an exception
    (``GPL-2+ with Font exception``) does not matter; NC and ND licences are not free.

    >>> [licence_ok(x) for x in ("GPL-2+", "CC-BY-NC-SA-4.0", "LGPL-2.1 or custom", "")]
    [True, False, True, False]
    """
    expression = re.sub(r"\s+with\s+.*$", "", expression.strip(), flags=re.IGNORECASE)
    return any(all(_FREE.fullmatch(term.strip()) for term in re.split(r"\s+and\s+", side))
               for side in re.split(r"\s+or\s+", expression, flags=re.IGNORECASE) if side)


@dataclass(frozen=True)
class Stanza:
    """A ``Files:`` paragraph of a DEP-5 copyright file."""

    patterns: tuple[str, ...]
    licence: str
    """The short name (first line of ``License:``); ``""`` when only a text is given."""


def parse_copyright(text: str) -> list[Stanza] | None:
    """The ``Files:`` stanzas of a machine-readable (DEP-5) copyright file, in order.

    Returns ``None`` for a free-form file (no ``Format:`` field in the first paragraph).
    """
    paragraphs = [p for p in re.split(r"\n[ \t]*\n", text.strip("\n")) if p.strip()]
    if not paragraphs or not re.search(r"^Format:", paragraphs[0], re.MULTILINE | re.IGNORECASE):
        return None
    stanzas = []
    for paragraph in paragraphs[1:]:
        fields: dict[str, str] = {}
        key = None
        for line in paragraph.splitlines():
            if line.startswith("#"):
                continue
            if line[:1].isspace() and key:
                fields[key] += "\n" + line.strip()
            elif ":" in line:
                key, value = line.split(":", 1)
                key = key.strip().lower()
                fields[key] = value.strip()
        if "files" in fields and "license" in fields:
            stanzas.append(Stanza(tuple(fields["files"].split()),
                                  fields["license"].split("\n", 1)[0].strip()))
    return stanzas


def _pattern_score(pattern: str, path: str) -> int | None:
    """How many trailing components of ``path`` the DEP-5 ``pattern`` matches (or None).

    Paths in the copyright file are the source tree's and installed paths differ in
    their leading folders, so a pattern matches the end of the path: all of it when
    its file name has a wildcard, else any of its tails. A raster extension matches
    any other (GCompris ships its ``.jpg`` sources as ``.webp``).
    """
    if pattern == "*":
        return 0
    image = r"\.(?:jpe?g|png|webp|tga|bmp|gif)$"
    pattern, path = re.sub(image, ".<img>", pattern, flags=re.I), re.sub(image, ".<img>", path,
                                                                             flags=re.I)
    pat, parts = pattern.split("/"), path.split("/")

    def matches(glob: str, text: str) -> bool:
        regex = "".join(".*" if c == "*" else "." if c == "?" else re.escape(c) for c in glob)
        return re.fullmatch(regex, text) is not None

    if "*" in pat[-1] or "?" in pat[-1]:
        hit = any(matches(pattern, "/".join(parts[k:])) for k in range(len(parts)))
        return len(pat) if hit else None
    for start in range(len(pat)):
        tail = pat[start:]
        if len(tail) <= len(parts) and matches("/".join(tail), "/".join(parts[-len(tail):])):
            return len(tail)
    return None


def licence_of(stanzas: list[Stanza], path: str) -> str | None:
    """The licence DEP-5 stanzas give ``path``: the most specific match, the last on a tie.

    >>> s = parse_copyright("Format: x\\n\\nFiles: *\\nLicense: GPL-2+\\n\\n"
    ...                     "Files: data/themes/bg.jpg\\nLicense: CC-BY-3.0\\n")
    >>> licence_of(s, "usr/share/sddm/themes/bg.jpg"), licence_of(s, "usr/share/x.png")
    ('CC-BY-3.0', 'GPL-2+')
    """
    best: tuple[int, int] | None = None
    for index, stanza in enumerate(stanzas):
        if all(p.startswith("debian/") for p in stanza.patterns):
            continue
        scores = [s for p in stanza.patterns if (s := _pattern_score(p, path)) is not None]
        if scores and (best is None or (max(scores), index) >= best):
            best = (max(scores), index)
    return None if best is None else stanzas[best[1]].licence


# --- fetching and unpacking -------------------------------------------------------------

def _run(command: list[str], **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run(command, capture_output=True, text=True, check=False, **kwargs)


def _last_line(text: str) -> str:
    lines = [line for line in text.strip().splitlines() if line.strip()]
    return lines[-1] if lines else "no output"


@dataclass
class Apt:
    """``apt-get download`` into ``cache``, one package at a time; never installs."""

    cache: Path
    offline: bool = False
    say: Callable[[str], None] = print
    _updated: bool = False
    _warned: bool = False

    def show(self, package: str) -> dict[str, str] | None:
        """``apt-cache show`` fields of the candidate version, or None if apt has none."""
        if self.offline or not shutil.which("apt-cache"):
            return None
        result = _run(["apt-cache", "show", "--no-all-versions", package])
        if (result.returncode or not result.stdout.strip()) and not self._updated \
                and not any(Path("/var/lib/apt/lists").glob("*Packages*")):
            self._updated = True  # apt has never read its sources: do it once
            self.say("apt has no package lists yet: running apt-get update")
            update = _run(["apt-get", "update"])
            if update.returncode:
                self.say(f"apt-get update failed: {_last_line(update.stderr)}")
            result = _run(["apt-cache", "show", "--no-all-versions", package])
        if result.returncode or not result.stdout.strip():
            return None
        return dict(re.findall(r"^([\w-]+): ?(.*)$", result.stdout, re.MULTILINE))

    def deb(self, package: str) -> tuple[Path | None, str]:
        """The package's .deb in the cache (downloading it if needed) and its version."""
        self.cache.mkdir(parents=True, exist_ok=True)
        info = self.show(package)
        cached = sorted(self.cache.glob(f"{package}_*.deb"), key=lambda p: p.stat().st_mtime)
        if info is None:
            if not self.offline and not shutil.which("apt-get") and not self._warned:
                self._warned = True
                self.say(f"apt-get not found: using the .deb files already in {self.cache}")
            if cached:
                return cached[-1], cached[-1].name.split("_")[1].replace("%3a", ":")
            if self.offline or not shutil.which("apt-get"):
                return None, "no .deb in the cache"
            return None, "not in apt's sources"
        version = info.get("Version", "?")
        name = f"{package}_{version.replace(':', '%3a')}_{info.get('Architecture', 'all')}.deb"
        path, expected = self.cache / name, info.get("SHA256")
        if path.is_file() and expected in (None, _sha256(path)):
            return path, version
        result = _run(["apt-get", "download", package], cwd=self.cache)
        if result.returncode or not path.is_file():
            self.offline = True  # one line, then only what the cache holds
            self.say(f"apt-get download {package} failed ({_last_line(result.stderr)}): "
                     f"using only the .deb files already in {self.cache}")
            return (cached[-1], cached[-1].name.split("_")[1].replace("%3a", ":")) if cached \
                else (None, "download failed")
        return path, version


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def unpack_deb(deb: Path, trees: Path) -> Path:
    """Unpack ``deb`` once into ``trees/<deb stem>/`` (``dpkg-deb -x``, or ar + tar)."""
    tree = trees / deb.stem
    if (tree / ".complete").is_file():
        return tree
    trees.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".unpack-", dir=trees))
    try:
        if shutil.which("dpkg-deb"):
            result = _run(["dpkg-deb", "-x", str(deb), str(staging)])
            if result.returncode:
                raise InputError(f"dpkg-deb -x {deb.name} failed: {_last_line(result.stderr)}")
        else:
            _unpack_ar(deb, staging)
        (staging / ".complete").write_text(deb.name)
        shutil.rmtree(tree, ignore_errors=True)
        staging.rename(tree)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return tree


def _unpack_ar(deb: Path, dest: Path) -> None:
    """Python fallback for ``dpkg-deb -x``: the ``data.tar.*`` member of the ar archive."""
    blob = deb.read_bytes()
    if not blob.startswith(b"!<arch>\n"):
        raise InputError(f"{deb.name} is not a Debian package (no ar header)")
    offset = 8
    while offset + 60 <= len(blob):
        name, size = blob[offset:offset + 16].strip(), int(blob[offset + 48:offset + 58])
        data = blob[offset + 60:offset + 60 + size]
        if name.rstrip(b"/").startswith(b"data.tar"):
            try:
                with tarfile.open(fileobj=io.BytesIO(data), mode="r:*") as tar:
                    tar.extractall(dest, filter="data")
            except tarfile.ReadError as err:
                raise InputError(f"cannot read {name.decode()} of {deb.name} without "
                                 f"dpkg-deb ({err})") from err
            return
        offset += 60 + size + size % 2
    raise InputError(f"{deb.name} has no data.tar member")


def rcc_images(blob: bytes) -> list[tuple[str, bytes]]:
    """``(path, bytes)`` of the images in a Qt binary resource file (``.rcc``).

    Format: magic ``qres``, version, then offsets of the tree (14 bytes a node, 22
    from version 2), the data (size-prefixed; zlib when flag 1) and the names
    (length, hash, UTF-16BE). zstd entries (flag 4) are skipped.
    """
    if blob[:4] != b"qres":
        raise InputError("not a Qt resource file (no 'qres' magic)")
    version, tree, data, names = struct.unpack(">4I", blob[4:20])
    node_size = 14 if version == 1 else 22
    found: list[tuple[str, bytes]] = []

    def name_at(offset: int) -> str:
        (length,) = struct.unpack(">H", blob[names + offset:names + offset + 2])
        return blob[names + offset + 6:names + offset + 6 + 2 * length].decode("utf-16-be")

    stack = [(0, "")]
    while stack:
        index, prefix = stack.pop()
        base = tree + index * node_size
        name_offset, flags = struct.unpack(">IH", blob[base:base + 6])
        name = name_at(name_offset) if index else ""
        if name in (".", "..") or "/" in name:
            continue
        if flags & 2:
            count, first = struct.unpack(">II", blob[base + 6:base + 14])
            stack.extend((child, f"{prefix}{name}/" if index else "")
                         for child in range(first, first + count))
        elif name.lower().endswith(IMAGE_SUFFIXES) and not flags & 4:
            (offset,) = struct.unpack(">I", blob[base + 10:base + 14])
            (size,) = struct.unpack(">I", blob[data + offset:data + offset + 4])
            payload = blob[data + offset + 4:data + offset + 4 + size]
            found.append((prefix + name, zlib.decompress(payload[4:]) if flags & 1 else payload))
    return found


def _unpack_rccs(tree: Path, pattern: str) -> None:
    """Unpack the images of each ``.rcc`` under ``tree`` to ``tree/.rcc/<file>/...``."""
    for rcc in sorted(tree.glob(pattern)):
        dest = tree / ".rcc" / rcc.name
        if (dest / ".complete").is_file() or not _plain_file(tree, rcc):
            continue
        for inner, payload in rcc_images(rcc.read_bytes()):
            target = dest / inner
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(payload)
        dest.mkdir(parents=True, exist_ok=True)
        (dest / ".complete").write_text(rcc.name)


def _plain_file(root: Path, path: Path) -> bool:
    """A regular file reached from ``root`` through no symlink."""
    node = path
    while node != root and node != node.parent:
        if node.is_symlink():
            return False
        node = node.parent
    return path.is_file()


# --- choosing and preparing photos ------------------------------------------------------

@dataclass(frozen=True)
class Candidate:
    """A file of a package that passed review, licence and size."""

    name: str
    """``<package>--<stem>``: the stable name, without ``.png``."""
    path: Path
    original: str
    """Its path inside the package (``file.rcc:inner/path`` for Qt resources)."""
    licence: str
    licence_from: str
    pixels: int
    turn: int = 0
    """Clockwise degrees to turn the photo upright (:attr:`Source.turns`)."""


def choose(source: Source, root: Path, *, copyright_text: str | None = None
           ) -> tuple[list[Candidate], list[tuple[str, str]]]:
    """The photos of an unpacked package, and ``(original path, reason)`` of the rest.

    Args:
        source: what to look for and the review lists.
        root: the unpacked package (or the installed Python package).
        copyright_text: its copyright file (default: ``usr/share/doc/<package>/copyright``).
    """
    if copyright_text is None and source.python is None:
        doc = root / "usr/share/doc" / source.package / "copyright"
        copyright_text = doc.read_text(errors="replace") if _plain_file(root, doc) else ""
    stanzas = parse_copyright(copyright_text) if copyright_text else None
    if source.rcc:
        _unpack_rccs(root, source.rcc)
    files = sorted({p for pattern in source.globs for p in root.glob(pattern)
                    if p.suffix.lower() in IMAGE_SUFFIXES and not p.is_dir()})
    kept: dict[str, Candidate] = {}
    dropped: list[tuple[str, str]] = []
    sizes: dict[Path, tuple[int, int]] = {}
    for path in files:
        rel = PurePosixPath(path.relative_to(root).as_posix())
        original = _original(rel)
        if not _plain_file(root, path):
            dropped.append((original, "symlink"))
            continue
        try:
            with Image.open(path) as im:
                sizes[path] = im.size
        except (OSError, Image.DecompressionBombError):
            dropped.append((original, "unreadable"))
    if source.largest_only:
        by_folder: dict[Path, Path] = {}
        for path, (w, h) in sizes.items():
            best = by_folder.get(path.parent)
            if best is None or w * h > sizes[best][0] * sizes[best][1]:
                by_folder[path.parent] = path
        for path in set(sizes) - set(by_folder.values()):
            dropped.append((_original(PurePosixPath(path.relative_to(root).as_posix())),
                            "smaller-copy"))
        sizes = {p: sizes[p] for p in by_folder.values()}
    for path in sorted(sizes):
        rel = PurePosixPath(path.relative_to(root).as_posix())
        original, stem = _original(rel), _safe(source.stem(rel))
        if min(sizes[path]) < MIN_SHORT_SIDE:
            dropped.append((original, "small"))
        elif stem not in source.keep:
            dropped.append((original, _reason(source, stem) or "unreviewed"))
        elif stem in kept:
            dropped.append((original, "name-clash"))
        else:
            licence, where = source.licences.get(stem, (None, ""))
            if licence is None:
                licence, where = _package_licence(source, stanzas, copyright_text, original)
            if licence and (licence_ok(licence) or source.heldout):
                kept[stem] = Candidate(f"{_safe(source.package)}--{stem}", path, original,
                                       licence, where, sizes[path][0] * sizes[path][1],
                                       source.turns.get(stem, 0))
            else:
                dropped.append((original, "licence"))
    return list(kept.values()), sorted(dropped)


def _original(rel: PurePosixPath) -> str:
    if rel.parts[0] == ".rcc":  # .rcc/<file>/<inner>: point at the resource file
        return f"{rel.parts[1]}:{PurePosixPath(*rel.parts[2:])}"
    return str(rel)


def _inner(original: str) -> str:
    return original.split(":", 1)[-1]


def _reason(source: Source, stem: str) -> str | None:
    return next((why for pattern, why in source.drop.items() if fnmatch.fnmatchcase(stem, pattern)),
                None)


def _package_licence(source: Source, stanzas: list[Stanza] | None, text: str | None,
                     original: str) -> tuple[str | None, str]:
    if stanzas is not None:
        return licence_of(stanzas, _inner(original)), "debian/copyright"
    if source.freeform and text and source.freeform[1] in " ".join(text.split()):
        return source.freeform[0], "debian/copyright (free-form)"
    return None, ""


def _safe(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._+-]+", "_", text)


def prepare(candidate: Candidate, folder: Path) -> tuple[int, int, str, int, np.ndarray]:
    """Write the candidate as ``folder/<name>.png``: RGB, shorter side <= 768 px.

    Returns:
        ``(width, height, sha256 of the PNG, 64-bit difference hash, thumbnail)``, the
        thumbnail ``(16, 16, 3) float32`` in [0, 1].
    """
    pixels = np.round(read_image(candidate.path) * 255).astype(np.uint8)  # upright, over white
    image = Image.fromarray(pixels).rotate(-candidate.turn, expand=True)
    scale = MAX_SHORT_SIDE / min(image.size)
    if scale < 1:
        size = (max(1, round(image.width * scale)), max(1, round(image.height * scale)))
        image = image.resize(size, Image.Resampling.LANCZOS, reducing_gap=3.0)
    target = folder / f"{candidate.name}.png"
    image.save(target, format="PNG", compress_level=6)
    thumb = np.asarray(image.resize((16, 16), Image.Resampling.BOX), np.float32) / 255
    return image.width, image.height, _sha256(target), difference_hash(image), thumb


def difference_hash(image: Image.Image) -> int:
    """64-bit dHash: is each pixel of a 9x8 grey thumbnail brighter than its right one."""
    grey = np.asarray(image.convert("L").resize((9, 8), Image.Resampling.BOX), np.int16)
    bits = (grey[:, 1:] > grey[:, :-1]).ravel()
    return int("".join("1" if b else "0" for b in bits), 2)


def is_heldout(name: str) -> bool:
    """The split rule: held out when ``sha256(name) % 10 == 0`` (about one photo in ten).

    >>> is_heldout("kphotoalbum--jesper"), is_heldout("kphotoalbum--snow")
    (True, False)
    """
    return int(hashlib.sha256(name.encode()).hexdigest(), 16) % HELDOUT_MODULUS == 0


# --- the output folder ------------------------------------------------------------------

def check_out(out: Path, *, update: bool) -> None:
    """Refuse an output folder that is a symlink, a file, someone else's or ours w/o update."""
    if out.is_symlink():
        raise OutputError(f"{out} is a symlink; give the real folder")
    if out.exists() and not out.is_dir():
        raise OutputError(f"{out} exists and is not a folder")
    if out.is_dir() and any(out.iterdir()):
        if not (out / MARKER).is_file():
            raise OutputError(f"{out} is not empty and was not made by fetch_photos.py "
                              f"(no {MARKER}); choose another --out")
        if not update:
            raise OutputError(f"{out} already holds photos from an earlier run; "
                              "pass --update to rebuild it")


@dataclass
class Row:
    """One prepared photo (a line of ``SOURCES.tsv``)."""

    candidate: Candidate
    package: str
    version: str
    split: str
    width: int
    height: int
    sha256: str
    dhash: int
    thumb: np.ndarray


def drop_duplicates(rows: list[Row]) -> tuple[list[Row], list[tuple[Row, Row]]]:
    """Keep one photo of each group of near-identical ones: a held-out one if any, else
    the largest original; returns the kept rows and ``(dropped, kept instead)`` pairs."""
    parent = list(range(len(rows)))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i in range(len(rows)):
        for j in range(i + 1, len(rows)):
            if _same_photo(rows[i], rows[j]):
                parent[find(i)] = find(j)
    groups: dict[int, list[Row]] = {}
    for i, row in enumerate(rows):
        groups.setdefault(find(i), []).append(row)
    kept, gone = [], []
    for group in groups.values():
        best = max(group, key=lambda r: (r.split == "heldout", r.candidate.pixels,
                                         r.candidate.name))
        kept.append(best)
        gone.extend((row, best) for row in group if row is not best)
    return sorted(kept, key=lambda r: r.candidate.name), gone


def _same_photo(a: Row, b: Row) -> bool:
    return ((a.dhash ^ b.dhash).bit_count() <= DUPLICATE_BITS
            and abs(np.log(a.width * b.height / (a.height * b.width))) <= 0.05
            and float(np.abs(a.thumb - b.thumb).mean()) <= DUPLICATE_MEAN)


def write_tables(folder: Path, rows: list[Row], dropped: list[tuple[str, str, str]]) -> None:
    """``SOURCES.tsv``, ``DROPPED.tsv`` and the marker file."""
    head = "name\tsplit\tpackage\toriginal_path\tlicence\twidth\theight\tsha256\tversion\t" \
           "licence_from\n"
    lines = [f"{r.candidate.name}.png\t{r.split}\t{r.package}\t{r.candidate.original}\t"
             f"{r.candidate.licence}\t{r.width}\t{r.height}\t{r.sha256}\t{r.version}\t"
             f"{r.candidate.licence_from}\n" for r in rows]
    (folder / "SOURCES.tsv").write_text(head + "".join(lines))
    (folder / "DROPPED.tsv").write_text("package\toriginal_path\treason\n" + "".join(
        f"{p}\t{o}\t{why}\n" for p, o, why in sorted(dropped)))
    (folder / MARKER).write_text(json.dumps({"made_by": "scripts/data/fetch_photos.py",
                                             "format": 1}) + "\n")


# --- the command ------------------------------------------------------------------------

def source_root(source: Source, apt: Apt, trees: Path) -> tuple[Path | None, str]:
    """The unpacked package (or installed Python package) and its version or why not."""
    if source.python:
        spec = importlib.util.find_spec(source.python)
        if spec is None or not spec.submodule_search_locations:
            return None, f"{source.python} is not installed"
        return Path(spec.submodule_search_locations[0]), importlib.metadata.version(source.package)
    deb, version = apt.deb(source.package)
    return (unpack_deb(deb, trees), version) if deb else (None, version)


def build(out: Path, sources: tuple[Source, ...], apt: Apt, trees: Path, *, update: bool,
          say: Callable[[str], None] = print) -> list[Row]:
    """Fetch, review and prepare every source's photos into ``out`` (see module doc)."""
    check_out(out, update=update)
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}-", dir=out.parent))
    try:
        for split in ("train", "heldout"):
            (staging / split).mkdir()
        rows, dropped = [], []
        for index, source in enumerate(sources, 1):
            start = time.monotonic()
            root, version = source_root(source, apt, trees)
            if root is None:
                say(f"[{index}/{len(sources)}] {source.package}: skipped ({version})")
                continue
            kept, gone = choose(source, root)
            dropped += [(source.package, original, why) for original, why in gone]
            for candidate in kept:
                split = "heldout" if source.heldout or is_heldout(candidate.name) else "train"
                try:
                    w, h, digest, dhash, thumb = prepare(candidate, staging / split)
                except InputError as err:
                    dropped.append((source.package, candidate.original, "unreadable"))
                    say(f"  {candidate.original}: {err}")
                    continue
                rows.append(Row(candidate, source.package, version, split, w, h, digest, dhash,
                                thumb))
            reasons = ", ".join(f"{n} {why}"
                                for why, n in Counter(r for _, r in gone).most_common())
            say(f"[{index}/{len(sources)}] {source.package} {version}: {len(kept)} photos "
                f"({time.monotonic() - start:.1f} s); left out {len(gone)}"
                + (f": {reasons}" if reasons else ""))
        rows, duplicates = drop_duplicates(rows)
        for row, instead in duplicates:
            (staging / row.split / f"{row.candidate.name}.png").unlink()
            dropped.append((row.package, row.candidate.original,
                            f"duplicate of {instead.candidate.name}"))
        write_tables(staging, rows, dropped)
        if out.exists():
            old = out.with_name(f".{out.name}-old-{os.getpid()}")
            out.rename(old)
            staging.rename(out)
            shutil.rmtree(old)
        else:
            staging.rename(out)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return rows


def summary(rows: list[Row], out: Path, seconds: float) -> str:
    """The table printed at the end: photos per package, split and licences."""
    table = [f"{'package':30} {'train':>5} {'held':>5}  licences"]
    for package in dict.fromkeys(r.package for r in rows):
        mine = [r for r in rows if r.package == package]
        licences = ", ".join(f"{lic} {n}" for lic, n in
                             Counter(r.candidate.licence for r in mine).most_common())
        table.append(f"{package:30} {sum(r.split == 'train' for r in mine):5} "
                     f"{sum(r.split == 'heldout' for r in mine):5}  {licences}")
    train = sum(r.split == "train" for r in rows)
    size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    table.append(f"{'total':30} {train:5} {len(rows) - train:5}  "
                 f"{size / 2**20:.0f} MiB in {out}, {seconds:.0f} s")
    return "\n".join(table)


def list_sources(sources: tuple[Source, ...], apt: Apt) -> str:
    """What a run would fetch: package, version, download size, photos reviewed."""
    lines = []
    for source in sources:
        if source.python:
            spec = importlib.util.find_spec(source.python)
            state = "installed" if spec else "not installed"
        else:
            info = apt.show(source.package)
            cached = any(apt.cache.glob(f"{source.package}_*.deb"))
            state = "not in apt's sources" if info is None else (
                f"{info.get('Version')}, {int(info.get('Size', 0)) / 2**20:.1f} MiB"
                + (", cached" if cached else ""))
        lines.append(f"{source.package:30} {len(source.keep):4} photos  {state}"
                     + ("  (all held out)" if source.heldout else ""))
    lines.append("examined, no photographs: " + ", ".join(f"{p} ({w})"
                                                          for p, w in ART_ONLY.items()))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=REPO / "data" / "photos",
                        help="output folder (default: data/photos in the repository)")
    parser.add_argument("--cache", type=Path, default=Path(
        os.environ.get("PHOTO3D_CACHE", Path.home() / ".cache" / "photo3d")) / "debs",
        help="where .deb files are kept and unpacked (default ~/.cache/photo3d/debs)")
    parser.add_argument("--update", action="store_true", help="rebuild an earlier output")
    parser.add_argument("--list", action="store_true", help="print what would be fetched")
    parser.add_argument("--offline", action="store_true",
                        help="never call apt: use the .deb files already in the cache")
    parser.add_argument("--only", help="comma-separated packages (default: all)")
    args = parser.parse_args(argv)
    sources = SOURCES
    if args.only:
        wanted = set(args.only.split(","))
        sources = tuple(s for s in SOURCES if s.package in wanted)
        if unknown := wanted - {s.package for s in sources}:
            print(f"fetch_photos: unknown package(s): {', '.join(sorted(unknown))}",
                  file=sys.stderr)
            return 2
    apt = Apt(args.cache, offline=args.offline)
    if args.list:
        print(list_sources(sources, apt))
        return 0
    start = time.monotonic()
    try:
        rows = build(args.out, sources, apt, args.cache / "trees", update=args.update)
    except Photo3DError as err:
        print(f"fetch_photos: {err}", file=sys.stderr)
        return 2
    print(summary(rows, args.out, time.monotonic() - start))
    return 0


if __name__ == "__main__":
    sys.exit(main())
