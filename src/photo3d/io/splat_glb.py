"""Read and write Gaussian splats as binary glTF 2.0 with ``KHR_gaussian_splatting``.

What :func:`write_splat_glb` puts in the file (one mesh, one ``POINTS`` primitive,
the container of :mod:`photo3d.io.glb`):

==========================================  ============================================
attribute                                   data
==========================================  ============================================
``POSITION``                                float32 VEC3, OpenCV ``(x, -y, -z)``: glTF's
                                            y up, camera looking down -z
``KHR_gaussian_splatting:ROTATION``         float32 VEC4 unit quaternion ``(x, y, z, w)``
``KHR_gaussian_splatting:SCALE``            float32 VEC3, standard deviations (linear)
``KHR_gaussian_splatting:OPACITY``          float32 SCALAR in [0, 1]
``KHR_gaussian_splatting:SH_DEGREE_0_COEF_0``  float32 VEC3, the DC term ``(rgb - 0.5) / SH_C0``
``COLOR_0``                                 normalized uint8 VEC4, linear RGB and the
                                            opacity: what viewers without the extension
                                            show as points (the spec's fallback)
==========================================  ============================================

The primitive's extension object names the ``ellipse`` kernel and the
``srgb_rec709_display`` colour space (the DC term is sRGB, as 3DGS trains it), the
two properties the ratified extension requires (KhronosGroup/glTF,
``extensions/2.0/Khronos/KHR_gaussian_splatting``, as edited in April 2026);
``projection`` and ``sortingMethod`` keep their defaults (``perspective``,
``cameraDistance``) and are left out. The
axes turn as in :mod:`photo3d.io.gltf` (a 180 degree rotation about x), so a
Gaussian's rotation ``q = (w, x, y, z)`` becomes ``(w, x, -y, -z)``. The input view is
a perspective camera node at the origin, and the mesh ``extras`` hold its exact
size and field of view.
"""

from __future__ import annotations

import os

import numpy as np

from photo3d.camera import Intrinsics
from photo3d.errors import InputError
from photo3d.io.glb import (
    ARRAY_BUFFER,
    TO_GLTF,
    accessor,
    add_camera,
    pack_arrays,
    read_chunks,
    write_container,
)
from photo3d.structures.splats import SH_C0, Splats

PathLike = str | os.PathLike[str]

EXTENSION = "KHR_gaussian_splatting"
POINTS = 0
ROTATION, SCALE, OPACITY, SH_DC = (f"{EXTENSION}:{name}" for name in
                                   ("ROTATION", "SCALE", "OPACITY", "SH_DEGREE_0_COEF_0"))
_QUATERNION_FLIP = np.array([1, -1, -1, 1], np.float32)  # (x, y, z, w) -> (x, -y, -z, w)


def write_splat_glb(path: PathLike, splats: Splats, *,
                    intrinsics: Intrinsics | None = None) -> None:
    """Write ``splats`` as a GLB with ``KHR_gaussian_splatting`` (see the module doc).

    Args:
        path: file to create.
        splats: the Gaussians, OpenCV axes.
        intrinsics: the input view, stored as the camera node and in the mesh
            extras (None: no camera).

    Raises:
        InputError: the splats are inconsistent.
        OutputError: ``path`` cannot be written.

    Example:
        >>> import pathlib, tempfile
        >>> s = Splats(np.array([[0.1, -0.2, 2.0]]), np.array([[0.2, 0.5, 0.8]]),
        ...            np.array([0.9]), np.full((1, 3), 0.004), np.array([[1.0, 0, 0, 0]]))
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "splats.glb"
        >>> write_splat_glb(path, s, intrinsics=Intrinsics.default(64, 48))
        >>> back = read_splat_glb(path)
        >>> np.allclose(back.positions, s.positions), np.allclose(back.colors, s.colors)
        (True, True)
    """
    positions, colors, opacity, scales, rotations = splats.checked()
    gl_positions = positions * TO_GLTF
    xyzw = np.concatenate([rotations[:, 1:], rotations[:, :1]], axis=1)
    xyzw = xyzw / np.linalg.norm(xyzw, axis=1, keepdims=True) * _QUATERNION_FLIP
    rgba = np.full((len(colors), 4), 255, np.uint8)
    rgba[:, :3] = np.rint(_srgb_to_linear(np.clip(colors, 0, 1)) * 255)
    rgba[:, 3] = np.rint(opacity * 255)  # the extension's fallback: alpha = opacity
    arrays = {  # attribute: (data, type, normalized)
        "POSITION": (gl_positions, "VEC3", False),
        ROTATION: (xyzw.astype(np.float32), "VEC4", False),
        SCALE: (scales, "VEC3", False),
        OPACITY: (opacity, "SCALAR", False),
        SH_DC: (((colors - 0.5) / SH_C0).astype(np.float32), "VEC3", False),
        "COLOR_0": (rgba, "VEC4", True),
    }
    views, accessors, chunks = pack_arrays(
        [(data, kind, ARRAY_BUFFER, None, normalized)
         for data, kind, normalized in arrays.values()])
    accessors[0].update(min=gl_positions.min(axis=0).tolist(),
                        max=gl_positions.max(axis=0).tolist())
    primitive = {"mode": POINTS, "attributes": {name: i for i, name in enumerate(arrays)},
                 "extensions": {EXTENSION: {"kernel": "ellipse",
                                            "colorSpace": "srgb_rec709_display"}}}
    mesh = {"name": "photo3d splats", "primitives": [primitive]}
    document = {
        "asset": {"version": "2.0", "generator": "photo3d"},
        "extensionsUsed": [EXTENSION],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "photo3d", "mesh": 0}],
        "meshes": [mesh],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": sum(len(chunk) for chunk in chunks)}],
    }
    if intrinsics is not None:
        width, height = intrinsics.width, intrinsics.height
        hfov, vfov = intrinsics.fov
        mesh["extras"] = {"width": width, "height": height, "hfov": hfov, "vfov": vfov}
        add_camera(document, vfov, width / height)
    write_container(path, document, chunks)


def read_splat_glb(path: PathLike) -> Splats:
    """Read the first ``KHR_gaussian_splatting`` primitive of a GLB into :class:`Splats`
    (OpenCV axes; node transforms are not applied).

    Raises:
        InputError: the file is not a GLB, or its first primitive is not a Gaussian
            splat primitive with the five attributes.
    """
    document, binary = read_chunks(path)
    try:
        primitive = document["meshes"][0]["primitives"][0]
        attributes = primitive["attributes"]
        if primitive.get("mode") != POINTS or EXTENSION not in primitive.get("extensions", {}):
            raise InputError(f"glTF {path} has no {EXTENSION} point primitive")
        read = {name: accessor(document, binary, attributes[name], path).astype(np.float32)
                for name in ("POSITION", ROTATION, SCALE, OPACITY, SH_DC)}
    except InputError:
        raise
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as err:
        raise InputError(f"glTF {path} has an unexpected structure ({err!r})"[:300]) from None
    if not all(np.isfinite(v).all() for v in read.values()):
        raise InputError(f"glTF {path} has NaN or infinite splat values")
    xyzw = read[ROTATION] * _QUATERNION_FLIP
    return Splats(positions=read["POSITION"] * TO_GLTF,
                  colors=0.5 + SH_C0 * read[SH_DC],
                  opacity=read[OPACITY][:, 0],
                  scales=read[SCALE],
                  rotations=np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1))


def _srgb_to_linear(srgb: np.ndarray) -> np.ndarray:
    """sRGB in [0, 1] -> linear light (IEC 61966-2-1), float32."""
    linear = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    return linear.astype(np.float32)
