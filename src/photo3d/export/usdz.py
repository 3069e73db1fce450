"""``mesh.usdz``: the light textured mesh for AR Quick Look (iPhone, iPad, Vision Pro).

:func:`write_usdz` writes the light mesh (:mod:`photo3d.mesh.light`, the one in
``mesh.glb``) with usd-core (extra ``photo3d[usdz]``) in the conventions AR Quick Look
reads:

* the stage is Y-up in metres (``upAxis = "Y"``, ``metersPerUnit = 1``); positions
  are the OpenCV camera frame turned to Y-up, ``(x, -y, -z)`` as in the glTF, so the
  photo faces +Z, towards whoever looks at it;
* the mesh is scaled so that the input view's frame at the focus depth (the median
  depth of the photo's own pixels, :func:`~photo3d.export.quilt.focus_depth`) is
  :data:`FRAME_WIDTH` metres across its longer side, and moved so that the bottom
  centre of that frame is the origin, which AR Quick Look puts on the floor or
  table: the subject stands there as large as a 1 m print, with what lies behind
  it further back (on the bundled sample the far background is 33 m behind);
* one ``UsdPreviewSurface`` material shows the texture (an sRGB JPEG read through
  ``UsdUVTexture`` and a ``UsdPrimvarReader_float2`` of ``st``) as its emissive
  colour over a black diffuse colour, so the photo keeps its colours whatever the
  light of the room, as the glTF's unlit material does;
* the root prim ``/photo3d`` (kind ``component``) is the default prim; the package
  is made by ``UsdUtils.CreateNewARKitUsdzPackage`` (the layer as ``.usdc`` first,
  then the texture, uncompressed and 64-byte aligned).

usd-core's ARKit compliance checker reports no errors on it (tests/export/test_usdz.py).
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from photo3d.errors import InputError, OutputError, require
from photo3d.export.quilt import focus_depth
from photo3d.files.atomic import atomic_path, open_write
from photo3d.io.gltf_textured import encode_jpeg
from photo3d.structures.ldi import LDI

if TYPE_CHECKING:
    from photo3d.structures.mesh import TexturedMesh

USDZ_NAME = "mesh.usdz"
"""File name of the USDZ in a 3D photo folder."""

FRAME_WIDTH = 1.0
"""Default physical size, metres, of the input view's frame at the focus depth
(its longer side)."""

_TO_USD = np.array([1.0, -1.0, -1.0])  # OpenCV (x, y, z) -> Y-up (x, -y, -z)


def write_usdz(ldi: LDI, path: str | Path, *, mesh: TexturedMesh | None = None,
               frame_width: float = FRAME_WIDTH, quality: int = 90) -> None:
    """Write the light textured mesh of ``ldi`` as a USDZ package for AR Quick Look.

    Args:
        ldi: the 3D photo's layered depth image.
        path: the ``.usdz`` file to write (written to a temporary sibling, then
            renamed over it).
        mesh: the light mesh of ``ldi`` if already built
            (:func:`~photo3d.mesh.light.build_light_mesh`); built here otherwise.
        frame_width: metres across the longer side of the input view's frame at the
            focus depth (see the module doc).
        quality: JPEG quality of the texture (1-95).

    Raises:
        MissingExtra: usd-core is not installed (``pip install 'photo3d[usdz]'``).
        InputError: the mesh is empty or ``frame_width`` is not positive.
        OutputError: ``path`` cannot be written.

    Example:
        >>> import numpy as np, tempfile, pathlib, zipfile
        >>> from photo3d.stages.ldi import from_image
        >>> ldi = from_image(np.full((16, 24, 3), 0.5, np.float32), np.ones((16, 24), np.float32))
        >>> path = pathlib.Path(tempfile.mkdtemp()) / USDZ_NAME
        >>> write_usdz(ldi, path)
        >>> [name.rsplit(".", 1)[1] for name in zipfile.ZipFile(path).namelist()]
        ['usdc', 'jpg']
    """
    pxr = _import_pxr()
    if not frame_width > 0:
        raise InputError(f"frame_width must be positive, got {frame_width}")
    with (atomic_path(path, follow_symlinks=False) as tmp,  # checks the target first
          tempfile.TemporaryDirectory(prefix="photo3d-usdz-") as work):
        if mesh is None:
            from photo3d.mesh.light import build_light_mesh

            mesh = build_light_mesh(ldi)
        vertices, uv, _, faces = mesh.checked()
        if len(vertices) == 0 or len(faces) == 0:
            raise InputError("mesh has no vertices or no faces; USDZ cannot store it")
        points = usd_points(ldi, vertices, frame_width=frame_width)
        st = np.column_stack([uv[:, 0], 1.0 - uv[:, 1]]).astype(np.float32)  # USD: v up
        layer = Path(work) / "photo3d.usdc"
        with open_write(Path(work) / "texture.jpg") as file:
            file.write(encode_jpeg(np.asarray(mesh.texture), quality=quality))
        _write_stage(pxr, layer, points, st, faces)
        if mesh.overlay is not None:  # the soft silhouettes, blended (displayOpacity)
            _write_fringe(pxr, layer, mesh.overlay, usd_points(
                ldi, mesh.overlay.checked()[0], frame_width=frame_width))
        if not pxr.UsdUtils.CreateNewARKitUsdzPackage(str(layer), str(tmp)):
            raise OutputError(f"cannot write {path}: usd-core could not make the package")

def _write_fringe(pxr, layer: Path, fringe, points: np.ndarray) -> None:
    """Add the soft silhouettes (a :class:`~photo3d.structures.mesh.Mesh` with
    ``alpha``) to the saved stage: /photo3d/fringe with vertex ``displayColor``
    (linear) and ``displayOpacity``, an unlit-looking preview surface reading them."""
    Sdf, Usd, UsdGeom, UsdShade, Vt = pxr.Sdf, pxr.Usd, pxr.UsdGeom, pxr.UsdShade, pxr.Vt
    from photo3d.io.glb import srgb_to_linear

    _, colors, _, faces = fringe.checked()
    stage = Usd.Stage.Open(str(layer))
    geom = _triangles(pxr, stage, "/photo3d/fringe", points, faces)
    primvars = UsdGeom.PrimvarsAPI(geom)
    primvars.CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray,
                           UsdGeom.Tokens.vertex).Set(
        Vt.Vec3fArray.FromNumpy(srgb_to_linear(colors)))
    primvars.CreatePrimvar("displayOpacity", Sdf.ValueTypeNames.FloatArray,
                           UsdGeom.Tokens.vertex).Set(
        Vt.FloatArray.FromNumpy(np.clip(fringe.alpha, 0.0, 1.0).astype(np.float32)))
    material = UsdShade.Material.Define(stage, "/photo3d/fringe_material")
    surface = UsdShade.Shader.Define(stage, "/photo3d/fringe_material/surface")
    surface.CreateIdAttr("UsdPreviewSurface")
    for name, kind, reader_id in (("displayColor", Sdf.ValueTypeNames.Color3f,
                                   "UsdPrimvarReader_float3"),
                                  ("displayOpacity", Sdf.ValueTypeNames.Float,
                                   "UsdPrimvarReader_float")):
        reader = UsdShade.Shader.Define(stage, f"/photo3d/fringe_material/{name}")
        reader.CreateIdAttr(reader_id)
        reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set(name)
        output = reader.CreateOutput("result", kind)
        target = "emissiveColor" if name == "displayColor" else "opacity"
        surface.CreateInput(target, kind).ConnectToSource(output)
    surface.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(pxr.Gf.Vec3f(0, 0, 0))
    surface.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(1.0)
    material.CreateSurfaceOutput().ConnectToSource(surface.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(geom.GetPrim()).Bind(material)
    stage.GetRootLayer().Save()


def usd_points(ldi: LDI, vertices: np.ndarray, *, frame_width: float = FRAME_WIDTH
               ) -> np.ndarray:
    """``(N, 3) float32`` the mesh's OpenCV ``vertices`` as USDZ positions: Y-up, metres,
    the bottom centre of the input view's frame at the focus depth at the origin.

    Example:
        >>> from photo3d.stages.ldi import from_image
        >>> ldi = from_image(np.zeros((4, 8, 3), np.float32), np.ones((4, 8), np.float32))
        >>> z = float(ldi.depth()[0])  # a flat photo: every pixel at the focus depth
        >>> usd_points(ldi, np.array([[0.0, 0.0, z], [0.0, 0.0, 2 * z]], np.float32)).round(3)
        array([[ 0.  ,  0.25, -0.  ],
               [ 0.  ,  0.25, -1.  ]], dtype=float32)
    """
    k = ldi.intrinsics
    focus = focus_depth(ldi)
    metres = frame_width / (focus * max(k.width / k.fx, k.height / k.fy))  # per depth unit
    bottom = (k.height - k.cy) / k.fy * focus  # OpenCV y of the frame's lower edge
    origin = np.array([0.0, bottom, focus])
    return ((vertices - origin) * _TO_USD * metres).astype(np.float32)


def require_usd() -> None:
    """Raise :class:`~photo3d.errors.MissingExtra` now if usd-core is not installed
    (``make``, ``batch`` and ``export`` ask before any work).

    Example:
        >>> try:
        ...     require_usd()
        ... except ImportError as err:  # an extra
        ...     assert "photo3d[usdz]" in str(err)
    """
    require("pxr.UsdUtils", "usdz", purpose="writing USDZ", package="usd-core")


def _import_pxr():
    """The pxr modules :func:`write_usdz` uses (usd-core), or MissingExtra."""
    require_usd()
    from types import SimpleNamespace

    from pxr import Gf, Kind, Sdf, Usd, UsdGeom, UsdShade, UsdUtils, Vt

    return SimpleNamespace(Gf=Gf, Kind=Kind, Sdf=Sdf, Usd=Usd, UsdGeom=UsdGeom,
                           UsdShade=UsdShade, UsdUtils=UsdUtils, Vt=Vt)


def _triangles(pxr, stage, name: str, points: np.ndarray, faces: np.ndarray):
    """A ``UsdGeom.Mesh`` at ``name`` of ``stage``: triangles ``faces (M, 3)`` over
    ``points (N, 3)``, not subdivided, one-sided, with its extent."""
    UsdGeom, Vt = pxr.UsdGeom, pxr.Vt
    geom = UsdGeom.Mesh.Define(stage, name)
    geom.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points))
    geom.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, np.int32)))
    geom.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(faces.reshape(-1)))
    geom.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    geom.CreateDoubleSidedAttr(False)
    lo, hi = points.min(axis=0), points.max(axis=0)
    geom.CreateExtentAttr(Vt.Vec3fArray([pxr.Gf.Vec3f(*map(float, lo)),
                                         pxr.Gf.Vec3f(*map(float, hi))]))
    return geom


def _write_stage(pxr, layer: Path, points: np.ndarray, st: np.ndarray,
                 faces: np.ndarray) -> None:
    """The stage: /photo3d (Xform, component) holding the mesh and its material."""
    Sdf, Usd, UsdGeom, UsdShade, Vt = pxr.Sdf, pxr.Usd, pxr.UsdGeom, pxr.UsdShade, pxr.Vt
    stage = Usd.Stage.CreateNew(str(layer))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/photo3d")
    stage.SetDefaultPrim(root.GetPrim())
    Usd.ModelAPI(root.GetPrim()).SetKind(pxr.Kind.Tokens.component)

    geom = _triangles(pxr, stage, "/photo3d/photo", points, faces)
    primvar = UsdGeom.PrimvarsAPI(geom).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                      UsdGeom.Tokens.vertex)
    primvar.Set(Vt.Vec2fArray.FromNumpy(st))

    material = UsdShade.Material.Define(stage, "/photo3d/material")
    reader = UsdShade.Shader.Define(stage, "/photo3d/material/st")
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
    texture = UsdShade.Shader.Define(stage, "/photo3d/material/texture")
    texture.CreateIdAttr("UsdUVTexture")
    texture.CreateInput("file", Sdf.ValueTypeNames.Asset).Set("./texture.jpg")
    texture.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("sRGB")
    texture.CreateInput("wrapS", Sdf.ValueTypeNames.Token).Set("clamp")
    texture.CreateInput("wrapT", Sdf.ValueTypeNames.Token).Set("clamp")
    texture.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(
        reader.ConnectableAPI(), "result")
    rgb = texture.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
    surface = UsdShade.Shader.Define(stage, "/photo3d/material/surface")
    surface.CreateIdAttr("UsdPreviewSurface")
    surface.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(pxr.Gf.Vec3f(0, 0, 0))
    surface.CreateInput("emissiveColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(rgb)
    surface.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(1.0)
    surface.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
    material.CreateSurfaceOutput().ConnectToSource(surface.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(geom.GetPrim()).Bind(material)
    stage.GetRootLayer().Save()
