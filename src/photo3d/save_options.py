"""What a 3D photo folder holds besides the LDI: one frozen object, passed whole from the
command line (:class:`~photo3d.folder.MakeOptions`) to the writer
(:func:`photo3d.output.save_photo`), and recorded in ``config.json``'s ``save``.

This module imports nothing heavy (the command line reads it before the pipeline).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

from photo3d.errors import ConfigError

if TYPE_CHECKING:
    from photo3d.render.animate import VideoSpec
    from photo3d.render.renderer import RenderSettings

PLY_KINDS = ("binary", "ascii", None)
"""What ``ply`` may be (None: no ``mesh.ply``)."""

EXPORT_FORMATS = ("splats.ply", "splats.spz", "splats.glb", "mesh.usdz", "quilt")
"""What ``exports`` may hold: the names of :data:`photo3d.export.FORMATS` (spelled out
here so that this module stays light; a test checks they agree)."""


@dataclass(frozen=True)
class SaveOptions:
    """The files of a 3D photo folder and how they are made.

    Attributes:
        ply: ``"binary"``, ``"ascii"`` or None (no ``mesh.ply``).
        glb: write ``mesh.glb``.
        full_glb: ``mesh.glb`` is the full vertex-coloured mesh (one vertex per LDI
            pixel) instead of the light textured one.
        light_error: error bound of the light mesh in pixels (None:
            :data:`photo3d.mesh.light.LIGHT_ERROR`).
        viewer: write ``viewer.html``.
        videos: the videos to render (:class:`~photo3d.render.animate.VideoSpec` s).
        render_settings: how videos are rendered (None: defaults).
        exports: formats of :mod:`photo3d.export` written into the folder too
            (:data:`EXPORT_FORMATS`: ``"splats.spz"``, ``"mesh.usdz"``, ...; repeats
            are written once), as ``photo3d export`` writes them.

    Example:
        >>> options = SaveOptions(ply=None, viewer=False)
        >>> options.glb, options.ply, dataclasses.replace(options, glb=False).glb
        (True, None, False)
        >>> SaveOptions(ply="text")
        Traceback (most recent call last):
        ...
        photo3d.errors.ConfigError: ply must be 'binary', 'ascii' or None, got 'text'
        >>> SaveOptions(exports=["splats.spz", "quilt", "splats.spz"]).exports
        ('splats.spz', 'quilt')
        >>> SaveOptions(exports=["splats.obj"])  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        photo3d.errors.ConfigError: unknown export format 'splats.obj'; choose from splats.ply, ...
    """

    ply: str | None = "binary"
    glb: bool = True
    full_glb: bool = False
    light_error: float | None = None
    viewer: bool = True
    videos: tuple[VideoSpec, ...] = ()
    render_settings: RenderSettings | None = None
    exports: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "videos", tuple(self.videos))
        if self.ply not in PLY_KINDS:
            raise ConfigError(f"ply must be 'binary', 'ascii' or None, got {self.ply!r}")
        exports = () if self.exports is None else self.exports
        if isinstance(exports, str | bytes):
            raise ConfigError(f"exports must be a list of format names, got {exports!r}")
        unknown = [n for n in exports if not isinstance(n, str) or n not in EXPORT_FORMATS]
        if unknown:
            raise ConfigError(f"unknown export format {unknown[0]!r}; choose from "
                              + ", ".join(EXPORT_FORMATS))
        object.__setattr__(self, "exports", tuple(dict.fromkeys(exports)))

    def with_(self, **changes) -> SaveOptions:
        """A copy with fields replaced (:func:`dataclasses.replace`)."""
        return dataclasses.replace(self, **changes)
