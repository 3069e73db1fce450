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

SPLAT_DENSITIES = ("adaptive", "dense")
"""What ``splats`` may be (:data:`photo3d.export.splats.DENSITIES`, the default first)."""
SPZ_VERSIONS = (3, 4)
"""What ``spz_version`` may be (3, the default: docs/outputs.md says why)."""


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
        splats: the splat exports' layout: ``"adaptive"`` (fewer, larger splats
            where the photo is flat) or ``"dense"`` (one per LDI pixel).
        spz_version: the version of ``splats.spz``: 3 (gzip) or 4 (zstd streams).
        splat_fit: the splat exports' colours are fitted to photo3d's render through
            a splat renderer's blend (:mod:`photo3d.export.splat_fit`; the default:
            False keeps each splat's colour as its pixels').

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
        >>> SaveOptions(spz_version=2)
        Traceback (most recent call last):
        ...
        photo3d.errors.ConfigError: spz_version must be 3 or 4, got 2
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
    splats: str = "adaptive"
    spz_version: int = 3
    splat_fit: bool = True

    def __post_init__(self) -> None:
        if isinstance(self.videos, str | bytes) or not hasattr(self.videos, "__iter__"):
            raise ConfigError(f"videos must be a list of photo3d.render.animate.VideoSpec s, "
                              f"got {self.videos!r}")
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
        if self.splats not in SPLAT_DENSITIES:
            raise ConfigError(f"splats must be one of {', '.join(SPLAT_DENSITIES)}, "
                              f"got {self.splats!r}")
        if self.spz_version not in SPZ_VERSIONS or isinstance(self.spz_version, bool):
            raise ConfigError(f"spz_version must be 3 or 4, got {self.spz_version!r}")
        for name in ("glb", "full_glb", "viewer", "splat_fit"):  # "false" is true
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{name} must be True or False, got {getattr(self, name)!r}")
        error = self.light_error
        if error is not None and (isinstance(error, bool) or not isinstance(error, int | float)
                                  or not 0 <= error < float("inf")):
            raise ConfigError(f"light_error must be a number of pixels >= 0 or None, "
                              f"got {error!r}")
        self._check_rendering()

    def _check_rendering(self) -> None:
        """``videos`` are VideoSpec s and ``render_settings`` a RenderSettings or None
        (imported only then: this module stays light)."""
        if self.videos:
            from photo3d.render.animate import VideoSpec

            wrong = [v for v in self.videos if not isinstance(v, VideoSpec)]
            if wrong:
                raise ConfigError(f"videos must be photo3d.render.animate.VideoSpec s, "
                                  f"got {wrong[0]!r}")
        if self.render_settings is not None:
            from photo3d.render.renderer import RenderSettings

            if not isinstance(self.render_settings, RenderSettings):
                raise ConfigError(f"render_settings must be a photo3d.render.renderer."
                                  f"RenderSettings or None, got a "
                                  f"{type(self.render_settings).__name__}")

    def with_(self, **changes) -> SaveOptions:
        """A copy with fields replaced (:func:`dataclasses.replace`); an unknown field
        is a :class:`~photo3d.errors.ConfigError` naming the known ones.

        Example:
            >>> SaveOptions().with_(glb=False).glb
            False
        """
        known = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise ConfigError(f"unknown save option {unknown[0]!r}; the options are "
                              f"{', '.join(sorted(known))}")
        return dataclasses.replace(self, **changes)
