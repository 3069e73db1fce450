import numpy as np
from conftest import exact_config, texture, two_planes

import photo3d
from photo3d.camera import unproject
from photo3d.mesh.full import build_mesh
from photo3d.render.raster import rasterize
from photo3d.stages.ldi import cut, from_image


def signed_areas(mesh):
    """Signed area of each face projected into the input view (pixels)."""
    v = mesh.vertices
    p = v[:, :2] / v[:, 2:3]
    a, b, c = p[mesh.faces[:, 0]], p[mesh.faces[:, 1]], p[mesh.faces[:, 2]]
    ab, ac = b - a, c - a
    return 0.5 * (ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0])


def test_fully_connected_grid_has_two_triangles_per_quad():
    ldi = from_image(texture(7, 9), np.ones((7, 9), np.float32))
    m = build_mesh(ldi)
    assert m.faces.shape == (2 * 6 * 8, 3)
    assert m.vertices.shape == (63, 3)


def test_faces_are_unique_and_consistently_wound():
    img, d = two_planes()
    photo = photo3d.make(img, depth=d, config=exact_config(border=4))
    m = photo.mesh()
    key = np.sort(m.faces, axis=1)
    assert np.unique(key, axis=0).shape[0] == m.faces.shape[0]  # no duplicates
    areas = signed_areas(m)
    # y points down in the image: counter-clockwise seen from the camera is negative here
    assert np.all(areas < 0)
    # normals point towards the camera (OpenCV: -z)
    v = m.vertices
    n = np.cross(v[m.faces[:, 1]] - v[m.faces[:, 0]], v[m.faces[:, 2]] - v[m.faces[:, 0]])
    assert np.all(n[:, 2] < 0)


def _faces_numpy(links: np.ndarray) -> np.ndarray:
    """The corner-triangle rule of build_mesh's docstring in NumPy (the reference the
    numba kernel must match, order included)."""
    idx = np.arange(len(links))
    left, right, up, down = (links[:, i].astype(np.int64) for i in range(4))

    def nb(pix, d):
        out = np.full(pix.shape, -1, np.int64)
        out[pix >= 0] = links[pix[pix >= 0], d]
        return out

    a = idx[(right >= 0) & (down >= 0)]
    d = idx[(up >= 0) & (left >= 0)]
    b = idx[(left >= 0) & (down >= 0)]
    b = b[(nb(left[b], 3) < 0) & (nb(down[b], 0) < 0)]
    c = idx[(up >= 0) & (right >= 0)]
    c = c[(nb(up[c], 1) < 0) & (nb(right[c], 2) < 0)]
    faces = np.concatenate([np.stack([a, down[a], right[a]], 1), np.stack([up[d], left[d], d], 1),
                            np.stack([left[b], down[b], b], 1), np.stack([up[c], c, right[c]], 1)])
    return faces[np.argsort(faces.max(axis=1), kind="stable")]


def test_faces_match_the_numpy_reference_on_a_layered_photo():
    img = texture(40, 56, seed=3)
    d = np.ones((40, 56), np.float32)
    d[10:30, 15:40] = 3.0
    d[5:20, 44:52] = 2.0
    photo = photo3d.make(img, depth=d, config=exact_config(border=4))
    assert photo.ldi.size > 40 * 56  # hidden layers: T_b/T_c corners occur
    faces = build_mesh(photo.ldi).faces
    np.testing.assert_array_equal(faces, _faces_numpy(photo.ldi.links))
    assert faces.dtype == np.int32


def test_cut_quads_get_no_triangles_and_edge_ends_get_one():
    d = np.zeros((4, 4), np.float32)
    cuts = np.zeros((4, 4), np.uint8)
    cuts[:2, 1] = 2  # cut between columns 1 and 2 in rows 0-1 only
    m = build_mesh(cut(from_image(np.zeros((4, 4, 3), np.float32), d), cuts))
    # 9 quads: quad (row 0, col 1) loses both triangles, quad (row 1, col 1) has
    # three links left and gets one triangle.
    assert m.faces.shape[0] == 2 * 9 - 2 - 1


def test_vertices_sit_on_pixel_centres_at_their_depth():
    img, d = two_planes(16, 16, 8)
    photo = photo3d.make(img, depth=d, config=exact_config())
    m = photo.mesh()
    k = photo.ldi.intrinsics
    v = m.vertices[: 16 * 16]
    x = v[:, 0] / v[:, 2] * k.fx + k.cx - 0.5
    y = v[:, 1] / v[:, 2] * k.fy + k.cy - 0.5
    np.testing.assert_allclose(x.reshape(16, 16), np.tile(np.arange(16), (16, 1)), atol=1e-4)
    np.testing.assert_allclose(y.reshape(16, 16), np.tile(np.arange(16)[:, None], (1, 16)),
                               atol=1e-4)
    expected = unproject(photo.ldi.x, photo.ldi.y, photo.ldi.depth(), k)
    np.testing.assert_array_equal(m.vertices, expected)


def test_mesh_rendered_at_the_input_camera_reproduces_the_input_image():
    img = texture(60, 90, seed=7)
    d = np.ones((60, 90), np.float32)
    d[15:45, 30:60] = 3.0  # a box in front
    d[20:40, 5:20] = 2.0
    photo = photo3d.make(img, depth=d, config=exact_config(border=6, edge_dilation=0))
    m = photo.mesh()
    frag = rasterize(m.vertices, m.colors, m.faces, photo.ldi.intrinsics)
    assert frag.mask.all()
    expected = np.round(img * 255) / 255
    np.testing.assert_allclose(frag.color, expected, atol=1e-5)
    # and the depth is the input depth
    np.testing.assert_allclose(frag.depth.reshape(-1), photo.ldi.depth()[: 60 * 90], rtol=1e-5)
