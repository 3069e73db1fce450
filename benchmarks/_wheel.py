"""The wheel path of the first-run benchmarks: photo3d installed from its release wheel
(``make wheel``) into a fresh virtual environment, no source tree, run by a user who
cannot write into that environment (``site-packages`` read-only, as a system install)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NOBODY = 65534
BASE_PYTHON = "/usr/bin/python3.11" if Path("/usr/bin/python3.11").exists() else sys.executable
"""The interpreter the fresh environment is made from: the system's, which the
unprivileged user can read (a pyenv Python under /root is out of its reach)."""


def find_wheel(wheel: Path | None) -> Path:
    """``wheel``, or the newest ``dist/photo3d-*.whl`` (SystemExit if there is none)."""
    if wheel is not None:
        return wheel.resolve()
    found = sorted((ROOT / "dist").glob("photo3d-*.whl"), key=lambda p: p.stat().st_mtime)
    if not found:
        raise SystemExit("no dist/photo3d-*.whl: run `make wheel` first (or give --wheel)")
    return found[-1]


def fresh_venv(wheel: Path, folder: Path, extras: str = "sample") -> str:
    """A new virtual environment in ``folder`` with ``wheel[extras]`` installed from the
    package index (nothing from this tree); returns its Python."""
    subprocess.run([BASE_PYTHON, "-m", "venv", str(folder)], check=True)
    python = str(folder / "bin" / "python")
    subprocess.run([python, "-m", "pip", "install", "--quiet", "--disable-pip-version-check",
                    f"{wheel}[{extras}]"], check=True)
    return python


def installed_package(python: str) -> Path:
    """The ``photo3d`` folder ``python`` imports (checked: not this tree's ``src``)."""
    out = subprocess.run([python, "-c", "import photo3d; print(photo3d.__file__)"],
                         capture_output=True, text=True, check=True, cwd="/",
                         env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"})
    folder = Path(out.stdout.strip()).parent
    if ROOT in folder.parents:
        raise SystemExit(f"photo3d imported from the tree ({folder}), not the wheel")
    return folder


def cache_files(package: Path) -> set[str]:
    """numba cache files (``.nbi``, ``.nbc``) inside the installed package, outside
    the shipped folder: the ones a run wrote there."""
    return {str(p.relative_to(package)) for p in package.rglob("*.nb[ic]")
            if "_kernel_cache" not in p.parts}


def as_user(package: Path) -> list[str]:
    """A command prefix that runs the rest as a user who cannot write into
    ``package``: ``setpriv`` to ``nobody`` when this process is root (root writes
    through any mode bits), else nothing, with the package's folders made read-only."""
    if os.geteuid() == 0 and shutil.which("setpriv"):
        return ["setpriv", f"--reuid={NOBODY}", f"--regid={NOBODY}", "--clear-groups", "--"]
    for path in [package, *package.rglob("*")]:
        path.chmod(path.stat().st_mode & ~0o222)
    return []


def user_folder(path: Path) -> Path:
    """``path`` made (empty) and given to the user :func:`as_user` runs as."""
    shutil.rmtree(path, ignore_errors=True)
    path.mkdir(parents=True)
    if os.geteuid() == 0:
        os.chown(path, NOBODY, NOBODY)
    return path


def user_env(home: Path) -> dict:
    """The environment of a run as that user: ``home`` as its home and cache folder
    (numba's user-wide cache is ``$XDG_CACHE_HOME/numba``), no ``NUMBA_CACHE_DIR``
    and no ``PYTHONPATH`` (only the installed photo3d)."""
    return {"HOME": str(home), "XDG_CACHE_HOME": str(home / ".cache"), "PYTHONPATH": "",
            "NUMBA_CACHE_DIR": ""}
