"""The light textured mesh: error bound, texture, exact vertices, and its renders."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import exact_config, texture

import photo3d
from photo3d.camera import Camera, Intrinsics, unproject
from photo3d.errors import InputError
from photo3d.mesh.full import build_mesh
from photo3d.mesh.light import build_light_mesh
from photo3d.render.renderer import Renderer, RenderSettings
from photo3d.stages.ldi import from_image
from photo3d.structures.mesh import TexturedMesh


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    return float(10 * np.log10(1.0 / max(np.mean((a - b) ** 2), 1e-12)))


def box_photo(border: int = 8) -> photo3d.Photo3D:
    """80x64 textured background (disparity 1) with a box in front (disparity 2.5)."""
    disp = np.ones((64, 80), np.float32)
    disp[16:44, 24:56] = 2.5
    return photo3d.make(texture(64, 80, seed=5), depth=disp, config=exact_config(border=border))


def render(mesh, position, size=(80, 64), ssaa=2) -> np.ndarray:
    camera = Camera.translated(Intrinsics.default(*size), position)
    with Renderer(mesh, RenderSettings(ssaa=ssaa, backend="numba")) as renderer:
        return renderer.render(camera).color


def test_a_plane_becomes_two_triangles_with_the_photo_as_texture():
    image = texture(48, 64, seed=1)
    ldi = from_image(image, np.full((48, 64), 0.5, np.float32))
    light = build_light_mesh(ldi)
    assert len(light.faces) <= 4 and len(build_mesh(ldi).faces) == 2 * 47 * 63
    # the photo itself is the texture of the input layer, texel for pixel
    np.testing.assert_array_equal(light.texture[:48, :64], np.rint(image * 255).astype(np.uint8))
    # the input view shows the photo (bilinear texture at the pixel centres); the
    # last column and row lie exactly on the right / bottom edge, which the fill rule
    # leaves to the (absent) neighbour, so they are hole-filled
    got = render(light, (0.0, 0.0, 0.0), size=(64, 48), ssaa=1)
    assert np.abs(got - image)[:-1, :-1].max() < 0.5 / 255 + 1e-6


def test_vertices_are_ldi_pixels_and_labels_follow_them():
    photo = box_photo()
    ldi, light = photo.ldi, photo.light_mesh()
    points = unproject(ldi.x, ldi.y, ldi.depth(), ldi.intrinsics)
    index = {tuple(p): i for i, p in enumerate(points.tolist())}
    found = [index.get(tuple(p)) for p in light.vertices.tolist()]
    assert None not in found
    np.testing.assert_array_equal(light.labels, ldi.label[found])
    assert (light.uv >= 0).all() and (light.uv <= 1).all()


def test_light_mesh_is_small_and_renders_like_the_full_mesh():
    photo = box_photo()
    full, light = photo.mesh(), photo.light_mesh()
    assert len(light.faces) < len(full.faces) / 3
    for position in [(0.0, 0.0, 0.0), (0.03, -0.02, 0.0), (-0.02, 0.0, 0.05)]:
        a, b = render(full, position), render(light, position)
        assert psnr(a, b) > 35, position
    # the test can fail: the same mesh with its texture shifted by 3 texels is far off
    shifted = dataclasses.replace(light, texture=np.roll(light.texture, 3, axis=1))
    assert psnr(render(full, (0.03, -0.02, 0.0)), render(shifted, (0.03, -0.02, 0.0))) < 30


def test_error_bound_controls_the_triangle_count():
    photo = box_photo()
    full = photo.mesh()
    exact = build_light_mesh(photo.ldi, max_error=0.0, full=full)
    assert len(exact.faces) == len(full.faces)
    coarse = build_light_mesh(photo.ldi, max_error=2.0, full=full)
    assert len(coarse.faces) < len(build_light_mesh(photo.ldi, max_error=0.1, full=full).faces)


def test_silhouettes_keep_their_pixel_outline():
    """The box's outline seen from (near) the input camera is exactly the full mesh's,
    at 4 times the default bound.

    (Slightly off the input camera: exactly there, pixel centres lie on the outline,
    where the full mesh has a vertex on every one and the light mesh only at corners,
    and the rasterizer's fill rule treats the two differently. A much coarser bound
    may cut a corner, which it allows: here from 4 px on (meshoptimizer, used before:
    6 px).)"""
    photo = box_photo(border=0)
    full, light = photo.mesh(), photo.light_mesh(max_error=2.0)
    k = photo.ldi.intrinsics
    settings = RenderSettings(ssaa=1, fill_holes=False, backend="numba")
    with Renderer(full, settings) as rf, Renderer(light, settings) as rl:
        camera = Camera.translated(k, (0.002, 0.0013, 0.0))
        a, b = rf.render(camera).depth, rl.render(camera).depth
    np.testing.assert_array_equal(a < 1.0 / 2.4 * 3, b < 1.0 / 2.4 * 3)  # box pixels


def test_bad_arguments_are_one_line_errors():
    ldi = from_image(np.zeros((4, 4, 3), np.float32), np.ones((4, 4), np.float32))
    with pytest.raises(InputError, match="max_error"):
        build_light_mesh(ldi, max_error=-1.0)
    mesh = TexturedMesh(np.zeros((3, 3)), np.zeros((2, 2)), np.zeros((2, 2, 3), np.uint8),
                        np.ones(3), np.array([[0, 1, 2]]), 1, 4, 4, 1.0, 1.0)
    with pytest.raises(InputError, match="uv"):
        mesh.checked()


def _open_edges(faces: np.ndarray) -> set:
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), 1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    return {tuple(e) for e in uniq[count == 1].tolist()}


def test_tiled_simplification_meets_at_the_tile_seam(monkeypatch):
    """Strips simplified apart (two threads) still form one surface: the open
    edges are the grid's outline only (the vertices the tiles share are locked;
    unlocked, each tile collapses its side of the seam its own way)."""
    import photo3d.mesh._simplify
    import photo3d.mesh.light as light

    n = 120
    yy, xx = np.mgrid[0:n, 0:n].astype(np.float32)
    # curved (many triangles stay) but flat along the seam, where unlocked tiles
    # would collapse their borders each its own way (cracks)
    z = 20.0 + 3.0 * np.sin(xx / 9.0) * np.cos(yy / 13.0) * (np.abs(xx - n / 2) > 12)
    points = np.stack([xx.ravel(), yy.ravel(), z.ravel()], 1)
    q = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    faces = np.concatenate([np.stack([q, q + n, q + 1], 1), np.stack([q + 1, q + n, q + n + 1], 1)])
    whole = light._simplify(points, faces, 2.0)
    monkeypatch.setattr(photo3d.mesh._simplify, "_TILE_FACES", 1000)
    tiled = light._simplify(points, faces, 2.0)
    assert len(whole) < len(tiled) < len(faces) / 10  # the locked seam keeps its vertices
    outline = set()
    for f in _open_edges(tiled):
        a, b = points[list(f), :2]
        assert a[0] in (0, n - 1) and b[0] == a[0] or a[1] in (0, n - 1) and b[1] == a[1], f
        outline.add(f)
    # the outline's length is the grid's perimeter: no edge is missing
    length = sum(np.abs(points[a, :2] - points[b, :2]).sum() for a, b in outline)
    assert length == 4 * (n - 1)


def test_layer_images_grow_when_the_first_room_is_short(monkeypatch):
    """Faces of hidden layers claim extra layer images; when the first allocation is
    too small it is doubled and the result is the same."""
    import photo3d.mesh.light as light

    disp = np.ones((64, 80), np.float32)
    for y, x, d in ((8, 10, 2.0), (20, 30, 3.0), (30, 45, 4.5), (14, 55, 6.0)):
        disp[y:y + 22, x:x + 20] = d  # overlapping boxes: hidden faces need new layers
    photo = photo3d.make(texture(64, 80, seed=5), depth=disp, config=exact_config(border=8))
    expected = build_light_mesh(photo.ldi)
    calls = []
    claim = light.claim_faces

    def spy(*args):
        calls.append(args[3].shape[0])
        return claim(*args)

    monkeypatch.setattr(light, "claim_faces", spy)
    monkeypatch.setattr(light, "_LAYER_ROOM", 0)  # one spare layer image at first
    got = build_light_mesh(photo.ldi)
    assert len(calls) >= 2 and calls[1] == 2 * calls[0]
    np.testing.assert_array_equal(got.faces, expected.faces)
    np.testing.assert_array_equal(got.texture, expected.texture)
