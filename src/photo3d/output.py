"""Saving and reloading 3D photos as a folder, atomically.

A 3D photo folder holds ``photo3d.npz`` (the LDI, lossless), ``mesh.ply``
(binary by default, the authors' header; one vertex per LDI pixel), ``mesh.glb``
(the light textured mesh of :mod:`photo3d.mesh.light`, or the full vertex-coloured mesh
with ``full_glb``), ``viewer.html`` (interactive, self-contained) and ``config.json``
(everything that changes the output, see :func:`photo_meta`), videos in ``video/``
(rendered from the light mesh, with either backend; see benchmarks/RESULTS.md) and
the ``exports`` asked for (:mod:`photo3d.export`: splats, USDZ, a quilt).
Everything is written into a temporary sibling folder first and moved into place at
the end (:mod:`photo3d.files.staging`), so an interrupted or failed run never leaves a
half-written output folder, and ``overwrite`` only ever replaces a folder holding
nothing but these files.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from photo3d.config import Config
from photo3d.errors import InputError, OutputError
from photo3d.files.atomic import write_json
from photo3d.files.staging import Staging, stage_output
from photo3d.io.bounded import read_json
from photo3d.io.gltf import write_glb
from photo3d.io.gltf_textured import write_textured_glb
from photo3d.io.npz import load_npz, save_npz
from photo3d.io.ply import write_ply
from photo3d.mesh.light import LIGHT_ERROR, build_light_mesh
from photo3d.owned import FINISHED_FILES, LDI_FILE, claim_files, owned_photo, record_files
from photo3d.parallel import thread_pool
from photo3d.save_options import SaveOptions
from photo3d.structures.ldi import LDI

if TYPE_CHECKING:
    from photo3d.export import Format
    from photo3d.render.animate import VideoSpec
    from photo3d.render.renderer import RenderSettings
    from photo3d.structures.mesh import Mesh, TexturedMesh

class SavedPhoto(Protocol):
    """What is saved of a 3D photo (a :class:`photo3d.Photo3D`)."""

    ldi: LDI
    config: Config
    stats: dict
    timings: dict
    inpainter: dict
    depth_source: str | None

    def mesh(self) -> Mesh: ...


def is_complete(out: str | Path) -> bool:
    """True if ``out`` is a finished 3D photo folder.

    Folders are written atomically (:func:`stage_photo`), so a folder holding
    :data:`FINISHED_FILES` is complete; ``photo3d batch`` skips such folders.

    Example:
        >>> import tempfile
        >>> is_complete(Path(tempfile.mkdtemp()))
        False
    """
    out = Path(out)
    return out.is_dir() and all((out / name).is_file() for name in FINISHED_FILES)


def check_output(out: str | Path, *, overwrite: bool, inputs: Sequence[str | Path] = (),
                 need_bytes: int = 0) -> Path:
    """Raise :class:`OutputError` early if ``out`` cannot become a 3D photo folder.

    Runs every check of :func:`stage_photo` (a temporary folder is created and
    removed again, so permissions and read-only file systems are caught) and returns
    ``out`` as a Path. Use :func:`stage_photo` to keep the temporary folder and write.

    Example:
        >>> import pathlib, tempfile
        >>> check_output(pathlib.Path(tempfile.mkdtemp()) / "o", overwrite=False).name
        'o'
    """
    with stage_photo(out, overwrite=overwrite, inputs=inputs, need_bytes=need_bytes):
        pass
    return Path(out)


def stage_photo(out: str | Path, *, overwrite: bool, inputs: Sequence[str | Path] = (),
                need_bytes: int = 0) -> Staging:
    """Check ``out`` before the work and create the temporary folder to write it in.

    See :func:`photo3d.files.staging.stage_output` (``inputs``: files the run reads,
    which the output may not hold; ``overwrite`` only replaces a 3D photo folder).
    Use the result in a ``with`` block and pass it to :func:`save_photo` as ``out``.

    Example:
        >>> import pathlib, tempfile
        >>> with stage_photo(pathlib.Path(tempfile.mkdtemp()) / "o", overwrite=False) as s:
        ...     s.path.name.startswith(".o.")
        True
    """
    return stage_output(out, overwrite=overwrite, inputs=inputs, owned=owned_photo,
                        need_bytes=need_bytes)


def save_photo(photo: SavedPhoto, out: str | Path | Staging,
               options: SaveOptions | None = None, *, overwrite: bool = False,
               progress: Callable[[str, float], None] | None = None) -> Path:
    """Write a 3D photo folder atomically.

    Args:
        photo: the 3D photo.
        out: destination folder; must not exist or be empty unless ``overwrite``
            (which only replaces a 3D photo folder). Or the :class:`Staging` that
            :func:`stage_photo` returned before the work.
        options: which files and how (:class:`~photo3d.save_options.SaveOptions`;
            default: ``mesh.ply`` binary, the light ``mesh.glb``, ``viewer.html``, no
            videos).
        progress: ``progress(stage, fraction)`` with stages ``save`` and ``video``.

    Returns:
        ``out`` as a :class:`~pathlib.Path`.

    Example:
        >>> import photo3d, numpy as np, tempfile, pathlib
        >>> photo = photo3d.make(np.zeros((16, 16, 3)), depth=np.ones((16, 16)),
        ...                      config=photo3d.Config(size=None))
        >>> tmp = pathlib.Path(tempfile.mkdtemp()) / "out"
        >>> sorted(p.name for p in save_photo(photo, tmp, SaveOptions(ply=None)).iterdir())
        ['config.json', 'mesh.glb', 'photo3d.npz', 'viewer.html']
    """
    options = options or SaveOptions()
    staging = out if isinstance(out, Staging) else stage_photo(out, overwrite=overwrite)
    with staging:
        try:
            _write_photo(photo, staging.path, title=staging.final.name, options=options,
                         progress=progress)
        except OSError as err:
            raise OutputError(f"cannot write {staging.out}: {err.strerror or err}") from None
        staging.commit()
    return Path(staging.out)


def light_error(options: SaveOptions) -> float:
    """The light mesh's error bound of ``options`` (its default when None).

    Example:
        >>> light_error(SaveOptions()) == LIGHT_ERROR, light_error(SaveOptions(light_error=2))
        (True, 2)
    """
    return LIGHT_ERROR if options.light_error is None else options.light_error


def _write_photo(photo: SavedPhoto, tmp: Path, *, title: str, options: SaveOptions,
                 progress) -> None:
    """Write the files of a 3D photo folder into ``tmp``.

    The meshes are built in this thread; the files are written by up to two writer
    threads (:func:`~photo3d.parallel.thread_pool`) as soon as what they hold is
    ready (``photo3d.npz`` first, its deflate and the writes release the GIL), so
    writing overlaps building the light mesh. The
    ``exports`` are written by the same threads, from the meshes built here, before
    the folder is committed: a failed export leaves no folder."""
    meta = photo_meta(photo, options)
    if options.exports:
        from photo3d.export import preload

        preload([fmt for _, fmt in _export_targets(photo.ldi, options)])  # before threads
    with thread_pool(2, name="write") as pool:
        jobs = [pool.submit(save_npz, photo.ldi, tmp / LDI_FILE, meta=meta)]
        write_json(tmp / "config.json", meta)
        mesh, light = _write_meshes(photo, tmp, pool, jobs, title=title, options=options)
        if options.exports:
            light = _write_exports(photo, tmp, pool, jobs, mesh=mesh, light=light,
                                   options=options)
        for job in jobs:
            job.result()
    if progress:
        progress("save", 1.0)
    if options.videos:
        write_videos(photo, _video_mesh(photo, mesh, light, options), tmp, options.videos,
                     settings=options.render_settings, progress=progress)


def photo_meta(photo: SavedPhoto, options: SaveOptions | None = None) -> dict:
    """What ``config.json`` (and the metadata of ``photo3d.npz``) records: everything
    that changes the output.

    Returns:
        ``{"config": the resolved Config, "inpainter": the backend's settings,
        "depth_source": one line or None, "save": {"ply", "glb": "light", "full" or
        None, "light_error", "viewer", "videos": [VideoSpec fields], "render_settings":
        RenderSettings fields or None without videos, "exports": [format names]},
        "stats", "timings", "written": the videos' and the exports' file names}``,
        JSON-able.

    Example:
        >>> import photo3d, numpy as np
        >>> photo = photo3d.make(np.zeros((16, 16, 3)), depth=np.ones((16, 16)),
        ...                      config=photo3d.Config(size=None))
        >>> meta = photo_meta(photo, SaveOptions(full_glb=True))
        >>> list(meta)
        ['config', 'inpainter', 'depth_source', 'save', 'stats', 'timings', 'written']
        >>> meta["save"]["glb"], meta["inpainter"]["name"]
        ('full', 'structured')
        >>> photo_meta(photo, SaveOptions(exports=("quilt", "splats.spz")))["written"]
        ['quilt_qs8x6a0.75.png', 'splats.spz']
    """
    options = options or SaveOptions()
    videos = options.videos
    save = {"ply": options.ply,
            "glb": ("full" if options.full_glb else "light") if options.glb else None,
            "light_error": light_error(options), "viewer": options.viewer,
            "videos": [dataclasses.asdict(v) for v in videos], "render_settings": None,
            "exports": list(options.exports)}
    if options.exports:
        save |= {"splats": options.splats, "spz_version": options.spz_version}
    written = sorted([f"video/{v.name}.{v.format}" for v in videos]
                     + [path for path, _ in _export_targets(photo.ldi, options)])
    if videos:
        from photo3d.render.renderer import RenderSettings

        save["render_settings"] = dataclasses.asdict(options.render_settings
                                                     or RenderSettings())
    return {"config": photo.config.to_dict(), "inpainter": dict(photo.inpainter),
            "depth_source": photo.depth_source, "save": save, "stats": photo.stats,
            "timings": photo.timings, "written": written}


def _video_mesh(photo: SavedPhoto, mesh, light, options: SaveOptions, *,
                folder: Path | None = None):
    """The mesh videos are drawn from: the light textured one, with either backend
    (``light``, or built from ``mesh``). With OpenGL it draws about 3 times faster than
    the full mesh at the same look; with numba, at one sample per pixel antialiased at
    depth edges (``RenderSettings.antialias`` ``auto``), about 3 times faster than the
    full mesh at 2x2 samples, 38-40 dB from it (benchmarks/RESULTS.md, videos).

    With neither mesh given, ``folder``'s ``mesh.glb`` is read back
    (:func:`photo3d.io.light_glb.read_light_glb`, 0.05 s instead of 1.5-2 s to build
    it) when ``config.json`` says it is the light mesh of the same error bound and
    the file is photo3d's, of this photo; otherwise the light mesh is built."""
    if light is not None:
        return light
    max_error = light_error(options)
    if mesh is None and folder is not None:
        from photo3d.io.light_glb import read_light_glb

        try:
            save = read_json(folder / "config.json").get("save")
            if (isinstance(save, dict) and save.get("glb") == "light"
                    and save.get("light_error") == max_error):
                return read_light_glb(folder / "mesh.glb", intrinsics=photo.ldi.intrinsics,
                                      lattice=photo.ldi.lattice_shape)
        except (OSError, ValueError, AttributeError, InputError):
            pass  # not photo3d's light mesh of this photo: built below
    return build_light_mesh(photo.ldi, full=photo.mesh() if mesh is None else mesh,
                            max_error=max_error)


def _write_meshes(photo: SavedPhoto, tmp: Path, pool: Executor, jobs: list, *,
                  title: str, options: SaveOptions) -> tuple[Mesh | None, TexturedMesh | None]:
    """Build the meshes and have ``pool`` write ``mesh.ply``, ``mesh.glb`` and
    ``viewer.html`` as asked into ``tmp`` (their futures are added to ``jobs``);
    returns the full and light meshes if they were built."""
    ply, glb, viewer, full_glb = options.ply, options.glb, options.viewer, options.full_glb
    mesh = photo.mesh() if ply or glb or viewer else None
    light = None
    if ply:
        jobs.append(pool.submit(write_ply, tmp / "mesh.ply", mesh, binary=ply == "binary"))
    if glb and full_glb:
        jobs.append(pool.submit(write_glb, tmp / "mesh.glb", mesh))
    if (glb and not full_glb) or viewer:
        light = build_light_mesh(photo.ldi, full=mesh, max_error=light_error(options))
    if glb and not full_glb:
        jobs.append(pool.submit(write_textured_glb, tmp / "mesh.glb", light))
    if viewer:  # here: on a writer thread beside mesh.glb, the save took 0.15 s longer
        from photo3d.viewer import write_viewer

        write_viewer(light, tmp / "viewer.html", title=title)
    return mesh, light


def _export_targets(ldi: LDI, options: SaveOptions) -> list[tuple[str, Format]]:
    """``(file name, Format)`` of each of ``options.exports``
    (:data:`photo3d.export.FORMATS`)."""
    if not options.exports:
        return []
    from photo3d.export import check_formats

    return [(fmt.filename(ldi), fmt) for fmt in check_formats(options.exports)]


def _write_exports(photo: SavedPhoto, tmp: Path, pool: Executor, jobs: list, *,
                   mesh: Mesh | None, light: TexturedMesh | None,
                   options: SaveOptions) -> TexturedMesh | None:
    """Have ``pool`` write ``options.exports`` into ``tmp`` (their futures added to
    ``jobs``) with :func:`photo3d.export.submit_writers`, from the light mesh already
    built (built here from ``mesh`` if a format takes it and it is not); returns the
    light mesh, so that the videos are drawn from the same one."""
    from photo3d.export import submit_writers

    targets = _export_targets(photo.ldi, options)
    if light is None and any("mesh" in fmt.options for _, fmt in targets):
        light = build_light_mesh(photo.ldi, full=mesh, max_error=light_error(options))
    jobs += submit_writers(pool, photo.ldi, [(fmt, tmp / name) for name, fmt in targets],
                           mesh=light, density=options.splats,
                           spz_version=options.spz_version)
    return light


def write_videos(photo: SavedPhoto, mesh, folder: Path, videos: Sequence[VideoSpec], *,
                 settings: RenderSettings | None = None,
                 progress: Callable[[str, float], None] | None = None) -> list[Path]:
    """Render ``videos`` of ``photo`` into ``folder/video/`` (one renderer for all).

    ``mesh``: the mesh to draw, a full :class:`~photo3d.structures.mesh.Mesh` or a light
    :class:`~photo3d.structures.mesh.TexturedMesh`; None: the light one, read from
    ``folder/mesh.glb`` when that is photo3d's light mesh of this photo and of the
    default error bound, else built here (see :func:`_video_mesh`).

    Nothing is written through a symbolic link, and no file photo3d did not write is
    replaced: a ``video`` that is a link, or a video name that is a link or a file
    ``config.json`` does not list (:mod:`photo3d.owned`), is refused (OutputError)
    before anything is rendered. The videos written are added to that list.
    """
    from photo3d.files.atomic import refuse_symlink
    from photo3d.kernel_cache import adopt
    from photo3d.render.animate import render_video
    from photo3d.render.renderer import Renderer

    adopt()  # the wheel's compiled kernels, if they fit (once per process)
    refuse_symlink(folder / "video")
    names = [f"video/{spec.name}.{spec.format}" for spec in videos]
    claim_files(folder, names)
    try:
        (folder / "video").mkdir(exist_ok=True)
        written = []
        if mesh is None:
            mesh = _video_mesh(photo, None, None, SaveOptions(render_settings=settings),
                               folder=folder)
        with Renderer(mesh, settings) as renderer:
            for i, spec in enumerate(videos):
                def on_frame(done: int, total: int, i: int = i) -> None:
                    if progress:
                        progress("video", (i + done / total) / len(videos))

                target = folder / "video" / f"{spec.name}.{spec.format}"
                written.append(render_video(renderer, photo.ldi, spec, target,
                                            progress=on_frame))
        record_files(folder, names)
    except OSError as err:
        raise OutputError(f"cannot write videos in {folder}: {err.strerror or err}") from None
    return written


def read_folder(path: str | Path) -> tuple[LDI, dict]:
    """The LDI and the metadata (:func:`photo_meta`; folders saved before it recorded
    ``inpainter``, ``depth_source`` and ``save`` hold only ``config``, ``stats`` and
    ``timings``) of a 3D photo folder or of its ``photo3d.npz``;
    :func:`photo3d.load` makes a Photo3D of them.

    Raises:
        InputError: there is no 3D photo at ``path``.
    """
    path = Path(path)
    if path.is_dir():
        path = path / LDI_FILE
    if not path.exists():
        raise InputError(f"no 3D photo at {path}")
    return load_npz(path)
