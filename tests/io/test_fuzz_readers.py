"""One bound for every read (issue 45): every reader of a file photo3d reads back
answers a damaged file with one line (a :class:`~photo3d.errors.Photo3DError`), never
a traceback, a recursion or a huge allocation.

Hypothesis mutates a valid file of each format (bytes flipped, cut, inserted, a
length field rewritten) within a small budget; ``scripts/fuzz/fuzz_readers.py`` runs the
same properties for longer. Crafted cases from the fifth round of hostile testing
(``mesh.glb`` that ``render`` reads back, deeply nested JSON) come first."""

from __future__ import annotations

import json
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from fuzzing import FORMATS, mutated, one_line
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from photo3d.errors import InputError, Photo3DError
from photo3d.io.glb import read_chunks, write_container
from photo3d.io.light_glb import read_light_glb

FAST = settings(max_examples=30, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])


# --- defect 5: render trusts the folder's mesh.glb --------------------------------------

@pytest.fixture(scope="module")
def light(tmp_path_factory):
    """A light mesh photo3d wrote (``mesh.glb``), its document, BIN chunk and LDI."""
    return FORMATS["mesh.glb"](tmp_path_factory.mktemp("glb"))


def _rewrite(path: Path, document: dict, binary: bytes) -> Path:
    write_container(path, document, [binary + bytes(-len(binary) % 4)])
    return path


def _read(light, path):
    ldi = light.ldi
    return read_light_glb(path, intrinsics=ldi.intrinsics, lattice=ldi.lattice_shape)


def test_deeply_nested_json_in_a_glb_is_one_line(light, tmp_path):
    data = light.path.read_bytes()
    text = b'{"asset": {"generator": "photo3d"}, "x": ' + b"[" * 100_000 + b"]" * 100_000 + b"}"
    text += b" " * (-len(text) % 4)
    crafted = data[:12] + struct.pack("<II", len(text), 0x4E4F534A) + text
    (tmp_path / "mesh.glb").write_bytes(crafted)
    with pytest.raises(InputError, match="nested deeper"):
        _read(light, tmp_path / "mesh.glb")


def test_signed_or_out_of_range_indices_are_one_line(light, tmp_path):
    document, binary = read_chunks(light.path)
    index = document["meshes"][0]["primitives"][0]["indices"]
    document["accessors"][index]["componentType"] = 5120  # int8: -1 indexes from the end
    view = document["bufferViews"][document["accessors"][index]["bufferView"]]
    raw = bytearray(binary)
    raw[view.get("byteOffset", 0)] = 0xF0
    with pytest.raises(InputError, match="component type"):
        _read(light, _rewrite(tmp_path / "mesh.glb", document, bytes(raw)))


def test_an_accessor_that_names_nothing_is_one_line(light, tmp_path):
    document, binary = read_chunks(light.path)
    document["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 10**6
    with pytest.raises(InputError, match="no accessors"):
        _read(light, _rewrite(tmp_path / "mesh.glb", document, binary))


def _png_header(width: int, height: int) -> bytes:
    """A PNG that declares ``width x height`` RGB pixels (its data cut short)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data)))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
            + chunk(b"IDAT", zlib.compress(bytes(3 * width + 1) * 4)) + chunk(b"IEND", b""))


@pytest.mark.parametrize("side", [9000, 40000])  # a 2.3 GB texture; a decompression bomb
def test_a_huge_texture_is_refused_before_it_is_decoded(light, tmp_path, monkeypatch, side):
    from PIL import ImageFile

    decoded = []
    real = ImageFile.ImageFile.load
    monkeypatch.setattr(ImageFile.ImageFile, "load",
                        lambda self: decoded.append(self.size) or real(self))
    document, binary = read_chunks(light.path)
    image_view = document["images"][0]["bufferView"]
    png = _png_header(side, side)
    document["bufferViews"][image_view] = {"buffer": 0, "byteOffset": len(binary),
                                           "byteLength": len(png)}
    document["images"][0]["mimeType"] = "image/png"
    path = _rewrite(tmp_path / "mesh.glb", document, binary + png)
    with pytest.raises(InputError, match="pixels"):
        _read(light, path)
    assert decoded == []


def test_render_builds_the_mesh_again_from_a_hostile_mesh_glb(light, tmp_path, capsys):
    """The CLI: a crafted mesh.glb is not photo3d's mesh, so the videos are drawn from
    the mesh built from photo3d.npz (exit 0, no traceback)."""
    from photo3d.cli import main

    folder = light.folder
    text = b'{"asset": {"generator": "photo3d"}, "x": ' + b"[" * 100_000 + b"]" * 100_000 + b"}"
    text += b" " * (-len(text) % 4)
    (folder / "mesh.glb").write_bytes(light.path.read_bytes()[:12]
                                      + struct.pack("<II", len(text), 0x4E4F534A) + text)
    status = main(["render", str(folder), "-q", "--frames", "2", "--size", "32x24",
                   "--format", "gif", "--ssaa", "1"])
    err = capsys.readouterr().err
    assert status == 0 and "Traceback" not in err, err


# --- defect 6: deeply nested JSON ------------------------------------------------------

@pytest.mark.parametrize("text", ["[" * 100_000, '{"a": ' * 50_000, "[" * 65 + "]" * 65])
def test_deep_json_is_refused_before_parsing(tmp_path, text):
    from photo3d.io.bounded import read_json

    path = tmp_path / "state.json"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        read_json(path)
    assert "\n" not in str(err.value)


def test_a_fifo_is_refused_without_blocking(tmp_path):
    import os

    from photo3d.io.bounded import read_json

    os.mkfifo(tmp_path / "config.json")
    with pytest.raises(InputError, match="not a regular file"):
        read_json(tmp_path / "config.json")


@FAST
@given(st.recursive(st.none() | st.booleans() | st.integers() | st.text(max_size=5),
                    lambda kids: st.lists(kids, max_size=3)
                    | st.dictionaries(st.text(max_size=3), kids, max_size=3), max_leaves=20))
def test_json_depth_is_the_nesting(value):
    from photo3d.io.bounded import json_depth, loads_json

    text = json.dumps(value)

    def depth(v):
        if isinstance(v, list):
            return 1 + max(map(depth, v), default=0)
        if isinstance(v, dict):
            return 1 + max(map(depth, v.values()), default=0)
        return 0

    assert json_depth(text) == depth(value)
    assert loads_json(text, what="x") == value


@FAST
@given(st.binary(max_size=200))
def test_loads_json_is_a_value_or_one_line(data):
    from photo3d.io.bounded import loads_json

    try:
        loads_json(data, what="x")
    except InputError as err:
        assert "\n" not in str(err)


# --- every reader, mutated valid files ---------------------------------------------------

@pytest.fixture(scope="module")
def valid(tmp_path_factory):
    """``valid(name)``: a valid file of the format ``name`` (made once, when asked for)."""
    root, made = tmp_path_factory.mktemp("valid"), {}

    def get(name):
        if name not in made:
            made[name] = FORMATS[name](root / name.replace(".", "_"))
        return made[name]

    return get


@pytest.mark.parametrize("name", sorted(FORMATS))
def test_each_valid_file_reads(valid, name):
    valid(name).read(valid(name).path)


@pytest.mark.parametrize("name", sorted(FORMATS))
def test_each_reader_answers_a_damaged_file_in_one_line(valid, tmp_path_factory, name):
    sample = valid(name)
    folder = tmp_path_factory.mktemp("fuzz")
    data = sample.path.read_bytes()

    @FAST
    @given(mutated(data))
    def check(damaged: bytes):
        path = folder / sample.path.name
        path.write_bytes(damaged)
        one_line(sample.read, path)

    check()


def test_one_line_fails_on_a_traceback(tmp_path):
    """The property can fail: a reader raising anything but a Photo3DError fails it."""
    def broken(path):
        raise IndexError("list index out of range")

    with pytest.raises(AssertionError):
        one_line(broken, tmp_path)
    with pytest.raises(AssertionError):
        one_line(lambda path: (_ for _ in ()).throw(Photo3DError("two\nlines")), tmp_path)
    assert np.isfinite(1.0)
