"""What a folder holds, to compare before and after a command: links, folders and
file contents (the tests that check nothing outside an output changed)."""

from __future__ import annotations

import os
from pathlib import Path


def tree(root: Path) -> dict[str, str | bytes]:
    """Every entry under ``root``: a link's target, a file's bytes, ``"dir"``."""
    found: dict[str, str | bytes] = {}
    for path in sorted(root.rglob("*")):
        key = str(path.relative_to(root))
        if path.is_symlink():
            found[key] = "-> " + os.readlink(path)
        elif path.is_dir():
            found[key] = "dir"
        else:
            found[key] = path.read_bytes()
    return found
