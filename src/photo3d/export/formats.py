"""The export formats: each one's name, writer (by module path, imported only when
asked for: usd-core is needed only for ``mesh.usdz``), file name and options
(:data:`FORMATS`). A writer is ``writer(ldi, path, **options)`` and writes exactly
``path``, atomically."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass

from photo3d.structures.ldi import LDI


@dataclass(frozen=True)
class Format:
    """One export format.

    Attributes:
        name: what users ask for (``"splats.ply"``).
        module: the module holding its writer (imported only when used).
        writer: the writer's name in ``module``: ``writer(ldi, path, **options)``
            writes ``path`` atomically.
        filename: ``filename(ldi) -> str``, the file's name in a 3D photo folder.
        options: the keyword options the writer takes (of :func:`export_folder`'s,
            ``splats``, the splats built once when several splat formats are
            written, and ``mesh``, the light textured mesh, built once).
        preload: modules the writer imports that must be imported before the
            writer threads start (:func:`photo3d.export.writers.preload`).
        suffix: what a file of this format must end with (``".ply"``; a file named
            with ``-o`` too, case aside); empty: any name.

    Example:
        >>> FORMATS["splats.spz"].filename(None), FORMATS["quilt"].suffix
        ('splats.spz', '.png')
    """

    name: str
    module: str
    writer: str
    filename: Callable[[LDI], str]
    options: tuple[str, ...] = ()
    preload: tuple[str, ...] = ()
    suffix: str = ""

    def load(self) -> Callable[..., None]:
        """The writer function (imports its module)."""
        return getattr(importlib.import_module(self.module), self.writer)


def _fixed(name: str) -> Callable[[LDI], str]:
    return lambda ldi: name


def _named_by(module: str, attribute: str) -> Callable[[LDI], str]:
    """A file name defined in ``module``: a string, or a function of the LDI."""
    def filename(ldi: LDI) -> str:
        value = getattr(importlib.import_module(module), attribute)
        return value(ldi) if callable(value) else value

    return filename


SPLATS_MODULE = "photo3d.export.splats"
"""The module of the three splat formats' writers."""
_SPLAT_OPTIONS = ("density", "fit", "splats")  # splats: built once for several splat formats
_MESH_OPTIONS = ("mesh",)  # the light textured mesh, built once for all that take it
_USD = ("pxr.Gf", "pxr.Kind", "pxr.Sdf", "pxr.Usd", "pxr.UsdGeom", "pxr.UsdShade",
        "pxr.UsdUtils", "pxr.Vt")  # what write_usdz imports (usd-core)
FORMATS: dict[str, Format] = {
    "splats.ply": Format("splats.ply", SPLATS_MODULE, "write_ply", _fixed("splats.ply"),
                         _SPLAT_OPTIONS, suffix=".ply"),
    "splats.spz": Format("splats.spz", SPLATS_MODULE, "write_spz", _fixed("splats.spz"),
                         (*_SPLAT_OPTIONS, "spz_version"), suffix=".spz"),
    "splats.glb": Format("splats.glb", SPLATS_MODULE, "write_glb", _fixed("splats.glb"),
                         _SPLAT_OPTIONS, suffix=".glb"),
    "mesh.usdz": Format("mesh.usdz", "photo3d.export.usdz", "write_usdz",
                        _named_by("photo3d.export.usdz", "USDZ_NAME"), _MESH_OPTIONS, _USD,
                        suffix=".usdz"),
    "quilt": Format("quilt", "photo3d.export.quilt", "write_quilt",
                    _named_by("photo3d.export.quilt", "quilt_filename"), _MESH_OPTIONS,
                    suffix=".png"),
}
"""The export formats by name, in the order ``photo3d export --help`` lists them
(:data:`photo3d.save_options.EXPORT_FORMATS` spells the same names)."""
