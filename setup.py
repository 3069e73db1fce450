"""photo3d's build: its dependencies, and the compiled kernels a release wheel ships.

Everything else is in pyproject.toml. ``PHOTO3D_KERNEL_CACHE=DIR`` (``make wheel`` sets
it) puts DIR, built by ``scripts/release/build_kernels.py``, into the wheel as
``photo3d/_kernel_cache`` and pins numba and llvmlite to the versions it was built
with: numba reads a cache only from its own version. The build fails when DIR is not
current (a kernel's source changed since it was built: it would never load, and
every user's first run would compile). Without the variable (the sdist, an editable
install, a wheel pip builds from the sdist) nothing is shipped and numba keeps its
range: photo3d then compiles its kernels on first use, as from a clone.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
CACHE_ENV = "PHOTO3D_KERNEL_CACHE"

DEPENDENCIES = [
    "numpy>=1.26",
    "scipy>=1.11",
    "pillow>=10.0",
    "numba>=0.59",
    "tqdm>=4.60",
    "av>=14",
]


def _kernel_cache_module():
    """photo3d/kernel_cache.py loaded alone (standard library only: no numba here)."""
    spec = importlib.util.spec_from_file_location(
        "_photo3d_kernel_cache", ROOT / "src" / "photo3d" / "kernel_cache.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _shipped() -> tuple[Path | None, dict | None]:
    """The caches to ship and their manifest (None, None: none); SystemExit if they
    are not current."""
    folder = os.environ.get(CACHE_ENV)
    if not folder:
        return None, None
    folder = Path(folder).resolve()
    cache = _kernel_cache_module()
    problems = cache.check_current(folder, ROOT / "src" / "photo3d")
    if problems:
        raise SystemExit(f"{CACHE_ENV}={folder} is not current, rebuild it "
                         "(make kernels):\n  " + "\n  ".join(problems))
    return folder, json.loads((folder / cache.MANIFEST).read_text(encoding="utf-8"))


SHIPPED, MANIFEST = _shipped()


class BuildPy(build_py):
    """build_py that adds the shipped caches (not in an editable install)."""

    def run(self) -> None:
        super().run()
        if SHIPPED is not None and not getattr(self, "editable_mode", False):
            dest = Path(self.build_lib) / "photo3d" / "_kernel_cache"
            shutil.rmtree(dest, ignore_errors=True)
            shutil.copytree(SHIPPED, dest)


def dependencies() -> list[str]:
    """DEPENDENCIES, numba (and its llvmlite) pinned to the shipped caches' versions."""
    if MANIFEST is None:
        return DEPENDENCIES
    pinned = [d for d in DEPENDENCIES if not d.startswith("numba")]
    return [*pinned, f"numba=={MANIFEST['numba']}", f"llvmlite=={MANIFEST['llvmlite']}"]


setup(install_requires=dependencies(), cmdclass={"build_py": BuildPy})
