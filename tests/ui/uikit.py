"""Helpers of the ``photo3d ui`` tests: the bundled sample as files, a hostile file,
checks of the downloads, and a running server (each module starts one)."""

from __future__ import annotations

import struct
import zipfile
import zlib
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

GRADIO_WARNINGS = [pytest.mark.filterwarnings(f"ignore:{message}:DeprecationWarning")
                   for message in ("'future.no_silent_downcasting' is deprecated",
                                   "The copy keyword is deprecated")]
"""Marks for the modules that run a server: gradio's queue summarises its events
with pandas, whose version 3 warns about what gradio asks of it (nothing of
photo3d's)."""


def write_sample(folder: Path) -> tuple[Path, Path]:
    """The bundled sample as a user would upload it: ``sample.png`` and its
    ground-truth disparity ``sample.pfm`` (+inf where unknown)."""
    from photo3d.io.depth import write_pfm
    from photo3d.io.images import write_image
    from photo3d.sample import motorcycle

    sample = motorcycle()
    write_image(folder / "sample.png", sample.left)
    write_pfm(folder / "sample.pfm", np.asarray(sample.disparity))
    return folder / "sample.png", folder / "sample.pfm"


def png_bomb(path: Path, side: int = 20_000) -> Path:
    """A PNG that declares ``side x side`` grey pixels in a few hundred bytes (a
    decompression bomb: refused before it is decoded)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    header = struct.pack(">IIBBBBB", side, side, 8, 0, 0, 0, 0)
    body = zlib.compress(b"\0" * (side + 1))  # one row; the rest is missing
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", body)
                     + chunk(b"IEND", b""))
    return path


def check_glb(path: Path, *, min_faces: int = 1) -> None:
    """``path`` is a glTF 2.0 binary that an independent reader (trimesh) loads, with
    at least ``min_faces`` triangles."""
    import trimesh

    data = Path(path).read_bytes()
    assert data[:4] == b"glTF" and struct.unpack("<I", data[4:8])[0] == 2
    assert struct.unpack("<I", data[8:12])[0] == len(data)
    scene = trimesh.load(path, force="scene")
    assert sum(len(g.faces) for g in scene.geometry.values()) >= min_faces


def check_zip(path: Path, *, videos: tuple[str, ...] = ()) -> set[str]:
    """``path`` is an intact zip of a 3D photo folder; returns its names."""
    with zipfile.ZipFile(path) as z:
        assert z.testzip() is None
        names = set(z.namelist())
    assert {"mesh.glb", "viewer.html", "photo3d.npz", "config.json", "depth.png",
            "depth_preview.png"} <= names
    assert {f"video/{v}.mp4" for v in videos} <= names
    return names


@contextmanager
def running(**options):
    """A ``photo3d ui`` server on a free port of 127.0.0.1, closed afterwards."""
    from photo3d.ui import UiOptions, start

    server = start(UiOptions(port=0, **options))
    try:
        yield server
    finally:
        server.close()
    assert not server.workspace.root.exists()


@contextmanager
def first_request_held(monkeypatch):
    """Within the block, the server's first request waits in its worker until the
    returned ``gate`` (a ``threading.Event``) is set, or 120 s; ``calls`` lists every
    request's arguments. So a test sees a second request queued, however fast the
    first would end. The gate is set when the block ends."""
    import threading

    from photo3d.ui import runner

    gate, calls, real = threading.Event(), [], runner.run_job

    def held(*args, **kwargs):
        calls.append(args)
        if len(calls) == 1:
            gate.wait(120)
        yield from real(*args, **kwargs)

    monkeypatch.setattr(runner, "run_job", held)
    try:
        yield gate, calls
    finally:
        gate.set()
