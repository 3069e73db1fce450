"""PLY: exact round trips, the authors' header, trimesh as the independent reader."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import trimesh
from conftest import grid_mesh

from photo3d.errors import InputError, OutputError
from photo3d.io.ply import read_ply, write_ply
from photo3d.structures.mesh import Mesh


def assert_same_mesh(got: Mesh, want: Mesh) -> None:
    for name in ("vertices", "colors", "labels", "faces"):
        a, b = getattr(got, name), getattr(want, name)
        assert a.dtype == b.dtype, name
        np.testing.assert_array_equal(a, b, err_msg=name)
    assert (got.width, got.height, got.hfov, got.vfov) == (
        want.width,
        want.height,
        want.hfov,
        want.vfov,
    )


@pytest.mark.parametrize("binary", [True, False])
def test_round_trip_is_exact(tmp_path, binary):
    mesh = grid_mesh()
    write_ply(tmp_path / "m.ply", mesh, binary=binary)
    assert_same_mesh(read_ply(tmp_path / "m.ply"), mesh)


def test_ascii_restores_extreme_float32_exactly(tmp_path):
    rng = np.random.default_rng(1)
    mesh = grid_mesh(4, 4)
    magnitudes = 10.0 ** rng.uniform(-30, 30, (16, 3))
    vertices = (rng.standard_normal((16, 3)) * magnitudes).astype(np.float32)
    vertices[0] = [np.finfo(np.float32).max, np.finfo(np.float32).tiny, -0.0]
    mesh = Mesh(vertices, mesh.colors, mesh.labels, mesh.faces, 3, 2, np.pi / 3, 0.1)
    write_ply(tmp_path / "m.ply", mesh, binary=False)
    back = read_ply(tmp_path / "m.ply")
    assert back.vertices.tobytes() == vertices.tobytes()
    assert back.hfov == np.pi / 3


@pytest.mark.parametrize("binary", [True, False])
def test_header_matches_the_authors_layout(tmp_path, binary):
    mesh = grid_mesh()
    write_ply(tmp_path / "m.ply", mesh, binary=binary)
    data = (tmp_path / "m.ply").read_bytes()
    header = data[: data.index(b"end_header\n") + len(b"end_header\n")].decode("ascii")
    assert header.splitlines() == [
        "ply",
        f"format {'binary_little_endian' if binary else 'ascii'} 1.0",
        "comment H 480",
        "comment W 640",
        "comment hFov 1.1",
        "comment vFov 0.85",
        "element vertex 9",
        "property float x",
        "property float y",
        "property float z",
        "property uchar red",
        "property uchar green",
        "property uchar blue",
        "property uchar alpha",
        "element face 8",
        "property list uchar int vertex_index",
        "end_header",
    ]
    if binary:  # 9 vertices * 16 bytes + 8 faces * 13 bytes, nothing else
        assert len(data) == len(header) + 9 * 16 + 8 * 13


def test_ascii_body_splits_on_single_spaces_like_the_authors_reader(tmp_path):
    mesh = grid_mesh()
    write_ply(tmp_path / "m.ply", mesh, binary=False)
    body = (tmp_path / "m.ply").read_text().split("end_header\n")[1]
    lines = body.split("\n")
    assert lines[-1] == "" and len(lines) == 9 + 8 + 1
    for line, vertex, color, label in zip(
        lines[:9], mesh.vertices, mesh.colors, mesh.labels, strict=True
    ):
        words = line.split(" ")
        assert np.array(words[:3], np.float32).tolist() == vertex.tolist()
        assert [int(w) for w in words[3:]] == [*color.tolist(), int(label)]
    for line, face in zip(lines[9:-1], mesh.faces, strict=True):
        assert [int(w) for w in line.split(" ")] == [3, *face.tolist()]


@pytest.mark.parametrize("binary", [True, False])
def test_trimesh_reads_the_same_mesh(tmp_path, binary):
    mesh = grid_mesh()
    write_ply(tmp_path / "m.ply", mesh, binary=binary)
    loaded = trimesh.load(tmp_path / "m.ply", process=False, force="mesh")
    np.testing.assert_array_equal(loaded.vertices, mesh.vertices.astype(np.float64))
    np.testing.assert_array_equal(loaded.faces, mesh.faces)
    rgba = np.asarray(loaded.visual.vertex_colors)
    np.testing.assert_array_equal(rgba[:, :3], mesh.colors)
    np.testing.assert_array_equal(rgba[:, 3], mesh.labels)  # the authors' label as alpha
    # counter-clockwise seen from the camera: normals point back at it, -z in OpenCV
    np.testing.assert_allclose(loaded.face_normals, np.tile([0.0, 0.0, -1.0], (8, 1)), atol=1e-3)


def test_reads_foreign_ascii_without_alpha_or_comments(tmp_path):
    text = (
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
        "property double z\nproperty float nx\nproperty uchar red\nproperty uchar green\n"
        "property uchar blue\nelement face 1\nproperty list uchar uint vertex_indices\n"
        "end_header\n0 0 1 9 10 20 30\n1 0 1 9 40 50 60\n0 1 1 9 70 80 90\n3 0 2 1\n"
    )
    (tmp_path / "f.ply").write_text(text)
    mesh = read_ply(tmp_path / "f.ply")
    np.testing.assert_array_equal(mesh.vertices, [[0, 0, 1], [1, 0, 1], [0, 1, 1]])
    np.testing.assert_array_equal(mesh.colors, [[10, 20, 30], [40, 50, 60], [70, 80, 90]])
    np.testing.assert_array_equal(mesh.labels, [1, 1, 1])
    np.testing.assert_array_equal(mesh.faces, [[0, 2, 1]])
    assert (mesh.width, mesh.height, mesh.hfov, mesh.vfov) == (0, 0, 0.0, 0.0)


def test_reads_big_endian_binary(tmp_path):
    mesh = grid_mesh()
    names = ["x", "y", "z", "red", "green", "blue", "alpha"]
    vertex = np.empty(9, [(n, ">f4" if n in "xyz" else "u1") for n in names])
    for k, n in enumerate("xyz"):
        vertex[n] = mesh.vertices[:, k]
    for k, n in enumerate(names[3:6]):
        vertex[n] = mesh.colors[:, k]
    vertex["alpha"] = mesh.labels
    face = np.empty(8, [("n", "u1"), ("i", ">i4", (3,))])
    face["n"], face["i"] = 3, mesh.faces
    write_ply(tmp_path / "le.ply", mesh)
    text = (tmp_path / "le.ply").read_bytes().split(b"end_header\n")[0] + b"end_header\n"
    text = text.replace(b"binary_little_endian", b"binary_big_endian")
    (tmp_path / "be.ply").write_bytes(text + vertex.tobytes() + face.tobytes())
    assert_same_mesh(read_ply(tmp_path / "be.ply"), mesh)


def _ascii(tmp_path, faces_line="3 0 2 1", vertex_line="0 0 1 1 2 3 1"):
    write_ply(tmp_path / "a.ply", grid_mesh(), binary=False)
    head = (tmp_path / "a.ply").read_text().split("end_header\n")[0]
    head = head.replace("element vertex 9", "element vertex 3").replace("face 8", "face 1")
    body = f"{vertex_line}\n0 1 1 1 2 3 1\n1 0 1 1 2 3 1\n{faces_line}\n"
    return (head + "end_header\n" + body).encode()


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda p: b"not a ply file", "not a PLY"),
        (lambda p: (p / "m.ply").read_bytes()[:-5], "truncated"),
        (lambda p: (p / "m.ply").read_bytes().replace(b"uchar int", b"uchar long"), "bad header"),
        (lambda p: _ascii(p, faces_line="4 0 2 1 1"), "3 indices per line"),
        (lambda p: _ascii(p, faces_line="2 0 2 1"), "not triangles"),
        (lambda p: _ascii(p).rsplit(b"\n", 2)[0] + b"\n", "truncated"),
        (lambda p: _ascii(p, faces_line="3 0 2 7"), "outside"),
        (lambda p: _ascii(p, vertex_line="0 0 one 1 2 3 1"), "non-numeric"),
        (lambda p: _ascii(p, faces_line="3 0 2 1\n3 0 1 2"), "more data than"),
    ],
)
def test_malformed_files_raise_input_error(tmp_path, make, message):
    write_ply(tmp_path / "m.ply", grid_mesh())
    (tmp_path / "bad.ply").write_bytes(make(tmp_path))
    with pytest.raises(InputError, match=message):
        read_ply(tmp_path / "bad.ply")


def test_binary_quads_raise_input_error(tmp_path):
    write_ply(tmp_path / "m.ply", grid_mesh())
    data = bytearray((tmp_path / "m.ply").read_bytes())
    data[data.index(b"end_header\n") + 11 + 9 * 16] = 4  # first face count
    (tmp_path / "bad.ply").write_bytes(bytes(data))
    with pytest.raises(InputError, match="not triangles"):
        read_ply(tmp_path / "bad.ply")


def test_missing_file_and_bad_outputs(tmp_path):
    with pytest.raises(InputError, match="cannot read"):
        read_ply(tmp_path / "missing.ply")
    with pytest.raises(OutputError, match="cannot write"):
        write_ply(tmp_path / "no" / "such" / "dir.ply", grid_mesh())
    mesh = grid_mesh()
    with pytest.raises(InputError, match="labels"):
        write_ply(tmp_path / "m.ply", replace(mesh, labels=mesh.labels[:-1]))
    with pytest.raises(InputError, match="outside"):
        write_ply(tmp_path / "m.ply", replace(mesh, faces=mesh.faces + 1))
