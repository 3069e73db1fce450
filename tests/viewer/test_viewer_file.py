"""viewer.html without a browser: self-contained, round trip of the embedded mesh, errors."""

from __future__ import annotations

import base64
import json
import math
import re
from dataclasses import replace

import numpy as np
import pytest
from conftest import grid_mesh
from viewer_scenes import box_photo, canonical_faces, shuffled

from photo3d.errors import InputError, OutputError
from photo3d.io.gltf import write_glb
from photo3d.structures.mesh import Mesh
from photo3d.viewer import read_viewer, write_viewer
from photo3d.viewer._codec import decode_mesh, encode_mesh


def embedded(path) -> tuple[dict, str]:
    text = path.read_text()
    header = re.search(r'id="photo3d-header">(.*?)</script>', text, re.S).group(1)
    return json.loads(header), text


def assert_same_mesh(back: Mesh, mesh: Mesh, header: dict) -> None:
    """Positions within half a quantisation step, everything else exact."""
    lo, hi = np.array(header["position"]["lo"]), np.array(header["position"]["hi"])
    step = (hi - lo) / 65535
    v, w = mesh.vertices.astype(np.float64), back.vertices.astype(np.float64)
    for axis in range(2):  # image-plane directions x / z, y / z
        err = np.abs(w[:, axis] / w[:, 2] - v[:, axis] / v[:, 2])
        assert err.max() <= 0.5 * step[axis] + 1e-6
    assert np.abs(1 / w[:, 2] - 1 / v[:, 2]).max() <= 0.5 * step[2] + 1e-6
    np.testing.assert_array_equal(back.colors, mesh.colors)
    np.testing.assert_array_equal(back.labels, mesh.labels)
    np.testing.assert_array_equal(canonical_faces(back.faces), canonical_faces(mesh.faces))
    assert (back.width, back.height) == (mesh.width, mesh.height)
    assert (back.hfov, back.vfov) == (mesh.hfov, mesh.vfov)


def test_round_trip_of_a_3d_photo(tmp_path):
    mesh = box_photo().mesh()
    path = write_viewer(mesh, tmp_path / "viewer.html")
    header, _ = embedded(path)
    back = read_viewer(path)
    assert_same_mesh(back, mesh, header)
    # less than 1/50 px on screen at the input camera's focal length
    fx = mesh.width / 2 / math.tan(mesh.hfov / 2)
    step = (np.array(header["position"]["hi"]) - header["position"]["lo"]) / 65535
    assert 0.5 * step[:2].max() * fx < 0.02


def test_round_trip_with_any_face_order_and_large_indices():
    mesh = grid_mesh(300, 300)  # 90,000 vertices: indices and deltas beyond 16 bits
    mesh = shuffled(mesh, seed=1)
    header, payload = encode_mesh(mesh)
    assert_same_mesh(decode_mesh(header, payload), mesh, header)


def test_page_is_self_contained(tmp_path):
    path = write_viewer(box_photo().mesh(), tmp_path / "viewer.html", title="Box")
    text = path.read_text()
    assert not re.search(r"https?:|//[a-z0-9-]+\.[a-z]|@import|url\(|\bimport\(", text, re.I)
    links = re.findall(r'\b(?:src|href|action)\s*=\s*"([^"]*)"', text, re.I)
    assert links == ["data:,"]  # the empty favicon only: no file the browser would fetch
    assert "default-src 'none'" in text  # the CSP forbids every load
    assert "fetch(" not in text and "XMLHttpRequest" not in text and "WebSocket" not in text
    assert text.count("<script") == 3 and "<title>Box</title>" in text


def test_size_is_a_fraction_of_the_glb(tmp_path):
    mesh = box_photo().mesh()
    html = write_viewer(mesh, tmp_path / "viewer.html").stat().st_size
    write_glb(tmp_path / "mesh.glb", mesh)
    assert html < 0.5 * (tmp_path / "mesh.glb").stat().st_size


def test_title_is_escaped_and_animate_recorded(tmp_path):
    path = write_viewer(grid_mesh(), tmp_path / "v.html", title="</title><script>x()</script>",
                        animate=False)
    header, text = embedded(path)
    assert "<script>x()" not in text and "&lt;/title&gt;" in text
    assert header["animate"] is False
    assert header["vertices"] == 9 and header["faces"] == 8


def test_payload_is_plain_base64(tmp_path):
    path = write_viewer(grid_mesh(), tmp_path / "v.html")
    data = re.search(r'id="photo3d-data">(.*?)</script>', path.read_text(), re.S).group(1)
    assert re.fullmatch(r"[A-Za-z0-9+/]*={0,2}", data)
    assert base64.b64decode(data)[:1] == b"\x78"  # a zlib stream


@pytest.mark.parametrize("change, message", [
    (lambda m: replace(m, vertices=m.vertices * np.float32([1, 1, -1])), "z > 0"),
    (lambda m: replace(m, faces=np.zeros((0, 3), np.int32)), "no vertices or no faces"),
    (lambda m: replace(m, vertices=np.full_like(m.vertices, np.nan)), "NaN"),
    (lambda m: replace(m, colors=m.colors[:2]), "colors"),
])
def test_bad_meshes_are_refused(tmp_path, change, message):
    with pytest.raises(InputError, match=message):
        write_viewer(change(grid_mesh()), tmp_path / "v.html")
    assert not (tmp_path / "v.html").exists()


def test_unwritable_path_and_foreign_files(tmp_path):
    with pytest.raises(OutputError, match="cannot write .*v.html"):
        write_viewer(grid_mesh(), tmp_path / "missing" / "v.html")
    (tmp_path / "other.html").write_text("<html></html>")
    with pytest.raises(InputError, match="not a photo3d viewer"):
        read_viewer(tmp_path / "other.html")
    with pytest.raises(InputError, match="not found"):
        read_viewer(tmp_path / "nothing.html")


def _damaged_page(path, change) -> None:
    """Rewrite the page ``path`` with ``change(header, raw) -> (header, payload)``
    applied to its header and its decompressed payload."""
    import zlib

    text = path.read_text()
    parts = [re.search(f'id="{name}">(.*?)</script>', text, re.S)
             for name in ("photo3d-header", "photo3d-data")]
    header, payload = change(json.loads(parts[0].group(1)),
                             zlib.decompress(base64.b64decode(parts[1].group(1))))
    text = text.replace(parts[1].group(1), base64.b64encode(payload).decode())
    path.write_text(text.replace(parts[0].group(1), json.dumps(header)))


def _zlib(raw: bytes) -> bytes:
    import zlib

    return zlib.compress(raw)


@pytest.mark.parametrize(("change", "message"), [
    (lambda h, raw: ({k: v for k, v in h.items() if k != "vertices"}, _zlib(raw)),
     "the header has no vertices"),
    (lambda h, raw: ({**h, "vertices": "x"}, _zlib(raw)), "invalid literal"),
    (lambda h, raw: ({**h, "vertices": 10**9}, _zlib(raw)), "cannot reshape"),
    (lambda h, raw: ({**h, "sections": {}}, _zlib(raw)), "has no position"),
    (lambda h, raw: ({**h, "sections": {**h["sections"], "faces": "ab"}}, _zlib(raw)),
     "slice indices"),
    (lambda h, raw: ([h], _zlib(raw)), "not a photo3d viewer payload"),
    (lambda h, raw: (h, b"not deflate"), "damaged viewer data: error: Error -3"),
    (lambda h, raw: (h, _zlib(raw + bytes(64 << 20))), "bytes its header declares"),
    (lambda h, raw: (h, _zlib(raw[:-12] + b"\xff" * 12)), "faces has indices outside"),
])
def test_a_damaged_viewer_page_is_one_line(tmp_path, change, message):
    path = write_viewer(grid_mesh(), tmp_path / "viewer.html")
    _damaged_page(path, change)
    with pytest.raises(InputError, match=message) as err:
        read_viewer(path)
    assert "\n" not in str(err.value)


def test_a_viewer_fifo_is_refused_without_blocking(tmp_path):
    import os

    os.mkfifo(tmp_path / "viewer.html")
    with pytest.raises(InputError, match="not a regular file"):
        read_viewer(tmp_path / "viewer.html")


def test_textured_mesh_round_trip(tmp_path):
    """A light textured mesh: uv within 1/65535, texture as JPEG, faces and labels exact."""
    from photo3d.structures.mesh import TexturedMesh

    light = box_photo().light_mesh()
    back = read_viewer(write_viewer(light, tmp_path / "viewer.html"))
    assert isinstance(back, TexturedMesh)
    assert np.abs(back.uv - light.uv).max() <= 0.5 / 65535 + 1e-7
    assert np.abs(back.texture.astype(int) - light.texture).mean() < 3
    np.testing.assert_array_equal(back.labels, light.labels)
    np.testing.assert_array_equal(canonical_faces(back.faces), canonical_faces(light.faces))
    assert np.abs(back.vertices - light.vertices).max() < 1e-3


def test_soft_silhouettes_round_trip(tmp_path):
    """The fringe (faces with a vertex of alpha < 1) is stored apart and read back."""
    import photo3d
    from photo3d.config import Config
    from photo3d.mesh.light import build_light_mesh

    image = np.full((40, 48, 3), 0.4, np.float32)
    image[:, 20:24] = (0.9, 0.1, 0.1)
    depth = np.full((40, 48), 6.0, np.float32)
    depth[:, 18:26] = 2.0
    photo = photo3d.make(image, depth=depth, config=Config(size=None, depth_kind="depth",
                                                           spatial_scale=1.0, edges="soft"))
    full = photo.mesh()
    back = read_viewer(write_viewer(full, tmp_path / "full.html"))
    assert len(back.faces) == len(full.faces)
    soft = np.sort(full.alpha[full.alpha < 1])
    assert np.allclose(np.sort(back.alpha[back.alpha < 1]), soft, atol=1 / 255)
    light = build_light_mesh(photo.ldi)
    again = read_viewer(write_viewer(light, tmp_path / "light.html"))
    assert again.overlay is not None and len(again.overlay.faces) == len(light.overlay.faces)
    assert np.allclose(again.overlay.alpha, light.overlay.alpha, atol=1 / 255)
