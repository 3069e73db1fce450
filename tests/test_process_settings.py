"""The process-wide settings ``import photo3d`` makes before NumPy and OpenMP load
(``photo3d/__init__.py``): set unless the user set them, in a fresh process."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

CHILD = """
import os, photo3d, numpy
from numpy._core import multiarray
print(os.environ["GOMP_SPINCOUNT"], os.environ["NUMPY_MADVISE_HUGEPAGE"],
      multiarray._get_madvise_hugepage())
"""


def _child(**env: str) -> list[str]:
    clean = {k: v for k, v in os.environ.items()
             if k not in ("GOMP_SPINCOUNT", "NUMPY_MADVISE_HUGEPAGE")}
    out = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True,
                         check=True, env={**clean, **env})
    return out.stdout.split()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="huge pages: Linux")
def test_numpy_asks_for_no_huge_pages_and_openmp_spins_briefly():
    assert _child() == ["10000", "0", "False"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="huge pages: Linux")
def test_what_the_user_set_is_kept():
    assert _child(GOMP_SPINCOUNT="5", NUMPY_MADVISE_HUGEPAGE="1") == ["5", "1", "True"]
