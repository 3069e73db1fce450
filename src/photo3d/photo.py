"""The result of :func:`photo3d.make`: a :class:`Photo3D` (the inpainted LDI and how it
was made), with the views of it a user asks for (meshes, renders) and its folder on
disk (:mod:`photo3d.output`)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from photo3d.camera import Camera
from photo3d.config import Config
from photo3d.errors import ConfigError, InputError
from photo3d.files.staging import Staging
from photo3d.mesh.full import build_mesh
from photo3d.save_options import SaveOptions
from photo3d.structures.ldi import LDI
from photo3d.structures.mesh import Mesh

if TYPE_CHECKING:
    from photo3d.render.renderer import RenderSettings, View
    from photo3d.structures.mesh import TexturedMesh


@dataclass
class Photo3D:
    """A 3D photo: the inpainted LDI plus how it was made.

    Attributes:
        ldi: the layered depth image.
        config: the configuration that produced it.
        timings: seconds per stage.
        stats: counts (edges per pass, pixels added, ...).
        inpainter: the inpainting backend's settings, JSON-able (its ``settings()``:
            name, and for ``learned`` the weights and their SHA-256, precision, ...);
            empty for a photo saved before they were recorded.
        depth_source: where the depth came from, one line (a
            :attr:`~photo3d.depth.sources.DepthEstimate.source`), or None if unknown.
    """

    ldi: LDI
    config: Config
    timings: dict[str, float] = field(default_factory=dict)
    stats: dict[str, object] = field(default_factory=dict)
    inpainter: dict[str, object] = field(default_factory=dict)
    depth_source: str | None = None

    def mesh(self) -> Mesh:
        """The triangle mesh of the LDI (see :func:`photo3d.mesh.full.build_mesh`)."""
        return build_mesh(self.ldi)

    def light_mesh(self, *, max_error: float | None = None) -> TexturedMesh:
        """The light textured mesh (see :func:`photo3d.mesh.light.build_light_mesh`).

        Example:
            >>> import numpy as np, photo3d
            >>> photo = photo3d.make(np.full((32, 32, 3), 0.5), depth=np.ones((32, 32)),
            ...                      config=photo3d.Config(size=None))
            >>> len(photo.light_mesh().faces) < len(photo.mesh().faces)
            True
        """
        from photo3d.mesh.light import LIGHT_ERROR, build_light_mesh

        return build_light_mesh(self.ldi, max_error=LIGHT_ERROR if max_error is None
                                else max_error)

    def render(self, camera: Camera, *, settings: RenderSettings | None = None) -> View:
        """Render a novel view.

        Args:
            camera: intrinsics (output size) and camera-from-world pose; the input
                view is ``Camera(photo.ldi.intrinsics, np.eye(4))``.
            settings: :class:`~photo3d.render.renderer.RenderSettings` (default:
                2x supersampling, holes filled, automatic backend).

        Returns:
            :class:`~photo3d.render.renderer.View` with ``color (H, W, 3)``,
            ``depth (H, W)`` and the coverage ``mask (H, W)``.

        Raises:
            InputError: ``camera`` is no camera
                (:func:`~photo3d.render.renderer.check_camera`).
            ConfigError: the view needs more memory than is available
                (:func:`photo3d.resources.check_render_memory`), or bad ``settings``.

        For many views of one photo use :class:`~photo3d.render.renderer.Renderer`
        directly: it prepares the mesh once.

        Example:
            >>> import numpy as np, photo3d
            >>> photo = photo3d.make(np.full((16, 16, 3), 0.5), depth=np.ones((16, 16)),
            ...                      config=photo3d.Config(size=None))
            >>> cam = Camera.translated(photo.ldi.intrinsics, (0.01, 0.0, 0.0))
            >>> photo.render(cam).color.shape
            (16, 16, 3)
        """
        from photo3d.render.renderer import Renderer, RenderSettings, check_camera
        from photo3d.resources import check_render_memory

        check_camera(camera)  # then the view's memory, before the mesh is built
        k = camera.intrinsics
        ssaa = (settings if isinstance(settings, RenderSettings) else RenderSettings()).ssaa
        check_render_memory(self.ldi.size, (int(k.width), int(k.height)), ssaa=ssaa)
        with Renderer(self.mesh(), settings) as renderer:
            return renderer.render(camera)

    def save(self, out: str | Path, options: SaveOptions | None = None, *,
             overwrite: bool = False, progress=None, **changes) -> Path:
        """Write ``photo3d.npz``, ``mesh.ply``, ``mesh.glb``, ``viewer.html``,
        ``config.json`` and the requested videos (``video/NAME.mp4``) to ``out``,
        atomically.

        Args:
            out: the folder (must not exist or be empty unless ``overwrite``).
            options: :class:`~photo3d.save_options.SaveOptions` (default: its defaults).
            overwrite: replace a 3D photo folder photo3d wrote.
            progress: ``progress(stage, fraction)``.
            changes: fields of ``options`` to replace, e.g. ``glb=False``.

        Raises:
            InputError: ``out`` is no path. ConfigError: ``options`` is no
            :class:`~photo3d.save_options.SaveOptions`, or a change names no field.
            OutputError: see :func:`photo3d.output.save_photo`.

        See :func:`photo3d.output.save_photo`.

        Example:
            >>> import numpy as np, photo3d, tempfile, pathlib
            >>> photo = photo3d.make(np.zeros((16, 16, 3)), depth=np.ones((16, 16)),
            ...                      config=photo3d.Config(size=None))
            >>> out = photo.save(pathlib.Path(tempfile.mkdtemp()) / "o", ply=None, viewer=False)
            >>> sorted(p.name for p in out.iterdir())
            ['config.json', 'mesh.glb', 'photo3d.npz']
        """
        from photo3d.output import save_photo

        if not isinstance(out, Staging):  # (make's own: its staged folder)
            _check_path(out, "out")
        if options is not None and not isinstance(options, SaveOptions):
            raise ConfigError(f"options must be a SaveOptions or None, got a "
                              f"{type(options).__name__} (fields go as keywords: "
                              f"save(out, glb=False))")
        options = (options or SaveOptions()).with_(**changes)
        return save_photo(self, out, options, overwrite=overwrite, progress=progress)

    @classmethod
    def load(cls, path: str | Path) -> Photo3D:
        """Reload a saved 3D photo (a folder or its ``photo3d.npz``)."""
        return load(path)


def load(path: str | Path) -> Photo3D:
    """Reload a 3D photo from its folder or its ``photo3d.npz``.

    Folders saved before the inpainter's settings and the depth source were
    recorded load with ``inpainter == {}`` and ``depth_source is None``; so do
    damaged optional records (``timings``, ``stats``, ``inpainter`` that are not
    dictionaries).

    Raises:
        InputError: no 3D photo at ``path``, a damaged ``photo3d.npz`` or a saved
            configuration that is not a valid :class:`~photo3d.config.Config`.

    Example:
        >>> import photo3d, numpy as np, tempfile, pathlib
        >>> photo = photo3d.make(np.zeros((16, 16, 3)), depth=np.ones((16, 16)),
        ...                      config=photo3d.Config(size=None))
        >>> tmp = photo.save(pathlib.Path(tempfile.mkdtemp()) / "out", glb=False, ply=None)
        >>> back = photo3d.load(tmp)
        >>> back.ldi.size == photo.ldi.size, back.inpainter["name"], back.depth_source
        (True, 'structured', 'depth array (disparity)')
    """
    from photo3d.output import read_folder

    _check_path(path, "path")
    ldi, meta = read_folder(path)
    config = meta.get("config", {})
    if not isinstance(config, dict):
        raise InputError(f"cannot read 3D photo {path}: its saved configuration is a "
                         f"{type(config).__name__}, not a dictionary")
    try:
        config = Config.from_dict(config)
    except (ValueError, TypeError) as err:
        raise InputError(f"cannot read 3D photo {path}: {err}") from None

    def table(key: str) -> dict:  # optional records: a damaged one is dropped
        value = meta.get(key)
        return value if isinstance(value, dict) else {}

    source = meta.get("depth_source")
    return Photo3D(ldi=ldi, config=config, timings=table("timings"), stats=table("stats"),
                   inpainter=table("inpainter"),
                   depth_source=source if isinstance(source, str) else None)


def _check_path(value, name: str) -> None:
    """Refuse a ``value`` that is no path (``str`` or ``os.PathLike``), naming it."""
    if not isinstance(value, str | os.PathLike) or not os.fspath(value):
        raise InputError(f"{name} must be a folder path (str or pathlib.Path), got {value!r}")
