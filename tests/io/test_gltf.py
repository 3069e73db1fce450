"""GLB: exact round trips, the file layout read by hand, trimesh as the independent reader."""

from __future__ import annotations

import json
import math
import struct
from dataclasses import replace

import numpy as np
import pytest
import trimesh
from conftest import grid_mesh

from photo3d.errors import InputError, OutputError
from photo3d.io.gltf import read_glb, write_glb

OPENCV_TO_GLTF = np.array([1.0, -1.0, -1.0])


def srgb_to_linear(srgb: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 decoding, written independently of the module under test."""
    s = srgb / 255.0
    return np.where(s <= 0.04045, s / 12.92, ((s + 0.055) / 1.055) ** 2.4)


def split_glb(data: bytes) -> tuple[dict, bytes, bytes]:
    """(JSON document, raw JSON chunk, BIN chunk), checking the GLB framing."""
    magic, version, length = struct.unpack_from("<4sII", data)
    assert (magic, version, length) == (b"glTF", 2, len(data))
    json_length, json_type = struct.unpack_from("<I4s", data, 12)
    assert json_type == b"JSON" and json_length % 4 == 0
    raw_json = data[20 : 20 + json_length]
    bin_length, bin_type = struct.unpack_from("<I4s", data, 20 + json_length)
    assert bin_type == b"BIN\0" and bin_length % 4 == 0
    assert 28 + json_length + bin_length == len(data)
    return json.loads(raw_json), raw_json, data[28 + json_length :]


@pytest.mark.parametrize("shape", [(3, 3), (16, 16), (260, 260)])  # uint16 and uint32 indices
def test_round_trip_is_exact(tmp_path, shape):
    mesh = grid_mesh(*shape)
    write_glb(tmp_path / "m.glb", mesh)
    back = read_glb(tmp_path / "m.glb")
    for name in ("vertices", "colors", "labels", "faces"):
        a, b = getattr(back, name), getattr(mesh, name)
        assert a.dtype == b.dtype, name
        np.testing.assert_array_equal(a, b, err_msg=name)
    assert (back.width, back.height, back.hfov, back.vfov) == (640, 480, 1.1, 0.85)


def test_every_srgb_level_survives(tmp_path):
    mesh = grid_mesh(16, 16)
    assert sorted(set(mesh.colors[:, 0].tolist())) == list(range(256))
    write_glb(tmp_path / "m.glb", mesh)
    np.testing.assert_array_equal(read_glb(tmp_path / "m.glb").colors, mesh.colors)


@pytest.mark.parametrize("shape, index_type", [((3, 3), 5123), ((260, 260), 5125)])
def test_file_layout(tmp_path, shape, index_type):
    mesh = grid_mesh(*shape)
    write_glb(tmp_path / "m.glb", mesh)
    doc, raw_json, binary = split_glb((tmp_path / "m.glb").read_bytes())
    assert raw_json.rstrip(b" ").endswith(b"}") and len(raw_json) - len(raw_json.rstrip(b" ")) < 4
    assert doc["asset"] == {"version": "2.0", "generator": "photo3d"}
    assert doc["extensionsUsed"] == ["KHR_materials_unlit"]
    (material,) = doc["materials"]
    assert material["extensions"] == {"KHR_materials_unlit": {}}
    assert material["pbrMetallicRoughness"] == {
        "baseColorFactor": [1.0, 1.0, 1.0, 1.0],
        "metallicFactor": 0.0,
        "roughnessFactor": 1.0,
    }
    assert material["doubleSided"] is False
    (primitive,) = doc["meshes"][0]["primitives"]
    assert primitive["mode"] == 4 and primitive["material"] == 0
    accessors, views = doc["accessors"], doc["bufferViews"]
    position = accessors[primitive["attributes"]["POSITION"]]
    gltf_vertices = mesh.vertices * OPENCV_TO_GLTF.astype(np.float32)
    assert position["min"] == gltf_vertices.min(0).tolist()
    assert position["max"] == gltf_vertices.max(0).tolist()
    assert accessors[primitive["attributes"]["COLOR_0"]]["componentType"] == 5126
    assert accessors[primitive["attributes"]["_LABEL"]]["componentType"] == 5121
    assert accessors[primitive["indices"]]["componentType"] == index_type
    assert accessors[primitive["indices"]]["count"] == mesh.faces.size
    for view in views:
        assert view["byteOffset"] % 4 == 0 and view.get("byteStride", 4) % 4 == 0
        assert view["byteOffset"] + view["byteLength"] <= len(binary)
    targets = {
        name: views[accessors[i]["bufferView"]]["target"]
        for name, i in primitive["attributes"].items()
    }
    assert targets == {"POSITION": 34962, "COLOR_0": 34962, "_LABEL": 34962}
    assert views[accessors[primitive["indices"]]["bufferView"]]["target"] == 34963
    assert doc["buffers"] == [{"byteLength": len(binary)}]
    last = max(v["byteOffset"] + v["byteLength"] for v in views)
    assert binary[last:] == bytes(len(binary) - last)  # zero padding
    # the input camera: a perspective camera on an identity node in the scene
    (camera,) = doc["cameras"]
    assert camera["type"] == "perspective"
    assert camera["perspective"] == {"yfov": 0.85, "aspectRatio": 640 / 480, "znear": 0.01}
    (node,) = [n for n in doc["nodes"] if "camera" in n]
    assert set(node) <= {"name", "camera"}
    assert doc["nodes"].index(node) in doc["scenes"][doc["scene"]]["nodes"]


def test_trimesh_reads_the_same_mesh(tmp_path):
    mesh = grid_mesh(16, 16)
    write_glb(tmp_path / "m.glb", mesh)
    scene = trimesh.load(tmp_path / "m.glb", process=False)
    (geometry,) = scene.geometry.values()
    flat = trimesh.load(tmp_path / "m.glb", process=False, force="mesh")  # node transforms applied
    for loaded in (geometry, flat):
        np.testing.assert_array_equal(
            loaded.vertices * OPENCV_TO_GLTF, mesh.vertices.astype(np.float64)
        )
        np.testing.assert_array_equal(loaded.faces, mesh.faces)
        # front faces look at the camera: +z in glTF, -z back in the OpenCV frame
        normals = loaded.face_normals * OPENCV_TO_GLTF
        np.testing.assert_allclose(normals, np.tile([0.0, 0.0, -1.0], (len(normals), 1)), atol=1e-3)
    # trimesh hands back the stored COLOR_0 as is: linear light, not sRGB
    linear = np.asarray(geometry.visual.vertex_attributes["color"])
    np.testing.assert_allclose(linear, srgb_to_linear(mesh.colors), rtol=0, atol=1e-6)
    np.testing.assert_array_equal(
        np.asarray(geometry.vertex_attributes["_LABEL"]).ravel(), mesh.labels
    )
    assert math.isclose(scene.camera.fov[1], math.degrees(0.85), rel_tol=1e-6)


def test_no_camera_without_a_field_of_view(tmp_path):
    write_glb(tmp_path / "m.glb", replace(grid_mesh(), hfov=0.0, vfov=0.0))
    doc, _, _ = split_glb((tmp_path / "m.glb").read_bytes())
    assert "cameras" not in doc and all("camera" not in n for n in doc["nodes"])
    assert read_glb(tmp_path / "m.glb").vfov == 0.0


def repack(data: bytes, edit) -> bytes:
    """The GLB ``data`` with its JSON document changed in place by ``edit(doc)``."""
    doc, _, binary = split_glb(data)
    edit(doc)
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    chunks = (
        struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(binary), b"BIN\0")
    )
    return struct.pack("<4sII", b"glTF", 2, 12 + len(chunks) + len(binary)) + chunks + binary


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda data: b"PK\x03\x04" + data[4:], "not a binary glTF"),
        (lambda data: data[:30], "JSON"),
        (lambda data: data[:-8], "truncated"),
        (
            lambda data: repack(data, lambda d: d["meshes"][0]["primitives"][0].update(mode=0)),
            "triangles",
        ),
        (lambda data: repack(data, lambda d: d["nodes"][0].update(scale=[2, 2, 2])), "transform"),
        (lambda data: repack(data, lambda d: d["bufferViews"][0].update(byteLength=8)), "past its"),
        (lambda data: repack(data, lambda d: d["meshes"][0].pop("primitives")), "structure"),
    ],
)
def test_malformed_files_raise_input_error(tmp_path, make, message):
    write_glb(tmp_path / "m.glb", grid_mesh())
    (tmp_path / "bad.glb").write_bytes(make((tmp_path / "m.glb").read_bytes()))
    with pytest.raises(InputError, match=message):
        read_glb(tmp_path / "bad.glb")


def test_bad_meshes_and_paths(tmp_path):
    mesh = grid_mesh()
    with pytest.raises(InputError, match="cannot read"):
        read_glb(tmp_path / "missing.glb")
    with pytest.raises(OutputError, match="cannot write"):
        write_glb(tmp_path / "no" / "dir" / "m.glb", mesh)
    with pytest.raises(InputError, match="no faces"):
        write_glb(tmp_path / "m.glb", replace(mesh, faces=np.zeros((0, 3), np.int32)))
    vertices = mesh.vertices.copy()
    vertices[4, 2] = np.nan
    with pytest.raises(InputError, match="NaN"):
        write_glb(tmp_path / "m.glb", replace(mesh, vertices=vertices))
    with pytest.raises(InputError, match="colors"):
        write_glb(tmp_path / "m.glb", replace(mesh, colors=mesh.colors[:, :2]))


def test_textured_glb_round_trip_and_independent_reader(tmp_path):
    """The light mesh as GLB: our reader gets it back, trimesh sees the texture and
    the unlit material, the input camera is a camera node."""
    from conftest import exact_config, texture

    import photo3d
    from photo3d.io.gltf_textured import read_textured_glb, write_textured_glb

    disp = np.ones((32, 40), np.float32)
    disp[8:24, 10:30] = 2.0
    photo = photo3d.make(texture(32, 40, seed=2), depth=disp, config=exact_config(border=4))
    light = photo.light_mesh()
    write_textured_glb(tmp_path / "m.glb", light)
    back = read_textured_glb(tmp_path / "m.glb")
    np.testing.assert_array_equal(back.vertices, light.vertices)
    np.testing.assert_array_equal(back.faces, light.faces)
    np.testing.assert_array_equal(back.uv, light.uv)
    np.testing.assert_array_equal(back.labels, light.labels)
    assert np.abs(back.texture.astype(int) - light.texture).mean() < 3  # JPEG
    doc, _, _ = split_glb((tmp_path / "m.glb").read_bytes())
    assert doc["extensionsUsed"] == ["KHR_materials_unlit"]
    material = doc["materials"][0]
    assert material["pbrMetallicRoughness"]["baseColorTexture"] == {"index": 0}
    assert doc["images"][0]["mimeType"] == "image/jpeg"
    (node,) = [n for n in doc["nodes"] if "camera" in n]
    assert doc["nodes"].index(node) in doc["scenes"][0]["nodes"]
    assert doc["cameras"][0]["perspective"]["yfov"] == pytest.approx(light.vfov)
    scene = trimesh.load(tmp_path / "m.glb", process=False, force="mesh")
    assert isinstance(scene.visual, trimesh.visual.TextureVisuals)
    assert scene.visual.material.baseColorTexture.size == light.texture.shape[1::-1]
    assert len(scene.faces) == len(light.faces)


def _shrink_vertices(doc: dict, count: int, keys=("POSITION", "TEXCOORD_0", "_LABEL")) -> None:
    """Claim only ``count`` vertices in the given attribute accessors (a hostile file)."""
    attributes = doc["meshes"][0]["primitives"][0]["attributes"]
    for key in keys:
        doc["accessors"][attributes[key]]["count"] = count
    doc["accessors"][attributes["POSITION"]].pop("min", None)
    doc["accessors"][attributes["POSITION"]].pop("max", None)


@pytest.mark.parametrize("keys, message", [(("POSITION", "TEXCOORD_0", "_LABEL"), "outside"),
                                           (("TEXCOORD_0",), "different lengths")])
def test_textured_reader_rejects_hostile_files(tmp_path, keys, message):
    """Indices past the vertices, or attributes of different lengths, raise InputError
    instead of building a mesh whose faces point outside its vertex arrays."""
    from photo3d.io.gltf_textured import read_textured_glb, write_textured_glb
    from photo3d.structures.mesh import TexturedMesh

    n = 9
    mesh = TexturedMesh(np.random.default_rng(0).random((n, 3), np.float32) + [0, 0, 1],
                        np.full((n, 2), 0.5, np.float32), np.zeros((4, 4, 3), np.uint8),
                        np.ones(n, np.uint8), np.array([[0, 1, 8], [2, 3, 4]], np.int32), 1,
                        4, 4, 0.5, 0.5)
    write_textured_glb(tmp_path / "m.glb", mesh)
    assert len(read_textured_glb(tmp_path / "m.glb").faces) == 2
    bad = repack((tmp_path / "m.glb").read_bytes(), lambda d: _shrink_vertices(d, 5, keys))
    (tmp_path / "bad.glb").write_bytes(bad)
    with pytest.raises(InputError, match=message):
        read_textured_glb(tmp_path / "bad.glb")
