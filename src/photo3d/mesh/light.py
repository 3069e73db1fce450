"""LDI -> light textured mesh: geometry to an error bound, colours in a texture.

The full mesh (:func:`photo3d.mesh.full.build_mesh`) has one vertex per LDI pixel: 3
million triangles for a 1024 px photo. The light mesh keeps its look from the
camera positions a 3D photo is seen from, at a few percent of the triangles:

* Charts: faces whose three pixels are all the first pixel at their lattice
  position (the input view and its extrapolated border) use the photo itself as
  texture, with the pixel positions (the camera projection) as texture
  coordinates. Every other face is given a *layer image* that holds its three
  pixels at their positions (:func:`photo3d.mesh._charts.claim_faces`), and a chart: its
  layer image's ``block x block`` square of the lattice. Vertices are duplicated
  per chart, so chart borders are texture seams.
* Geometry: edge-collapse simplification (:mod:`photo3d.mesh._simplify`, a port of
  meshoptimizer's: vertices stay where they are; open borders and seams only
  collapse along themselves) on the points
  ``(column, row, f * parallax / z)``: image position and parallax in pixels of the
  input view, with an absolute error bound ``max_error``. So a flat area becomes a
  few large triangles while depth edges, silhouettes and thin structures keep their
  outline to within the bound, for any camera shift up to ``parallax``. Every vertex
  is an LDI pixel, exactly where the full mesh has it. Before that, lattice blocks
  (32 to 2 pixels) that are whole in one layer and planar to within
  ``PLANAR_SHARE * max_error`` become fans from their centre to the border pixels
  that their neighbours need (:mod:`photo3d.mesh._planar`): about a third of the
  triangles reach the simplifier, which runs on four strips in the budget's threads.
* Texture: one sRGB image, the photo on the lattice at the top left, the charts
  (each with a one-texel gutter, holes filled from their neighbours) beside and
  below it.

A large triangle's texture is interpolated perspective-correctly (linear in 3D)
while the photo maps onto it projectively: where depth varies across a triangle the
two differ. The simplifier bounds that drift by ``max_error`` too (seen from the
input view, along every edge it makes); without that bound the sample's frames were
about 3 dB further from the full mesh's at the same triangle count. The benchmark
(``benchmarks/bench_light.py``) measures the whole effect on rendered frames.

Why edge collapses and not a height-field triangulation: an error-bounded
right-triangulated irregular network (Martini-style) over each layer was tried
first; it is fast, but it cannot simplify a staircase outline, so every pixel on a
depth edge, silhouette or layer seam stays a vertex: 650-760k triangles for the
sample against edge collapses' 86k at the same 0.5 px bound.

The result's faces list the input layer first, as the full mesh does.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from photo3d.errors import InputError
from photo3d.holes import fill_holes
from photo3d.mesh._charts import chart_vertices, claim_faces, fill_charts, pixel_ranks
from photo3d.mesh._planar import merged_faces, planar_blocks, quad_counts
from photo3d.mesh._simplify import simplify as _simplify
from photo3d.mesh.full import build_mesh
from photo3d.parallel import overlap
from photo3d.structures.ldi import LDI
from photo3d.structures.mesh import Mesh, TexturedMesh

_GUTTER = 1
_BLOCKS = (32, 2)  # sides of the planar blocks merged before the simplifier
_LAYER_ROOM = 1  # spare layer images first allocated per layer (doubled if short)
PLANAR_SHARE = 0.3
"""Planarity bound of those blocks, as a share of ``max_error``."""
LIGHT_ERROR = 0.5
"""Default error bound of the light mesh, pixels (benchmarks/RESULTS.md: light mesh)."""


KERNEL_MODULES = ("photo3d.mesh._faces", "photo3d.mesh._planar", "photo3d.mesh._charts",
                  "photo3d.mesh._collapse")
"""The modules whose numba kernels (their ``KERNELS``) :func:`build_light_mesh` runs."""


def load_kernels() -> None:
    """Load (or compile) :func:`build_light_mesh`'s numba kernels in the calling
    thread: before a worker thread builds the mesh, so that loading them (about 1 s,
    which a signal cannot interrupt in a worker thread) happens where Ctrl-C and
    SIGTERM stop it at once.

    Example:
        >>> load_kernels()
    """
    import importlib

    from numba.core.sigutils import normalize_signature

    for module in KERNEL_MODULES:
        for kernel, signature in getattr(importlib.import_module(module), "KERNELS", ()):
            if hasattr(kernel, "compile"):  # not with NUMBA_DISABLE_JIT
                # the argument types as a tuple, as a call gives them (numba's cache key)
                kernel.compile(tuple(normalize_signature(signature)[0]))


def build_light_mesh(ldi: LDI, *, max_error: float = LIGHT_ERROR, parallax: float = 0.03,
                     block: int = 64, full: Mesh | None = None) -> TexturedMesh:
    """Simplify the LDI's mesh to an error bound, with its colours in a texture.

    Args:
        ldi: the layered depth image.
        max_error: bound in pixels of the input view on how far the light surface
            may move from the full mesh's (measured in image position and in
            parallax for a camera shift of ``parallax``); 0 keeps every vertex.
        parallax: the camera shift (depth units) the bound is stated for; the
            authors' paths move by at most 0.05 forward and 0.015 sideways.
        block: side of the hidden layers' texture charts, in pixels.
        full: :func:`build_mesh` of ``ldi`` if already built (saves its time).

    Returns:
        :class:`TexturedMesh` whose vertices are LDI pixels (labels and positions
        those of :func:`build_mesh`). The faces of soft silhouettes (a vertex with
        ``alpha < 1``) are left out of it and kept, vertex-coloured and unsimplified,
        as its ``overlay`` (:meth:`~photo3d.structures.mesh.Mesh.split_fringe`).

    Example:
        >>> from photo3d.stages.ldi import from_image
        >>> ldi = from_image(np.full((40, 40, 3), 0.5, np.float32),
        ...                  np.full((40, 40), 0.5, np.float32))
        >>> light = build_light_mesh(ldi)
        >>> len(light.faces) < len(build_mesh(ldi).faces) // 10
        True
    """
    if not all(isinstance(v, int | float | np.integer | np.floating) and not isinstance(v, bool)
               for v in (max_error, parallax)) or not (0 <= max_error < np.inf
                                                      and 0 < parallax < np.inf):
        raise InputError(f"need max_error >= 0 and parallax > 0 (finite numbers), got "
                         f"{max_error!r}, {parallax!r}")
    if block < 2:
        raise InputError(f"block must be >= 2, got {block}")
    full = build_mesh(ldi) if full is None else full
    full, overlay = full.split_fringe()  # the soft silhouettes stay full, drawn blended
    rows, cols = ldi.lattice_shape
    pos = ldi.positions()
    rank = _ranks(pos, rows * cols)
    n_layers = int(rank.max()) + 1 if ldi.size else 1
    faces = full.faces  # int32; the kernels take either
    face_layer = np.zeros(len(faces), np.int64)
    deep = rank > 0
    hidden = deep[faces[:, 0]] | deep[faces[:, 1]] | deep[faces[:, 2]]
    room = n_layers + max(1, _LAYER_ROOM * n_layers)  # the sample needs 18 for 9 layers
    while True:
        images = np.full((room, rows * cols), -1, np.int32)
        images[rank, pos] = np.arange(ldi.size)
        try:
            face_layer[hidden], n_layers = claim_faces(faces[hidden], pos, rank, images,
                                                       n_layers)
            break
        except ValueError:  # more layer images needed than there was room for
            room *= 2
    if max_error > 0:
        k = ldi.intrinsics
        value = max(k.fx, k.fy) * parallax / full.vertices[:, 2]
        faces, face_layer = _merge_planar(faces, face_layer, pos, (rows, cols), images[:n_layers],
                                          value, PLANAR_SHARE * max_error)
    light = _textured(ldi, full, faces, face_layer, images[:n_layers], block,
                      max_error=float(max_error), parallax=float(parallax))
    return light if overlay is None else replace(light, overlay=overlay)


def _merge_planar(faces: np.ndarray, face_layer: np.ndarray, pos: np.ndarray,
                  shape: tuple[int, int],
                  images: np.ndarray, value: np.ndarray,
                  eps: float) -> tuple[np.ndarray, np.ndarray]:
    """Faces and their layer images with every lattice block whose ``value`` is
    planar within ``eps`` replaced by a fan (:mod:`photo3d.mesh._planar`): the same
    surface to within ``eps`` in far fewer triangles for the simplifier."""
    if not len(faces):
        return faces, face_layer
    rows, cols = shape
    py, px = np.divmod(pos, cols)
    some = faces[:10_000]  # all faces are wound alike: a sample tells which way
    f0 = some[:, 0]
    cross = ((px[some[:, 1]] - px[f0]) * (py[some[:, 2]] - py[f0])
             - (py[some[:, 1]] - py[f0]) * (px[some[:, 2]] - px[f0]))
    sign = 1 if np.median(np.sign(cross)) > 0 else -1
    cnt = quad_counts(faces, face_layer, py, px, len(images), rows, cols)
    blocks = planar_blocks(cnt, images, value.astype(np.float64), rows, cols, float(eps),
                           _BLOCKS[0], _BLOCKS[-1])
    return merged_faces(faces, face_layer, py, px, cnt, cols, blocks, images, sign)


def _ranks(pos: np.ndarray, n_positions: int) -> np.ndarray:
    """``(N,) int64`` index of each pixel among the pixels at its position (LDI order).

    Example:
        >>> _ranks(np.array([2, 0, 2, 2, 0]), 3).tolist()
        [0, 0, 1, 2, 1]
    """
    return pixel_ranks(np.ascontiguousarray(pos, np.int64), n_positions)


def _textured(ldi: LDI, full: Mesh, faces: np.ndarray, face_layer: np.ndarray,
              images: np.ndarray, block: int, *, max_error: float,
              parallax: float) -> TexturedMesh:
    """Charts, per-chart vertices, simplification and texture of ``faces``."""
    rows, cols = ldi.lattice_shape
    order = np.argsort(face_layer > 0, kind="stable")  # input layer first
    faces, face_layer = faces[order], face_layer[order]
    n_flat = len(faces) - int(np.count_nonzero(face_layer))
    pos = ldi.positions()
    py, px = np.divmod(pos, cols)
    # chart of each hidden face: its layer and the block holding its centroid
    deep = faces[n_flat:]
    cy = py[deep].sum(axis=1) // 3 // block
    cx = px[deep].sum(axis=1) // 3 // block
    nbx = -(-cols // block)
    key = (face_layer[n_flat:] * (-(-rows // block)) + cy) * nbx + cx
    charts, chart_of = np.unique(key, return_inverse=True)
    chart = np.full(len(faces), -1, np.int64)
    chart[n_flat:] = chart_of
    slot = block + 1 + 2 * _GUTTER
    slot_y, slot_x, tex_h, tex_w = _pack(len(charts), slot, rows, cols)
    c_layer, c_rest = np.divmod(charts, (-(-rows // block)) * nbx)
    c_by, c_bx = np.divmod(c_rest, nbx)
    with overlap(name="texture") as pool:  # the texture meanwhile
        texture = pool.submit(_texture, images, full.colors, (rows, cols), (tex_h, tex_w),
                              c_layer, c_by * block, c_bx * block, slot_y, slot_x, block)
        # vertices: one per (pixel, chart)
        corners, pixel, vchart = chart_vertices(faces, chart, ldi.size)
        k = ldi.intrinsics
        points = np.stack([px[pixel], py[pixel],
                           max(k.fx, k.fy) * parallax / full.vertices[pixel, 2]], 1)
        faces = _simplify(points, corners, max_error, position=pixel, drift=True)
        texture = texture.result()
    input_face = vchart[faces[:, 0]] == 0
    faces = faces[np.argsort(~input_face, kind="stable")]  # input layer first
    n_input = int(np.count_nonzero(input_face))
    used = np.zeros(len(pixel), bool)
    used[faces] = True
    renumber = np.cumsum(used) - 1
    faces = renumber[faces]
    pixel, vchart = pixel[used], vchart[used] - 1
    tx = px[pixel].astype(np.float64)
    ty = py[pixel].astype(np.float64)
    hid = vchart >= 0
    origin_y = slot_y + _GUTTER - c_by * block  # texel row = lattice row + origin
    origin_x = slot_x + _GUTTER - c_bx * block
    tx[hid] += origin_x[vchart[hid]]
    ty[hid] += origin_y[vchart[hid]]
    uv = np.stack([(tx + 0.5) / tex_w, (ty + 0.5) / tex_h], 1).astype(np.float32)
    return TexturedMesh(
        vertices=full.vertices[pixel], uv=uv, texture=texture, labels=full.labels[pixel],
        faces=faces.astype(np.int32), n_input=n_input, width=full.width,
        height=full.height, hfov=full.hfov, vfov=full.vfov,
    )


def _texture(images: np.ndarray, colors: np.ndarray, shape: tuple[int, int],
             size: tuple[int, int], c_layer: np.ndarray, c_y: np.ndarray, c_x: np.ndarray,
             slot_y: np.ndarray, slot_x: np.ndarray, block: int) -> np.ndarray:
    """``(T, U, 3) uint8`` the texture: layer image 0 (the photo on the lattice) at the
    top left, and chart ``i`` (layer image ``c_layer[i]``'s ``block`` square at lattice
    ``(c_y[i], c_x[i])``, with its gutter) at texel ``(slot_y[i], slot_x[i])``."""
    rows, cols = shape
    texture = np.zeros((*size, 3), np.uint8)
    texture[:rows, :cols] = _filled(images[0], colors, rows, cols)
    if len(c_layer):
        g = np.arange(-_GUTTER, block + 1 + _GUTTER)
        ly = np.clip(c_y[:, None] + g[None, :], 0, rows - 1)  # (C, slot)
        lx = np.clip(c_x[:, None] + g[None, :], 0, cols - 1)
        flat = ly[:, :, None] * cols + lx[:, None, :]  # (C, slot, slot)
        texels = fill_charts(images[c_layer[:, None, None], flat], colors)
        slot = len(g)
        ty = slot_y[:, None, None] + np.arange(slot)[None, :, None]
        tx = slot_x[:, None, None] + np.arange(slot)[None, None, :]
        texture[ty, tx] = texels
    return texture


def _pack(n: int, slot: int, rows: int, cols: int) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Places of ``n`` square slots beside and below a ``rows x cols`` block at the
    top-left, in a texture about as wide as it is high.

    Returns:
        ``(slot_y (n,), slot_x (n,))`` top-left texels, and the texture height, width.

    Example:
        >>> y, x, h, w = _pack(3, 10, 20, 20)
        >>> (h, w), y.tolist(), x.tolist()
        ((30, 30), [0, 10, 20], [20, 20, 0])
    """
    side = int(np.ceil(np.sqrt(rows * cols + n * slot * slot)))
    width = max(cols + slot * max(0, -(-(side - cols) // slot)), slot)
    right = (width - cols) // slot  # slot columns beside the block
    beside = right * (rows // slot)
    index = np.arange(n)
    first = index < beside
    r, c = np.divmod(index, max(right, 1))
    below_r, below_c = np.divmod(index - beside, width // slot)
    slot_y = np.where(first, r * slot, rows + below_r * slot)
    slot_x = np.where(first, cols + c * slot, below_c * slot)
    height = max(rows, int(slot_y.max()) + slot if n else rows)
    return slot_y.astype(np.int64), slot_x.astype(np.int64), height, width


def _filled(image: np.ndarray, colors: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """``(rows, cols, 3) uint8`` colours of a layer image, holes filled smoothly."""

    known = image >= 0
    out = np.zeros((rows * cols, 3), np.float32)
    out[known] = colors[image[known]]
    if known.all():
        return out.reshape(rows, cols, 3).astype(np.uint8)
    filled = fill_holes(out.reshape(rows, cols, 3), known.reshape(rows, cols).astype(np.float32))
    return np.clip(np.rint(filled), 0, 255).astype(np.uint8)
