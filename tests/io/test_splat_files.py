"""The three splat file formats: 3DGS PLY, SPZ and glTF KHR_gaussian_splatting.

Each is read back by a reader written here from the format's published description
(not photo3d's own reader), and by photo3d's reader; the GLB also by the Khronos
validator when it is installed (``PHOTO3D_NODE_MODULES``, as tests/io/test_gltf_validator).
"""

from __future__ import annotations

import gzip
import json
import os
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest
from glbfile import write_glb

from photo3d.camera import Intrinsics
from photo3d.errors import InputError
from photo3d.io.glb import read_chunks
from photo3d.io.splat_glb import read_splat_glb, write_splat_glb
from photo3d.io.splat_ply import PROPERTIES, read_splat_ply, write_splat_ply
from photo3d.io.spz import read_spz, write_spz
from photo3d.structures.splats import SH_C0, Splats


def random_splats(n: int = 500, seed: int = 0, *, rotated: bool = True) -> Splats:
    rng = np.random.default_rng(seed)
    positions = rng.uniform(-3, 3, (n, 3)) + [0, 0, 6]
    q = rng.normal(size=(n, 4)) if rotated else np.tile([1.0, 0, 0, 0], (n, 1))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return Splats(positions.astype(np.float32), rng.uniform(0, 1, (n, 3)).astype(np.float32),
                  rng.uniform(0.05, 0.99, n).astype(np.float32),
                  np.exp(rng.uniform(-7, -3, (n, 3))).astype(np.float32), q.astype(np.float32))


def same_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``|cos|`` between quaternions (q and -q are the same rotation)."""
    return np.abs((a * b).sum(axis=1))


# --- PLY ---------------------------------------------------------------------------

def test_ply_header_is_the_3dgs_minimum_and_the_body_is_float32_rows(tmp_path):
    splats = random_splats(7)
    write_splat_ply(tmp_path / "s.ply", splats)
    data = (tmp_path / "s.ply").read_bytes()
    head, body = data.split(b"end_header\n")
    assert head.decode().splitlines() == (
        ["ply", "format binary_little_endian 1.0", "element vertex 7"]
        + [f"property float {p}" for p in PROPERTIES])
    assert PROPERTIES == ("x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0",
                          "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3")
    rows = np.frombuffer(body, "<f4").reshape(7, 14)  # read as the format says
    np.testing.assert_array_equal(rows[:, :3], splats.positions)
    np.testing.assert_allclose(0.5 + SH_C0 * rows[:, 3:6], splats.colors, atol=1e-6)
    np.testing.assert_allclose(1 / (1 + np.exp(-rows[:, 6])), splats.opacity, rtol=1e-5)
    np.testing.assert_allclose(np.exp(rows[:, 7:10]), splats.scales, rtol=1e-5)
    np.testing.assert_allclose(rows[:, 10:], splats.rotations, atol=1e-6)  # w x y z


def test_ply_round_trip_and_refusals(tmp_path):
    splats = random_splats(50)
    write_splat_ply(tmp_path / "s.ply", splats)
    back = read_splat_ply(tmp_path / "s.ply")
    for name in ("positions", "colors", "opacity", "scales", "rotations"):
        np.testing.assert_allclose(getattr(back, name), getattr(splats, name), rtol=1e-5,
                                   atol=1e-6, err_msg=name)
    (tmp_path / "mesh.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement "
                                        b"vertex 1\nproperty float x\nend_header\n" + bytes(4))
    with pytest.raises(InputError, match="not a 3DGS PLY"):
        read_splat_ply(tmp_path / "mesh.ply")
    (tmp_path / "cut.ply").write_bytes((tmp_path / "s.ply").read_bytes()[:-10])
    with pytest.raises(InputError, match="truncated"):
        read_splat_ply(tmp_path / "cut.ply")
    with pytest.raises(InputError, match="scales must be > 0"):
        write_splat_ply(tmp_path / "bad.ply", Splats(splats.positions, splats.colors,
                                                     splats.opacity, 0 * splats.scales,
                                                     splats.rotations))


# --- SPZ ---------------------------------------------------------------------------

def spz_reference_read(path: Path) -> dict:
    """An SPZ reader written from Niantic's format description (README): versions 2
    and 3 are gzip around a 16-byte header; version 4 a 32-byte plain header
    (``numStreams`` at byte 15, ``tocByteOffset`` at 16), a table of (compressed,
    uncompressed) uint64 sizes and one zstd stream per non-empty attribute. Then
    positions, alphas, colours, scales, rotations (v2: x y z bytes; v3, v4: the
    smallest three in 10 bits each under a 2-bit index of the largest)."""
    raw = path.read_bytes()
    if raw[:4] == b"NGSP":
        from backports import zstd  # the package photo3d[spz4] installs

        magic, version, n, degree, bits, flags, streams, toc = struct.unpack_from(
            "<IIIBBBBI", raw)
        assert (version, flags, toc) == (4, 0, 32) and raw[20:32] == bytes(12)
        sizes = [struct.unpack_from("<QQ", raw, toc + 16 * i) for i in range(streams)]
        at, parts = toc + 16 * streams, []
        for packed, unpacked in sizes:
            parts.append(zstd.decompress(raw[at:at + packed]))
            assert len(parts[-1]) == unpacked
            at += packed
        assert at == len(raw) and streams == 5  # SH degree 0: no SH stream
        data = bytes(16) + b"".join(parts)
        reserved = 0
    else:
        data = gzip.decompress(raw)
        magic, version, n, degree, bits, flags, reserved = struct.unpack_from("<IIIBBBB", data)
    assert (magic, degree, flags, reserved) == (0x5053474E, 0, 0, 0)
    at = 16
    raw_pos = np.frombuffer(data, np.uint8, 9 * n, at).reshape(n, 3, 3).astype(np.int64)
    fixed = raw_pos[..., 0] | raw_pos[..., 1] << 8 | raw_pos[..., 2] << 16
    fixed = np.where(fixed >= 1 << 23, fixed - (1 << 24), fixed)
    at += 9 * n
    alpha = np.frombuffer(data, np.uint8, n, at) / 255.0
    at += n
    color = ((np.frombuffer(data, np.uint8, 3 * n, at).reshape(n, 3) / 255.0 - 0.5) / 0.15)
    at += 3 * n
    scale = np.frombuffer(data, np.uint8, 3 * n, at).reshape(n, 3) / 16.0 - 10.0
    at += 3 * n
    if version == 2:
        xyz = np.frombuffer(data, np.uint8, 3 * n, at).reshape(n, 3) / 127.5 - 1.0
        at += 3 * n
        w = np.sqrt(np.maximum(0, 1 - (xyz**2).sum(axis=1)))
        rotations = np.concatenate([w[:, None], xyz], axis=1)
    else:
        words = np.frombuffer(data, "<u4", n, at).astype(np.int64)
        at += 4 * n
        rotations = np.zeros((n, 4))
        for i, word in enumerate(words):
            largest, xyzw, shift = word >> 30, [0.0] * 4, 0
            for c in (3, 2, 1, 0):  # the last component is in the lowest bits
                if c == largest:
                    continue
                value = (word >> shift) & 1023
                shift += 10
                xyzw[c] = (value & 511) / 511 * np.sqrt(0.5) * (-1 if value & 512 else 1)
            xyzw[largest] = np.sqrt(max(0.0, 1 - sum(v * v for v in xyzw)))
            rotations[i] = [xyzw[3], *xyzw[:3]]
    assert at == len(data)
    return {"positions": fixed / 2.0**bits, "bits": bits, "opacity": alpha,
            "colors": 0.5 + SH_C0 * color, "scales": np.exp(scale), "version": version,
            "rotations": rotations, "count": n}


@pytest.mark.parametrize("version", [2, 3, 4])
def test_spz_matches_the_published_layout_in_rub_axes(tmp_path, version):
    splats = random_splats(300)
    write_spz(tmp_path / "s.spz", splats, version=version)
    magic = b"NGSP" if version == 4 else b"\x1f\x8b"  # v4: plain header; else gzip
    assert (tmp_path / "s.spz").read_bytes()[:len(magic)] == magic
    ref = spz_reference_read(tmp_path / "s.spz")
    assert ref["version"] == version
    step = 2.0 ** -ref["bits"]
    assert ref["count"] == 300 and step <= splats.scales.max(axis=1).min()
    flip = np.array([1, -1, -1])  # OpenCV (right, down, forward) -> SPZ (right, up, back)
    np.testing.assert_allclose(ref["positions"], splats.positions * flip, atol=step / 2 + 1e-6)
    np.testing.assert_allclose(ref["opacity"], splats.opacity, atol=0.5 / 255 + 1e-6)
    colour_step = SH_C0 / (0.15 * 255)
    np.testing.assert_allclose(ref["colors"], splats.colors, atol=colour_step / 2 + 1e-6)
    np.testing.assert_allclose(np.log(ref["scales"]), np.log(splats.scales), atol=1 / 32 + 1e-6)
    q = splats.rotations * np.array([1, 1, -1, -1])  # the same turn in RUB axes
    assert same_rotation(ref["rotations"], q).min() > (0.98 if version == 2 else 0.9995)


def test_spz_default_is_version_3_and_version_4_is_smaller(tmp_path):
    splats = random_splats(3000, rotated=False)
    write_spz(tmp_path / "3.spz", splats)
    write_spz(tmp_path / "4.spz", splats, version=4)
    assert spz_reference_read(tmp_path / "3.spz")["version"] == 3
    assert (tmp_path / "4.spz").stat().st_size < (tmp_path / "3.spz").stat().st_size


@pytest.mark.parametrize("version", [2, 3, 4])
def test_spz_round_trip_within_quantization(tmp_path, version):
    splats = random_splats(400, seed=version)
    write_spz(tmp_path / "s.spz", splats, version=version)
    back = read_spz(tmp_path / "s.spz")
    step = 2.0 ** -spz_reference_read(tmp_path / "s.spz")["bits"] if version == 2 else 1e-3
    np.testing.assert_allclose(back.positions, splats.positions, atol=step / 2 + 1e-6)
    np.testing.assert_allclose(back.colors, splats.colors, atol=SH_C0 / (0.15 * 255) / 2 + 1e-5)
    np.testing.assert_allclose(back.opacity, splats.opacity, atol=0.5 / 255 + 1e-6)
    cos = same_rotation(back.rotations, splats.rotations)
    assert cos.min() > (0.98 if version == 2 else 0.9995)  # v3 keeps rotations finer
    unrotated = random_splats(20, rotated=False)
    write_spz(tmp_path / "u.spz", unrotated, version=version)
    assert same_rotation(read_spz(tmp_path / "u.spz").rotations, unrotated.rotations).min() > 0.9999


def test_spz_refuses_what_it_cannot_hold(tmp_path):
    far = random_splats(3)
    far = Splats(far.positions * 1e7, far.colors, far.opacity, far.scales, far.rotations)
    with pytest.raises(InputError, match="24-bit"):
        write_spz(tmp_path / "far.spz", far)
    (tmp_path / "not.spz").write_bytes(gzip.compress(b"PSGN" + bytes(12)))
    with pytest.raises(InputError, match="not an SPZ file"):
        read_spz(tmp_path / "not.spz")
    (tmp_path / "plain.spz").write_bytes(b"plain")
    with pytest.raises(InputError, match="gzip"):
        read_spz(tmp_path / "plain.spz")
    with pytest.raises(InputError, match="version must be one of 2, 3, 4"):
        write_spz(tmp_path / "v5.spz", random_splats(3), version=5)
    write_spz(tmp_path / "v4.spz", random_splats(50), version=4)
    whole = (tmp_path / "v4.spz").read_bytes()
    (tmp_path / "cut.spz").write_bytes(whole[:-10])
    with pytest.raises(InputError, match="truncated"):
        read_spz(tmp_path / "cut.spz")
    (tmp_path / "six.spz").write_bytes(whole[:15] + bytes([6]) + whole[16:])
    with pytest.raises(InputError, match="6 streams for SH degree 0, expected 5"):
        read_spz(tmp_path / "six.spz")
    (tmp_path / "v3.spz").write_bytes(whole[:4] + struct.pack("<I", 3) + whole[8:])
    with pytest.raises(InputError, match="says version 3"):
        read_spz(tmp_path / "v3.spz")


# --- glTF --------------------------------------------------------------------------

def test_glb_has_the_khr_gaussian_splatting_primitive(tmp_path):
    splats = random_splats(30)
    write_splat_glb(tmp_path / "s.glb", splats, intrinsics=Intrinsics.default(64, 48))
    document, binary = read_chunks(tmp_path / "s.glb")
    assert document["extensionsUsed"] == ["KHR_gaussian_splatting"]
    primitive = document["meshes"][0]["primitives"][0]
    assert primitive["mode"] == 0  # POINTS
    assert primitive["extensions"] == {"KHR_gaussian_splatting": {
        "kernel": "ellipse", "colorSpace": "srgb_rec709_display"}}
    assert set(primitive["attributes"]) == {
        "POSITION", "COLOR_0", "KHR_gaussian_splatting:ROTATION",
        "KHR_gaussian_splatting:SCALE", "KHR_gaussian_splatting:OPACITY",
        "KHR_gaussian_splatting:SH_DEGREE_0_COEF_0"}
    assert document["cameras"][0]["perspective"]["aspectRatio"] == 64 / 48

    def attribute(name):  # read as glTF says: one bufferView per accessor, tightly packed
        acc = document["accessors"][primitive["attributes"][name]]
        view = document["bufferViews"][acc["bufferView"]]
        dtype = {5126: "<f4", 5121: "u1"}[acc["componentType"]]
        width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[acc["type"]]
        return np.frombuffer(binary, dtype, acc["count"] * width,
                             view["byteOffset"]).reshape(acc["count"], width)

    flip = np.array([1, -1, -1])  # glTF: y up, looking down -z
    np.testing.assert_array_equal(attribute("POSITION"), splats.positions * flip)
    np.testing.assert_allclose(attribute("KHR_gaussian_splatting:SCALE"), splats.scales)
    np.testing.assert_allclose(attribute("KHR_gaussian_splatting:OPACITY")[:, 0],
                               splats.opacity)
    xyzw = attribute("KHR_gaussian_splatting:ROTATION")
    q = splats.rotations * np.array([1, 1, -1, -1])
    np.testing.assert_allclose(xyzw, np.concatenate([q[:, 1:], q[:, :1]], axis=1), atol=1e-6)
    np.testing.assert_allclose(0.5 + SH_C0 * attribute(
        "KHR_gaussian_splatting:SH_DEGREE_0_COEF_0"), splats.colors, atol=1e-6)
    # the fallback colour: linear RGB and, as the spec says it should, the opacity
    np.testing.assert_allclose(attribute("COLOR_0")[:, 3], splats.opacity * 255, atol=0.5)
    back = read_splat_glb(tmp_path / "s.glb")
    np.testing.assert_allclose(back.positions, splats.positions)
    assert same_rotation(back.rotations, splats.rotations).min() > 0.99999


NODE_DIR = os.environ.get("PHOTO3D_NODE_MODULES", "")
VALIDATOR = Path(NODE_DIR) / "node_modules" / "gltf-validator"
SCRIPT = """
const v = require('gltf-validator'); const fs = require('fs');
v.validateBytes(new Uint8Array(fs.readFileSync(process.argv[1]))).then(r => {
  console.log(JSON.stringify(r.issues)); });
"""


@pytest.mark.skipif(not (shutil.which("node") and NODE_DIR and VALIDATOR.is_dir()),
                    reason="needs node and PHOTO3D_NODE_MODULES with gltf-validator")
def test_glb_passes_the_khronos_validator(tmp_path):
    """gltf-validator 2.0.0-dev.3.10 (the newest release) predates the ratified
    extension: it calls the extension's ``KHR_gaussian_splatting:*`` attribute names
    invalid and nothing else. Spelled as application attributes (``_ROTATION``, ...,
    the same accessors) the file has no error and no warning."""
    write_splat_glb(tmp_path / "s.glb", random_splats(40), intrinsics=Intrinsics.default(8, 6))

    def validate(path):
        out = subprocess.run(["node", "-e", SCRIPT, str(path)], cwd=NODE_DIR, check=True,
                             capture_output=True, text=True, timeout=120)
        return json.loads(out.stdout)

    issues = validate(tmp_path / "s.glb")
    attributes = "/meshes/0/primitives/0/attributes/KHR_gaussian_splatting:"
    # every message, each once: the four attribute names (errors), and the note that
    # the validator does not know the extension (an info); no warning, no hint
    assert sorted((m["severity"], m["code"], m["pointer"]) for m in issues["messages"]) == [
        (0, "MESH_PRIMITIVE_INVALID_ATTRIBUTE", attributes + name)
        for name in ("OPACITY", "ROTATION", "SCALE", "SH_DEGREE_0_COEF_0")] + [
        (2, "UNSUPPORTED_EXTENSION", "/extensionsUsed/0")]
    assert (issues["numErrors"], issues["numWarnings"], issues["numInfos"],
            issues["numHints"], issues["truncated"]) == (4, 0, 1, 0, False)

    document, binary = read_chunks(tmp_path / "s.glb")
    primitive = document["meshes"][0]["primitives"][0]
    primitive["attributes"] = {k.replace("KHR_gaussian_splatting:", "_"): v
                               for k, v in primitive["attributes"].items()}
    write_glb(tmp_path / "renamed.glb", document, binary)
    issues = validate(tmp_path / "renamed.glb")
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"]
    # and the validator does find errors: a broken accessor is refused
    document["accessors"][0]["count"] += 10
    write_glb(tmp_path / "bad.glb", document, binary)
    assert validate(tmp_path / "bad.glb")["numErrors"] > 0
