"""Layered scenes with thin structures, cast exactly, for ``bench_edges.py``.

A scene is a stack of fronto-parallel layers (world units: metres; OpenCV axes, the
input camera at the origin looking down +z). Each layer is a plane at depth ``z``
with a shape (a boolean function of the plane's X, Y) and a texture from a real photo
(scikit-image, the motorcycle sample) stretched over 1.3 times the input view's frame
at that depth (the back wall is larger than every view). Views are cast here,
independently of photo3d's renderer: each pixel averages 4 x 4 rays, each ray takes
the colour of the nearest layer whose shape it hits. Poses are translations only (the
four standard paths move, never turn), so every layer stays fronto-parallel in every
view.

The shapes, at the input view (480 x 320, focal 480): poles 2, 3, 6 and 10 px wide, a
slanted 2 px wire, a fence (4 px bars every 14 px and two 3 px rails), foliage (about
40 leaves, ellipses 6-16 px), a box with two rectangular holes and a ring.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

WIDTH, HEIGHT = 480, 320
FOCAL = 480.0
SAMPLES = 4  # rays per pixel along each axis

Shape = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Layer:
    """A plane at depth ``z`` (m) showing ``texture (h, w, 3) float32`` over the box
    ``x0..x1, y0..y1`` (m) where ``shape(X, Y)`` is true."""

    z: float
    shape: Shape
    box: tuple[float, float, float, float]
    texture: np.ndarray


def photos() -> list[np.ndarray]:
    """The textures: ``(h, w, 3) float32`` photos shipped with scikit-image and the
    motorcycle sample's right view."""
    from skimage import data

    from photo3d.sample import motorcycle

    imgs = [data.astronaut(), data.coffee(), data.chelsea(), data.rocket(),
            data.immunohistochemistry(), motorcycle().right * 255]
    return [np.asarray(i, np.float32)[..., :3] / 255.0 for i in imgs]


def _px(px: float, z: float) -> float:
    """World size of ``px`` input-view pixels at depth ``z``."""
    return px * z / FOCAL


def _xy(u: float, v: float, z: float) -> tuple[float, float]:
    """World X, Y at depth ``z`` seen at input pixel ``(u, v)``."""
    return (u - WIDTH / 2) * z / FOCAL, (v - HEIGHT / 2) * z / FOCAL


def _frame(z: float, margin: float = 1.3) -> tuple[float, float, float, float]:
    """The input view's frame at depth ``z``, ``margin`` times as large (a texture
    stretched over it keeps about the photo's own scale)."""
    hw, hh = margin * WIDTH / 2 * z / FOCAL, margin * HEIGHT / 2 * z / FOCAL
    return -hw, hw, -hh, hh


def scene(seed: int) -> list[Layer]:
    """Layers of scene ``seed``, far to near."""
    rng = np.random.default_rng(seed)
    tex = photos()
    order = rng.permutation(len(tex))
    t = [tex[i] for i in order]
    layers = [Layer(9.0, lambda x, y: np.ones(x.shape, bool), _frame(9.0), t[0])]

    z = 6.0  # a box with two holes and a ring
    bx0, by0 = _xy(rng.uniform(20, 60), rng.uniform(20, 60), z)
    bx1, by1 = _xy(rng.uniform(170, 210), rng.uniform(200, 250), z)
    hx0, hy0 = _xy(60 + 0.0, 80, z)
    hx1, hy1 = _xy(110, 130, z)
    gx0, gy0 = _xy(130, 150, z)
    gx1, gy1 = _xy(150, 190, z)
    cx, cy = _xy(rng.uniform(330, 400), rng.uniform(200, 250), z)
    r0, r1 = _px(18, z), _px(38, z)

    def box_ring(x, y, bx0=bx0, bx1=bx1, by0=by0, by1=by1):
        box = (x >= bx0) & (x <= bx1) & (y >= by0) & (y <= by1)
        holes = ((x >= hx0) & (x <= hx1) & (y >= hy0) & (y <= hy1)) | (
            (x >= gx0) & (x <= gx1) & (y >= gy0) & (y <= gy1))
        r2 = (x - cx) ** 2 + (y - cy) ** 2
        return (box & ~holes) | ((r2 >= r0 * r0) & (r2 <= r1 * r1))

    layers.append(Layer(z, box_ring, _frame(z), t[1]))

    z = 4.5  # a fence: bars and rails over the lower right
    fx0, fy0 = _xy(rng.uniform(220, 260), rng.uniform(150, 190), z)
    fx1, fy1 = _xy(470, 330, z)
    period, bar, rail = _px(14, z), _px(4, z), _px(3, z)
    rails = [_xy(0, v, z)[1] for v in (rng.uniform(200, 220), rng.uniform(260, 280))]

    def fence(x, y):
        inside = (x >= fx0) & (x <= fx1) & (y >= fy0) & (y <= fy1)
        bars = np.mod(x - fx0, period) < bar
        rows = np.zeros(x.shape, bool)
        for r in rails:
            rows |= np.abs(y - r) < rail / 2
        return inside & (bars | (rows & (y >= fy0)))

    layers.append(Layer(z, fence, _frame(z), t[2]))

    z = 3.5  # poles 2, 3, 6 and 10 px wide, full height
    us = np.sort(rng.uniform(40, 440, 4))
    poles = [(_xy(u, 0, z)[0], _px(w, z)) for u, w in zip(us, rng.permutation([2, 3, 6, 10]),
                                                          strict=True)]

    def pole(x, y):
        out = np.zeros(x.shape, bool)
        for px, pw in poles:
            out |= np.abs(x - px) < pw / 2
        return out

    layers.append(Layer(z, pole, _frame(z), t[3]))

    z = 3.0  # foliage: leaves (rotated ellipses) around a point in the upper half
    fcx, fcy = rng.uniform(120, 360), rng.uniform(50, 110)
    leaves = []
    for _ in range(40):
        u, v = fcx + rng.normal(0, 35), fcy + rng.normal(0, 22)
        a, b = rng.uniform(3, 8), rng.uniform(1.5, 4)
        leaves.append((*_xy(u, v, z), _px(a, z), _px(b, z), rng.uniform(0, np.pi)))

    def foliage(x, y):
        out = np.zeros(x.shape, bool)
        for lx, ly, a, b, th in leaves:
            dx, dy = x - lx, y - ly
            p = dx * np.cos(th) + dy * np.sin(th)
            q = -dx * np.sin(th) + dy * np.cos(th)
            out |= (p / a) ** 2 + (q / b) ** 2 <= 1.0
        return out

    green = 0.2 + 0.8 * t[4] * np.array([0.6, 1.0, 0.5], np.float32)  # leaf-like tint of a photo
    layers.append(Layer(z, foliage, _frame(z), green))

    z = 2.5  # a 2 px wire, slanted
    wy0, wy1 = rng.uniform(40, 140), rng.uniform(120, 260)
    (ax, ay), (bx, by) = _xy(0, wy0, z), _xy(WIDTH, wy1, z)
    nx, ny = -(by - ay), bx - ax
    norm = np.hypot(nx, ny)
    half = _px(1.0, z)

    def wire(x, y):
        return np.abs((x - ax) * nx + (y - ay) * ny) / norm < half

    wire_tex = np.clip(t[5][::-1] * 0.35, 0, 1)  # dark cable
    layers.append(Layer(z, wire, _frame(z), wire_tex))
    return layers


def _texture_at(tex: np.ndarray, box, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    x0, x1, y0, y1 = box
    h, w = tex.shape[:2]
    u = np.clip(((x - x0) / (x1 - x0) * w).astype(np.int64), 0, w - 1)
    v = np.clip(((y - y0) / (y1 - y0) * h).astype(np.int64), 0, h - 1)
    return tex[v, u]


def cast(layers: list[Layer], camera) -> tuple[np.ndarray, np.ndarray]:
    """View of ``layers`` from ``camera`` (a :class:`photo3d.camera.Camera` whose
    pose is a translation): ``(image (H, W, 3) float32, depth (H, W) float32)``, the
    image averaging 4 x 4 rays per pixel, the depth (camera z) at pixel centres."""
    k, t = camera.intrinsics, camera.pose[:3, 3]
    offsets = (np.arange(SAMPLES) + 0.5) / SAMPLES
    yy, xx = np.mgrid[0:k.height, 0:k.width].astype(np.float64)
    image = np.zeros((k.height, k.width, 3))
    for oy in offsets:
        for ox in offsets:
            image += _cast_rays(layers, (xx + ox - k.cx) / k.fx, (yy + oy - k.cy) / k.fy, t)[0]
    depth = _cast_rays(layers, (xx + 0.5 - k.cx) / k.fx, (yy + 0.5 - k.cy) / k.fy, t)[1]
    return (image / SAMPLES**2).astype(np.float32), depth.astype(np.float32)


def _cast_rays(layers, dx, dy, t):
    """Colour, camera depth and layer index of the rays ``(dx, dy, 1)`` of a camera
    translated by ``t`` (camera = world + t)."""
    col = np.zeros(dx.shape + (3,))
    depth = np.full(dx.shape, np.inf)
    index = np.full(dx.shape, -1)
    for i, layer in enumerate(layers):  # far to near: nearer layers paint over
        s = layer.z + t[2]
        x, y = dx * s - t[0], dy * s - t[1]
        hit = layer.shape(x, y)
        col[hit] = _texture_at(layer.texture, layer.box, x[hit], y[hit])
        depth[hit] = s
        index[hit] = i
    return col, depth, index


def disoccluded(layers: list[Layer], camera, input_camera) -> np.ndarray:
    """``(H, W) bool``: pixels of ``camera``'s view whose surface point (at the pixel
    centre) is hidden from ``input_camera`` by a nearer layer, or outside its frame
    (nothing in the photo shows them)."""
    k, t = camera.intrinsics, camera.pose[:3, 3]
    yy, xx = np.mgrid[0:k.height, 0:k.width].astype(np.float64)
    dx, dy = (xx + 0.5 - k.cx) / k.fx, (yy + 0.5 - k.cy) / k.fy
    _, depth, index = _cast_rays(layers, dx, dy, t)
    wx, wy = dx * depth - t[0], dy * depth - t[1]
    wz = depth - t[2]
    k0 = input_camera.intrinsics
    u, v = wx / wz, wy / wz  # the input camera sits at the origin
    _, _, seen = _cast_rays(layers, u, v, np.zeros(3))
    px, py = u * k0.fx + k0.cx, v * k0.fy + k0.cy
    inside = (px >= 0) & (px < k0.width) & (py >= 0) & (py < k0.height)
    return (seen != index) | ~inside
