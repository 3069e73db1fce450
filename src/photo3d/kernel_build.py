"""Building the compiled kernels the wheel ships (the release build, never a command).

``scripts/release/build_kernels.py`` runs photo3d's default paths with
``NUMBA_CPU_NAME`` set to a portable CPU and an empty ``NUMBA_CACHE_DIR``; then
:func:`collect` copies the cache files numba wrote for photo3d's sources into the
folder the wheel holds as ``photo3d/_kernel_cache``, one set per CPU name, and
:func:`write_manifest` lists every file, its SHA-256 and what the sets were built for.
What the files are, how a process adopts them and how ``setup.py`` checks they are
current: :mod:`photo3d.kernel_cache`.

Example:
    >>> import tempfile
    >>> target = {"cpu": "generic", "triple": "x86_64-unknown-linux-gnu",
    ...           "features": "", "functions": []}
    >>> write_manifest(Path(tempfile.mkdtemp()), [target], Path(__file__).parent)["files"]
    {}
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

from photo3d.kernel_cache import FORMAT, MANIFEST, parse_index, sha256

_CACHE_FILE = re.compile(r"^(?P<base>(?P<module>[^.]+)\..+\.(?P<python>py\d+\w*))"
                         r"(?:\.nbi|\.(?P<number>\d+)\.nbc)$")


def collect(raw: Path, shipped: Path, package: Path, *, cpu: str) -> dict:
    """Copy the cache files numba wrote into ``raw`` (a ``NUMBA_CACHE_DIR``) for the
    sources under ``package`` into ``shipped/<cpu>/``, and return the set's entry for
    the manifest (:func:`write_manifest`). Files of other sources are left out.

    Args:
        raw: the cache folder of a build run with ``NUMBA_CPU_NAME=cpu``.
        shipped: the folder the wheel will hold as ``photo3d/_kernel_cache``.
        package: the ``photo3d`` source folder those runs imported.
        cpu: the CPU name the caches were built for (a key of
            :data:`~photo3d.kernel_cache.TARGETS`).

    Returns:
        ``{"cpu", "triple", "features", "functions": [{"index", "data", "source",
        "python"}]}``, paths relative to ``shipped``, sources relative to
        ``package``'s parent.

    Example:
        >>> import tempfile
        >>> raw = Path(tempfile.mkdtemp())   # a cache with nothing of photo3d's
        >>> collect(raw, raw / "shipped", Path(__file__).parent, cpu="generic")
        {'cpu': 'generic', 'functions': []}
    """
    import shutil

    from numba.core.caching import _CacheLocator

    package = Path(package)
    folders = {}
    for folder in {package, *(p.parent for p in package.rglob("*.py"))}:
        sub = _CacheLocator.get_suitable_cache_subpath(os.path.join(str(folder), "x.py"))
        folders[sub] = folder
    entry: dict = {"cpu": cpu, "functions": []}
    for sub in sorted(p.name for p in Path(raw).iterdir() if p.name in folders):
        folder = folders[sub]
        rel = folder.relative_to(package.parent).as_posix()
        for index in sorted(Path(raw, sub).glob("*.nbi")):
            match = _CACHE_FILE.match(index.name)
            source = folder / f"{match['module']}.py" if match else None
            if source is None or not source.exists():
                continue
            _, stamp, overloads = parse_index(index.read_bytes())
            data = sorted(set(overloads.values()))
            for key in overloads:
                triple, name, features = key[1]
                if name != cpu:
                    raise ValueError(f"{index}: built for CPU {name!r}, not {cpu!r}")
                entry.update(triple=triple, features=features)
            dest = Path(shipped, cpu, rel)
            dest.mkdir(parents=True, exist_ok=True)
            for name in (index.name, *data):
                shutil.copyfile(index.parent / name, dest / name)
            entry["functions"].append({
                "index": f"{cpu}/{rel}/{index.name}",
                "data": [f"{cpu}/{rel}/{name}" for name in data],
                "source": f"{rel}/{source.name}", "python": match["python"]})
    return entry


def write_manifest(shipped: Path, targets: list[dict], package: Path) -> dict:
    """Write :data:`MANIFEST` into ``shipped``: numba's and llvmlite's versions, the
    target triple,
    the sets (most capable first, as :func:`~photo3d.kernel_cache.choose_target` tries them), every
    file's SHA-256 and every source's SHA-256; returns it.

    Example:
        >>> import tempfile
        >>> target = {"cpu": "generic", "triple": "x86_64-unknown-linux-gnu",
        ...           "features": "", "functions": []}
        >>> m = write_manifest(Path(tempfile.mkdtemp()), [target], Path(__file__).parent)
        >>> m["format"], m["targets"][0]["cpu"], m["files"]
        (1, 'generic', {})
    """
    import llvmlite
    import numba

    shipped = Path(shipped)
    files = {p.relative_to(shipped).as_posix(): sha256(p)
             for p in sorted(shipped.rglob("*")) if p.is_file() and p.name != MANIFEST}
    sources = sorted({f["source"] for t in targets for f in t["functions"]})
    triples = {t["triple"] for t in targets if "triple" in t}
    if len(triples) != 1:
        raise ValueError(f"the sets are for {sorted(triples)}: need exactly one triple")
    manifest = {"format": FORMAT, "numba": numba.__version__,
                "llvmlite": llvmlite.__version__, "triple": triples.pop(),
                "pythons": sorted({f["python"] for t in targets for f in t["functions"]}),
                "targets": targets, "files": files,
                "sources": {s: sha256(Path(package).parent / s) for s in sources}}
    (shipped / MANIFEST).write_text(json.dumps(manifest, indent=1), encoding="utf-8")
    return manifest
