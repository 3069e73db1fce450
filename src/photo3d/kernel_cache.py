"""Compiled kernels shipped in the wheel: numba's cache built for a portable CPU.

numba keeps each compiled kernel in its on-disk cache: an index file per function
(``<module>.<function>-<line>.py311.nbi``) mapping keys to data files (``.nbc``, the
machine code). A key is the argument types, the *target* (triple, CPU name, CPU
features: ``codegen.magic_tuple()``) and hashes of the function's bytecode; the index
also holds the numba version and a hash of the source file's bytes. So a cache built
on another machine is found only by a process with the same CPU name and features,
which is never the case across machines.

The wheel ships caches built with ``NUMBA_CPU_NAME=generic`` (plain x86-64 code,
which runs on every x86-64 CPU), one set per Python minor version the build had,
in ``photo3d/_kernel_cache/`` with a :data:`MANIFEST` that lists every file and its
SHA-256. :func:`adopt` copies the functions that fit this process into the folder
numba's own cache locators give each source file (``NUMBA_CACHE_DIR``, else the
``__pycache__`` beside the source if it is writable, else the user's cache folder:
never a read-only ``site-packages``), with each key's target rewritten to this
machine's, so numba loads them instead of compiling. Nothing is adopted, and numba
compiles as before, when the shipped set does not fit: another numba or Python
version, another CPU family (triple), a CPU without the features a set needs, a
source file that differs from the one the cache was built from, or a shipped file
whose hash is not the manifest's (cut short, altered). ``PHOTO3D_SHIPPED_KERNELS=0``
turns it off (the kernels are then compiled for this CPU, as from a clone).

This module imports only the standard library at its top: ``setup.py`` loads it to
check, before the wheel is built, that the caches are current
(:func:`check_current`), without numba. The release build that makes the shipped
folder is :mod:`photo3d.kernel_build`.

Example:
    >>> adopt(Path("/nonexistent"))   # nothing shipped there: nothing adopted
    0
"""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import re
import sys
import threading
from pathlib import Path

SHIPPED = Path(__file__).with_name("_kernel_cache")
"""Where the wheel's caches are installed (absent in a source tree)."""
MANIFEST = "manifest.json"
"""The shipped folder's list of files, their hashes and what they were built for."""
FORMAT = 1
"""The manifest's format version (another one is not read)."""
OFF_ENV = "PHOTO3D_SHIPPED_KERNELS"
"""Set to ``0`` to never adopt the shipped caches, or to a CPU name of :data:`TARGETS`
to adopt only that set (if this CPU can run it: for measuring one set)."""
TARGETS = {"generic": (), "x86-64-v3": ("avx", "avx2", "bmi", "bmi2", "f16c", "fma",
                                         "lzcnt", "movbe")}
"""The portable CPU names a set may be built for, and the LLVM features a CPU must
have to run its code (none for ``generic``: any x86-64)."""

_ADOPTED: set[str] = set()  # shipped folders adopted in this process
_LOCK = threading.Lock()
_MARKER = ".photo3d-shipped.json"  # in a cache folder: what was adopted into it


def adopt(shipped: Path | None = None) -> int:
    """Copy the shipped caches that fit this process into numba's cache (once per
    process and shipped folder; later calls return 0 at once).

    Args:
        shipped: the folder with :data:`MANIFEST` (default :data:`SHIPPED`); the
            sources it was built from are looked up relative to its parent folder's
            parent (``photo3d/_kernel_cache`` -> the folder holding ``photo3d``).

    Returns:
        How many functions' caches were copied now (0: nothing shipped, nothing fits,
        all copied by an earlier run, or turned off by ``PHOTO3D_SHIPPED_KERNELS=0``;
        ``PHOTO3D_SHIPPED_KERNELS=generic`` takes only the ``generic`` set).

    Example:
        >>> adopt(Path("/nonexistent"))
        0
    """
    shipped = SHIPPED if shipped is None else Path(shipped)
    wanted = os.environ.get(OFF_ENV, "").strip()
    if wanted == "0":
        return 0
    with _LOCK:  # a second caller (another thread) waits until the files are in place
        if str(shipped) in _ADOPTED:
            return 0
        _ADOPTED.add(str(shipped))
        return _adopt(shipped, wanted)


def _adopt(shipped: Path, wanted: str) -> int:
    """:func:`adopt`'s work, once per process and shipped folder."""
    manifest = read_manifest(shipped)
    if manifest is None:
        return 0
    import llvmlite
    import numba

    if (manifest.get("numba"), manifest.get("llvmlite")) != (numba.__version__,
                                                             llvmlite.__version__):
        return 0  # numba reads only its own caches; LLVM its own version's bitcode
    host = host_target()
    if wanted in TARGETS:  # only that set
        manifest = {**manifest, "targets": [t for t in manifest.get("targets", [])
                                            if t.get("cpu") == wanted]}
    target = choose_target(manifest, host)
    if target is None:
        return 0
    tag = python_tag()
    root = shipped.parent.parent
    hashes = manifest["files"]
    count = 0
    for function in target["functions"]:
        if function["python"] == tag:
            count += _adopt_function(shipped, root, function, hashes, target, host)
    return count


def read_manifest(shipped: Path) -> dict | None:
    """The manifest in ``shipped``, or None if there is none, it cannot be read or it
    is of another :data:`FORMAT`.

    Example:
        >>> read_manifest(Path("/nonexistent")) is None
        True
    """
    try:
        manifest = json.loads((Path(shipped) / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        return None
    return manifest


def choose_target(manifest: dict, host: tuple[str, str, str]) -> dict | None:
    """The first of the manifest's sets this CPU can run: same target triple, and
    every feature the set's CPU name needs (:data:`TARGETS`) among the host's.

    Args:
        manifest: as :func:`read_manifest` gives it.
        host: this process's ``(triple, cpu name, features)`` (:func:`host_target`);
            ``features`` as LLVM writes them, ``"+avx2,-avx512f,..."``.

    Example:
        >>> m = {"triple": "x86_64-unknown-linux-gnu",
        ...      "targets": [{"cpu": "x86-64-v3"}, {"cpu": "generic"}]}
        >>> choose_target(m, ("x86_64-unknown-linux-gnu", "znver4", "+avx,+avx2"))
        {'cpu': 'generic'}
        >>> choose_target(m, ("aarch64-unknown-linux-gnu", "neoverse-n1", "")) is None
        True
    """
    triple, _, features = host
    if manifest.get("triple") != triple:
        return None
    have = {f[1:] for f in features.split(",") if f.startswith("+")}
    for target in manifest.get("targets", []):
        needs = TARGETS.get(target.get("cpu"))
        if needs is not None and set(needs) <= have:
            return target
    return None


def host_target() -> tuple[str, str, str]:
    """This process's numba target: ``(triple, cpu name, features)``, the part of
    every cache key that names the machine (numba's ``magic_tuple``).

    Example:
        >>> triple, cpu, features = host_target()
        >>> isinstance(cpu, str)
        True
    """
    from numba.core.registry import cpu_target

    return tuple(cpu_target.target_context.codegen().magic_tuple())


def python_tag() -> str:
    """The Python part of numba's cache file names (``py311``).

    Example:
        >>> python_tag() == f"py{sys.version_info[0]}{sys.version_info[1]}" + sys.abiflags
        True
    """
    return f"py{sys.version_info[0]}{sys.version_info[1]}{getattr(sys, 'abiflags', '')}"


def sha256(path: Path) -> str:
    """The SHA-256 of a file's bytes, in hex.

    Example:
        >>> sha256(Path(__file__)) == hashlib.sha256(Path(__file__).read_bytes()).hexdigest()
        True
    """
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def cache_folder(source: str) -> Path | None:
    """The folder numba caches ``source``'s functions in: the first of its cache
    locators that takes the file and can write there (``NUMBA_CACHE_DIR``, the
    ``__pycache__`` beside it, the user's cache folder); None if none can.

    Example:
        >>> cache_folder(__file__) is not None
        True
    """
    from numba.core import config
    from numba.core.caching import CacheImpl

    if config.CACHE_LOCATOR_CLASSES:  # the user chose the locators: leave it to numba
        return None
    for locator_class in CacheImpl._locator_classes:
        # the locators read only the function's first line number from it
        locator = locator_class.from_function(_probe, source)
        if locator is not None:
            return Path(locator.get_cache_path())
    return None


def _probe() -> None:
    """Stands in for a kernel when numba's locators are asked for a folder."""


def _adopt_function(shipped: Path, root: Path, function: dict, hashes: dict,
                    target: dict, host: tuple) -> int:
    """Copy one function's index and data files into its cache folder, keys rewritten
    for ``host``; 1 if copied, 0 if it did not fit or was there already."""
    source = os.path.join(str(root), *function["source"].split("/"))
    folder = cache_folder(source)
    if folder is None:
        return 0
    index_path = shipped / function["index"]
    index_name = index_path.name
    marker = _read_marker(folder)
    done = [hashes.get(function["index"]), list(host)]
    if marker.get(index_name) == done and (folder / index_name).exists():
        return 0
    try:
        blobs = {name: _verified(shipped, name, hashes) for name in
                 (function["index"], *function["data"])}
        version, stamp, overloads = parse_index(blobs[function["index"]])
        with open(source, "rb") as f:
            current = hashlib.sha256(f.read()).digest()
    except (OSError, ValueError):
        return 0
    import numba

    if version != numba.__version__ or stamp != current:
        return 0  # another numba, or the source differs from the one it was built from
    data = {Path(name).name: blob for name, blob in blobs.items() if name != function["index"]}
    ours = {}
    built_for = (target["triple"], target["cpu"], target["features"])
    for key, data_name in overloads.items():
        sig, magic, code = key
        if tuple(magic) == built_for and data_name in data:
            ours[(sig, tuple(host), code)] = data[data_name]
    if not ours:
        return 0
    existing = _existing_index(folder / index_name, stamp)
    taken = set(existing.values())
    base = index_name[: -len(".nbi")]
    number = 0
    for key, blob in ours.items():
        if key in existing:
            continue
        while True:
            number += 1
            name = f"{base}.{number}.nbc"
            if name not in taken:
                break
        taken.add(name)
        _write(folder / name, blob)
        existing[key] = name
    from numba.core.serialize import dumps

    _write(folder / index_name,
           pickle.dumps(version, protocol=-1) + dumps((stamp, existing)))
    marker[index_name] = done
    _write(folder / _MARKER, json.dumps(marker).encode())
    return 1


def _verified(shipped: Path, name: str, hashes: dict) -> bytes:
    """A shipped file's bytes; ValueError if its hash is not the manifest's."""
    blob = (shipped / name).read_bytes()
    if hashlib.sha256(blob).hexdigest() != hashes.get(name):
        raise ValueError(f"{name}: not the file the manifest lists")
    return blob


def parse_index(blob: bytes) -> tuple[str, bytes, dict]:
    """numba's index file: ``(numba version, source stamp, {key: data file name})``;
    ValueError if it cannot be read."""
    import io

    try:
        f = io.BytesIO(blob)
        version = pickle.load(f)
        stamp, overloads = pickle.loads(f.read())
    except Exception as exc:  # a damaged pickle raises almost anything
        raise ValueError(f"unreadable index: {exc!r}") from exc
    if not isinstance(overloads, dict):
        raise ValueError("unreadable index: no table of overloads")
    return version, stamp, overloads


def _existing_index(path: Path, stamp: bytes) -> dict:
    """The entries of an index numba already has in the cache folder, if it is for
    this numba and this source (numba itself ignores any other)."""
    import numba

    try:
        version, old_stamp, overloads = parse_index(path.read_bytes())
    except (OSError, ValueError):
        return {}
    return dict(overloads) if version == numba.__version__ and old_stamp == stamp else {}


def _read_marker(folder: Path) -> dict:
    """What earlier runs adopted into ``folder``: ``{index name: [shipped hash, host]}``."""
    try:
        marker = json.loads((folder / _MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return marker if isinstance(marker, dict) else {}


def _write(path: Path, blob: bytes) -> None:
    """Write ``blob`` to ``path`` whole or not at all (a temporary file renamed)."""
    tmp = path.with_name(f"{path.name}.tmp.{os.getpid()}")
    try:
        tmp.write_bytes(blob)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


# --- whether the shipped folder is current (setup.py, before the wheel is built) ---


def check_current(shipped: Path, package: Path) -> list[str]:
    """What makes the shipped caches unfit to be packed with ``package`` (the
    ``photo3d`` source folder): a source changed since they were built, a kernel
    file (``cache=True``) they do not cover, a file missing or not the one the
    manifest lists. Empty: current. Needs only the standard library.

    Example:
        >>> check_current(Path("/nonexistent"), Path(__file__).parent)
        ['/nonexistent: no manifest.json (build the caches: make kernels)']
    """
    shipped, package = Path(shipped), Path(package)
    manifest = read_manifest(shipped)
    if manifest is None:
        return [f"{shipped}: no {MANIFEST} (build the caches: make kernels)"]
    problems = []
    for source, digest in sorted(manifest["sources"].items()):
        path = package.parent / source
        if not path.exists():
            problems.append(f"{source}: gone since the caches were built")
        elif sha256(path) != digest:
            problems.append(f"{source}: changed since the caches were built")
    covered = set(manifest["sources"])
    for path in sorted(package.rglob("*.py")):
        rel = path.relative_to(package.parent).as_posix()
        if rel not in covered and rel not in UNSHIPPED and _CACHED_KERNEL.search(
                path.read_text(encoding="utf-8")):
            problems.append(f"{rel}: has cached kernels the caches do not cover")
    for name, digest in sorted(manifest["files"].items()):
        path = shipped / name
        if not path.exists() or sha256(path) != digest:
            problems.append(f"{name}: missing or not the file the manifest lists")
    return problems


_CACHED_KERNEL = re.compile(r"^\s*@(?:numba\.)?n?jit\([^)]*\bcache\s*=\s*True", re.M)
"""A numba decorator with ``cache=True`` (what makes a file a cached kernel file)."""
UNSHIPPED = frozenset({"photo3d/eval/warp.py", "photo3d/inpaint/edgepaths.py"})
"""Kernel files off the default make, render and export paths (evaluation; the
learned fill's edge paths): compiled on first use, not shipped."""
