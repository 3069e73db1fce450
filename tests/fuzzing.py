"""Valid files of every format photo3d reads back, and their mutations, for the readers'
property tests (``tests/io/test_fuzz_readers.py``) and the long run
(``scripts/fuzz/fuzz_readers.py``)."""

from __future__ import annotations

import traceback
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from hypothesis import strategies as st

from photo3d.errors import Photo3DError


def _photo():
    import photo3d

    rng = np.random.default_rng(1)
    depth = np.ones((12, 12), np.float32)
    depth[3:9, 3:9] = 0.25
    return photo3d.make(rng.random((12, 12, 3)).astype(np.float32), depth=depth,
                        config=photo3d.Config(size=None))


def _light_glb(folder: Path) -> SimpleNamespace:
    from photo3d.io.light_glb import read_light_glb

    photo = _photo()
    folder = photo.save(folder / "photo", viewer=False, ply=None)
    ldi = photo.ldi
    return SimpleNamespace(
        path=folder / "mesh.glb", folder=folder, ldi=ldi,
        read=lambda p: read_light_glb(p, intrinsics=ldi.intrinsics, lattice=ldi.lattice_shape))


def _in(folder: Path, name: str, write: Callable[[Path], object],
        read: Callable[[Path], object]) -> SimpleNamespace:
    folder.mkdir(parents=True, exist_ok=True)
    write(folder / name)
    return SimpleNamespace(path=folder / name, read=read)


def _full_glb(folder):
    from photo3d.io.gltf import read_glb, write_glb

    mesh = _photo().mesh()
    return _in(folder, "full.glb", lambda p: write_glb(p, mesh), read_glb)


def _npz(folder):
    from photo3d.io.npz import load_npz, save_npz

    ldi = _photo().ldi
    return _in(folder, "photo3d.npz", lambda p: save_npz(ldi, p, meta={"a": [1]}), load_npz)


def _ply(folder):
    from photo3d.io.ply import read_ply, write_ply

    mesh = _photo().mesh()
    return _in(folder, "mesh.ply", lambda p: write_ply(p, mesh), read_ply)


def _splats():
    from photo3d.export.splats import build_splats

    return build_splats(_photo().ldi)


def _splat_ply(folder):
    from photo3d.io.splat_ply import read_splat_ply, write_splat_ply

    splats = _splats()
    return _in(folder, "splats.ply", lambda p: write_splat_ply(p, splats), read_splat_ply)


def _spz(folder):
    from photo3d.io.spz import read_spz, write_spz

    splats = _splats()
    return _in(folder, "splats.spz", lambda p: write_spz(p, splats), read_spz)


def _splat_glb(folder):
    from photo3d.io.splat_glb import read_splat_glb, write_splat_glb

    splats = _splats()
    return _in(folder, "splats.glb", lambda p: write_splat_glb(p, splats), read_splat_glb)


def _json(folder):
    from photo3d.files.atomic import write_json
    from photo3d.io.bounded import read_json

    value = {"written": ["splats.ply"], "save": {"videos": [{"path": "circle"}]}, "n": 1.5}
    return _in(folder, "config.json", lambda p: write_json(p, value), read_json)


def _png(folder):
    from photo3d.io.images import read_image, write_image

    image = np.random.default_rng(2).random((10, 14, 3)).astype(np.float32)
    return _in(folder, "photo.png", lambda p: write_image(p, image), read_image)


def _safetensors(folder):
    from photo3d.nets.weights import build_net, read_safetensors, save_safetensors

    net = build_net("depth", levels=3, width=0.125)
    return _in(folder, "depth.safetensors", lambda p: save_safetensors(net, p),
               read_safetensors)


FORMATS: dict[str, Callable[[Path], SimpleNamespace]] = {
    "mesh.glb": _light_glb, "full.glb": _full_glb, "photo3d.npz": _npz, "mesh.ply": _ply,
    "splats.ply": _splat_ply, "splats.spz": _spz, "splats.glb": _splat_glb,
    "config.json": _json, "photo.png": _png, "depth.safetensors": _safetensors,
}
"""Name -> ``make(folder)``: a valid file (``.path``) and its reader (``.read(path)``)."""


_EXTREMES = [0, 1, 0x7F, 0xFF, 0xFFFF, 0x7FFFFFFF, 0xFFFFFFFF, 0x10000000]


@st.composite
def mutated(draw, data: bytes):
    """``data`` with a few mutations: bytes replaced, a cut, bytes inserted, a 32-bit
    little-endian field set to an extreme (a length, a count, an offset)."""
    out = bytearray(data)
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["flip", "cut", "insert", "field"]))
        at = draw(st.integers(0, max(len(out) - 1, 0)))
        if kind == "flip" and out:
            out[at] = draw(st.integers(0, 255))
        elif kind == "cut":
            del out[at:]
        elif kind == "insert":
            out[at:at] = draw(st.binary(min_size=1, max_size=16))
        elif len(out) >= 4:
            at = min(at, len(out) - 4)
            out[at:at + 4] = draw(st.sampled_from(_EXTREMES)).to_bytes(4, "little")
    return bytes(out)


def one_line(read: Callable[[Path], object], path: Path) -> None:
    """Read ``path``; fail unless it reads or raises a one-line Photo3DError."""
    try:
        read(path)
    except Photo3DError as err:
        assert "\n" not in str(err), f"a message of several lines: {err!r}"
    except Exception as err:  # noqa: BLE001 - any other is the failure the test looks for
        raise AssertionError("a traceback: " + "".join(
            traceback.format_exception_only(err)).strip()) from err
