"""A GLB written back from its JSON document and binary chunk (as
:func:`photo3d.io.glb.read_chunks` returns them), for tests that alter a file."""

from __future__ import annotations

import json
import struct
from pathlib import Path

from photo3d.io.glb import BIN_CHUNK, JSON_CHUNK, MAGIC


def write_glb(path: Path, document: dict, binary: bytes) -> Path:
    """Write ``document`` (padded with spaces) and ``binary`` as a GLB at ``path``."""
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    path.write_bytes(struct.pack("<III", MAGIC, 2, 28 + len(text) + len(binary))
                     + struct.pack("<II", len(text), JSON_CHUNK) + text
                     + struct.pack("<II", len(binary), BIN_CHUNK) + binary)
    return path
