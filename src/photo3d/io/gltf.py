"""Write and read glTF 2.0 binary (``.glb``) meshes, with ``json``, ``struct`` and numpy.

What :func:`write_glb` puts in the file:

* ``POSITION``: float32 ``(x, -y, -z)`` of the OpenCV camera coordinates, i.e. a
  180 degree rotation about x into glTF's y-up, camera-looks-down--z axes. A rotation
  keeps the counter-clockwise winding, so faces stay front-facing towards the camera.
* ``COLOR_0``: float32 RGB in *linear* light (glTF vertex colours are linear; sRGB
  stored as-is looks washed out), decoded back to the same sRGB uint8 on reading.
* ``_LABEL``: the authors' vertex labels, uint8 scalar (application attribute; the
  spec forbids only unsigned int for those), one per 4-byte stride as vertex
  attributes must be 4-byte aligned.
* indices: uint16 when every index is below 65535 (the restart value), else uint32.
* an unlit material (``KHR_materials_unlit``; white base colour, metallic 0,
  roughness 1 as fallback), single-sided.
* the input view as a perspective camera node at the origin (identity transform,
  ``yfov = vfov``, ``aspectRatio = width / height``, ``znear = 0.01``); exact
  width, height, hfov, vfov in the mesh's ``extras``.

The textured variant (the light mesh) is in :mod:`photo3d.io.gltf_textured`, the
container in :mod:`photo3d.io.glb`.
"""

from __future__ import annotations

import os
from dataclasses import replace

import numpy as np

from photo3d.errors import InputError
from photo3d.io.glb import (
    ARRAY_BUFFER,
    TO_GLTF,
    TRIANGLES,
    UNLIT,
    WHITE,
    accessor,
    read_chunks,
    read_fringe,
    triangles,
    write_glb_file,
)
from photo3d.structures.mesh import Mesh

PathLike = str | os.PathLike[str]

_DEFAULT_LABEL = 1
_PRIMITIVE = {
    "attributes": {"POSITION": 0, "COLOR_0": 1, "_LABEL": 2},
    "indices": 3,
    "material": 0,
    "mode": TRIANGLES,
}
_MATERIAL = {
    "name": "unlit vertex colours",
    "pbrMetallicRoughness": {
        "baseColorFactor": WHITE,
        "metallicFactor": 0.0,
        "roughnessFactor": 1.0,
    },
    "extensions": {UNLIT: {}},
    "doubleSided": False,
}


def write_glb(path: PathLike, mesh: Mesh) -> None:
    """Write ``mesh`` as a binary glTF 2.0 file for Blender, three.js and web viewers.

    Args:
        path: file to create (overwritten if it exists).
        mesh: vertices ``(N, 3) float32`` finite OpenCV camera coordinates, colors
            ``(N, 3) uint8`` sRGB, labels ``(N,) uint8``, faces ``(M, 3) int32``;
            ``N >= 1`` and ``M >= 1`` (glTF has no empty accessors). Faces touching a
            vertex of ``alpha < 1`` (soft silhouettes) go into a second, blended
            primitive (:func:`photo3d.io.glb.write_glb_file`).

    Raises:
        InputError: the mesh is empty, has wrong shapes, non-finite vertices or
            out-of-range face indices.
        OutputError: ``path`` cannot be written.

    Example:
        >>> import numpy as np, tempfile, pathlib
        >>> from photo3d.mesh.full import Mesh

        >>> mesh = Mesh(np.eye(3, dtype=np.float32), np.zeros((3, 3), np.uint8),
        ...             np.ones(3, np.uint8), np.array([[0, 2, 1]], np.int32),
        ...             4, 3, 0.5, 0.4)
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "mesh.glb"
        >>> write_glb(path, mesh)
        >>> path.read_bytes()[:4]
        b'glTF'
    """
    fringe = None
    if mesh.alpha is not None:  # soft silhouettes: their faces in a second primitive
        faces = np.asarray(mesh.faces, np.int32)
        touch = (np.asarray(mesh.alpha) < 1.0)[faces].any(axis=1)
        if touch.any():
            fringe = replace(mesh, faces=faces[touch])
        mesh = replace(mesh, faces=faces[~touch], alpha=None)
        if fringe is not None:
            fringe = replace(fringe, vertices=mesh.vertices)  # shared: the same array
    vertices, colors, labels, faces = _checked_arrays(mesh)
    arrays = [(_SRGB_TO_LINEAR[colors], "VEC3", ARRAY_BUFFER, None)]
    write_glb_file(path, mesh, vertices, labels, faces, arrays, _PRIMITIVE, _MATERIAL,
                   fringe=fringe)


def read_glb(path: PathLike) -> Mesh:
    """Read a ``.glb`` written by :func:`write_glb` back into a :class:`Mesh`.

    Reads the first primitive of the first mesh (triangles; ``POSITION``, ``COLOR_0``
    linear RGB(A) as float or normalised integers, optional ``_LABEL``); undoes the
    axis and colour conversions. Node transforms are not applied. A second primitive
    (photo3d's soft silhouettes) is appended with its ``alpha`` (sharing the first's
    vertices, as :func:`write_glb` writes it, or after them).

    Args:
        path: a binary glTF 2.0 file.

    Returns:
        The mesh: vertices ``(N, 3) float32`` OpenCV camera coordinates, colors
        ``(N, 3) uint8`` sRGB (white without ``COLOR_0``), labels ``(N,) uint8``
        (1 without ``_LABEL``), faces ``(M, 3) int32``; width, height, hfov, vfov
        from the mesh extras (0 when absent).

    Raises:
        InputError: the file is missing, not a GLB, or uses unsupported features.

    Example:
        >>> import numpy as np, tempfile, pathlib
        >>> from photo3d.mesh.full import Mesh

        >>> colors = np.array([[0, 1, 2], [128, 200, 255], [7, 7, 7]], np.uint8)
        >>> mesh = Mesh(np.eye(3, dtype=np.float32), colors, np.full(3, 4, np.uint8),
        ...             np.array([[0, 2, 1]], np.int32), 4, 3, 0.5, 0.4)
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "mesh.glb"
        >>> write_glb(path, mesh)
        >>> back = read_glb(path)
        >>> back.colors.tolist() == colors.tolist(), back.labels.tolist()
        (True, [4, 4, 4])
    """
    document, binary = read_chunks(path)
    try:
        primitive = document["meshes"][0]["primitives"][0]
        if primitive.get("mode", TRIANGLES) != TRIANGLES or "indices" not in primitive:
            raise InputError(f"glTF {path} primitive is not indexed triangles")
        attributes = primitive["attributes"]
        positions = accessor(document, binary, attributes["POSITION"], path)
        count = len(positions)
        faces = triangles(document, binary, primitive["indices"], path, count)
        colors = np.full((count, 3), 255, np.uint8)
        if "COLOR_0" in attributes:
            colors = _linear_to_srgb(accessor(document, binary, attributes["COLOR_0"], path))
        labels = np.full(count, _DEFAULT_LABEL, np.uint8)
        if "_LABEL" in attributes:
            labels = accessor(document, binary, attributes["_LABEL"], path,
                              kinds=(5121,))[:, 0]
        extras = document["meshes"][0].get("extras", {})
        view = [float(extras.get(k, 0)) for k in ("width", "height", "hfov", "vfov")]
        if not all(np.isfinite(v) and 0 <= v < 2**31 for v in view):
            raise InputError(f"glTF {path} has an invalid view in its extras")
        if len(colors) != count or len(labels) != count:
            raise InputError(f"glTF {path} has attributes of different lengths")
        if not np.isfinite(positions).all():
            raise InputError(f"glTF {path} has NaN or infinite positions")
        if any(
            node.get("mesh") == 0 and {"matrix", "translation", "rotation", "scale"} & set(node)
            for node in document.get("nodes", [])
        ):
            raise InputError(f"glTF {path} places its mesh with a node transform (unsupported)")
    except InputError:
        raise
    except (KeyError, IndexError, TypeError, ValueError, AttributeError, OverflowError) as err:
        raise InputError(f"glTF {path} has an unexpected structure ({err!r})"[:300]) from None
    if positions.shape[1] != 3:
        raise InputError(f"glTF {path} has positions of another shape")
    mesh = Mesh(
        vertices=(positions * TO_GLTF).astype(np.float32),
        colors=colors,
        labels=labels.astype(np.uint8),
        faces=faces.astype(np.int32),
        width=int(view[0]),
        height=int(view[1]),
        hfov=view[2],
        vfov=view[3],
    )
    try:
        fringe = read_fringe(document, binary, path, extras)
    except InputError:
        raise
    except (KeyError, IndexError, TypeError, ValueError, AttributeError, OverflowError) as err:
        raise InputError(f"glTF {path} has an unexpected structure ({err!r})"[:300]) from None
    if fringe is None:
        return mesh
    if document["meshes"][0]["primitives"][1]["attributes"]["POSITION"] == attributes[
            "POSITION"]:  # photo3d's full mesh: the same vertices, with their alpha
        return replace(mesh, faces=np.concatenate([mesh.faces, fringe.faces]),
                       alpha=fringe.alpha)
    return replace(  # the soft silhouettes' vertices after the others, with their alpha
        mesh, vertices=np.concatenate([mesh.vertices, fringe.vertices]),
        colors=np.concatenate([mesh.colors, fringe.colors]),
        labels=np.concatenate([mesh.labels, fringe.labels]),
        faces=np.concatenate([mesh.faces, fringe.faces + count]),
        alpha=np.concatenate([np.ones(count, np.float32), fringe.alpha]))


def _srgb_to_linear_table() -> np.ndarray:
    """``(256,) float32`` linear value of each sRGB uint8 level (IEC 61966-2-1)."""
    srgb = np.arange(256) / 255.0
    linear = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    return linear.astype(np.float32)


_SRGB_TO_LINEAR = _srgb_to_linear_table()


def _linear_to_srgb(linear: np.ndarray) -> np.ndarray:
    """``(N, C >= 3)`` linear float colours -> ``(N, 3) uint8`` sRGB, rounded (NaN: 0)."""
    if linear.shape[1] < 3:
        raise ValueError(f"COLOR_0 has {linear.shape[1]} components")
    with np.errstate(invalid="ignore"):  # a signalling NaN in a damaged file
        value = np.clip(np.nan_to_num(linear[:, :3].astype(np.float64)), 0.0, 1.0)
    srgb = np.where(value <= 0.0031308, value * 12.92, 1.055 * value ** (1 / 2.4) - 0.055)
    return np.rint(srgb * 255.0).astype(np.uint8)


def _checked_arrays(mesh: Mesh) -> tuple[np.ndarray, ...]:
    """:meth:`Mesh.checked` plus what glTF cannot store (empty or non-finite data)."""
    arrays = mesh.checked()
    if len(arrays[0]) == 0 or len(arrays[3]) == 0:
        raise InputError("mesh has no vertices or no faces; glTF cannot store it")
    if not np.isfinite(arrays[0]).all():
        raise InputError("mesh.vertices has NaN or infinite values")
    return arrays


#END
