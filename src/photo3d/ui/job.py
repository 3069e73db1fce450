"""One request of ``photo3d ui``: uploaded files in, a 3D photo folder and a zip out.

:class:`JobOptions` holds what the page and the API let a client choose (every
field has a default, every value is checked strictly, and nothing in it can name a
file on the server: camera paths are presets only, the inpainter gets no options);
:func:`run_job` makes the photo with :func:`photo3d.folder.make_folder` (the path
``photo3d make`` takes) into a request's folder, writes the depth it used
(:func:`photo3d.depth.export.export_depth`) and zips the result
(:mod:`photo3d.ui.bundle`). Its result carries every warning ``photo3d make`` would
print (:mod:`photo3d.ui.notes`). Nothing here imports Gradio.

A request's folder after :func:`run_job` (which yields the 3D photo first and,
when videos are asked for, again once they are rendered)::

    out/              the 3D photo folder (mesh.glb, splats.spz, viewer.html, photo3d.npz,
                      video/, ...)
    depth.png         the normalised disparity the pipeline used (16-bit)
    depth_preview.png the same in colour (near = yellow)
    NAME-3d.zip       all of the above
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from photo3d.config import EDGES, Config
from photo3d.errors import ConfigError
from photo3d.folder import MakeOptions, output_bytes
from photo3d.save_options import SaveOptions
from photo3d.ui.bundle import safe_stem, zip_folder
from photo3d.ui.progress import StageMeter

FILLS = ("diffusion", "structured", "learned")
"""The inpainting backends a client may choose (docs/fills.md)."""

SOURCES = ("auto", "model")
"""Depth sources: ``auto`` takes the uploaded depth map, else the right view, else the
photo's embedded map, else the depth model; ``model`` runs the depth model even on a
photo with an embedded map."""

CAMERA_PATHS = ("dolly-zoom-in", "zoom-in", "circle", "swing")
"""The camera path presets (:data:`photo3d.render.paths.STANDARD_PATHS`); a client
cannot name a keyframe file."""

MAX_SIZE = 2048
"""Largest working size a client may ask for (the page's slider ends there; the
memory check may refuse less)."""

MAX_PATHS = 16
"""Longest list of camera paths a client may send (repeats are made once)."""

SPLATS = "splats.spz"
"""The splat file every request writes (:mod:`photo3d.export`: Niantic's SPZ, about a
tenth of the PLY's size: 9.6 MB for the bundled sample at 1024 px)."""


class JobCancelled(Exception):
    """The request was cancelled (or the server is stopping); its partial output
    was removed."""


@dataclass(frozen=True)
class JobOptions:
    """What a client chooses for one 3D photo (the defaults are ``photo3d make``'s,
    except that the PLY is off and one video is made; ``splats.spz`` is always
    written, as ``photo3d make --export splats.spz`` writes it).

    Attributes:
        size: working size in pixels (longer side); 0 keeps the photo's size.
        fill: the inpainting backend, one of :data:`FILLS`.
        source: the depth source, one of :data:`SOURCES`.
        depth_kind: what an uploaded depth map holds: ``"disparity"`` (near =
            bright) or ``"depth"``.
        videos: render videos along ``paths`` (True or False).
        paths: camera path presets (:data:`CAMERA_PATHS`), each made once, in the
            order first given (at most :data:`MAX_PATHS` entries).
        ply: also write ``mesh.ply`` (the full mesh, large; True or False).
        edges: where the depth edges go (:attr:`~photo3d.config.Config.edges`):
            ``soft`` (the default: on the photo's colour edges, with soft silhouettes),
            ``align`` (on the colour edges, cut hard) or ``exact``.

    Example:
        >>> options = JobOptions(size=512, paths=["swing"])
        >>> make = options.make_options()
        >>> make.config.size, [v.path for v in make.save.videos], make.save.ply
        (512, ['swing'], None)
        >>> make.config.edges, JobOptions(edges="exact").make_options().config.edges
        ('soft', 'exact')
        >>> make.save.exports
        ('splats.spz',)
        >>> JobOptions(paths=["swing", "circle", "swing"]).paths
        ('swing', 'circle')
        >>> JobOptions(paths=["/etc/passwd"])  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        photo3d.errors.ConfigError: unknown camera path '/etc/passwd': choose from ...
        >>> JobOptions(videos="no")
        Traceback (most recent call last):
        photo3d.errors.ConfigError: videos must be true or false, got 'no'
    """

    size: int = 1024
    fill: str = Config.inpainter
    source: str = "auto"
    depth_kind: str = "disparity"
    videos: bool = True
    paths: tuple[str, ...] = ("circle",)
    ply: bool = False
    edges: str = Config.edges

    def __post_init__(self) -> None:
        paths = () if self.paths is None else self.paths
        if not isinstance(paths, list | tuple) or len(paths) > MAX_PATHS:
            raise ConfigError(f"paths must be a list of at most {MAX_PATHS} camera paths "
                              f"({', '.join(CAMERA_PATHS)})")
        for path in paths:
            _one_of("camera path", path, CAMERA_PATHS)
        object.__setattr__(self, "paths", tuple(dict.fromkeys(paths)))
        size = self.size
        if isinstance(size, float) and size.is_integer():
            object.__setattr__(self, "size", int(size))
        if (isinstance(self.size, bool) or not isinstance(self.size, int)
                or not (self.size == 0 or 64 <= self.size <= MAX_SIZE)):
            raise ConfigError(f"size must be 0 (the photo's size) or 64..{MAX_SIZE}, got {size!r}")
        _one_of("fill", self.fill, FILLS)
        _one_of("depth source", self.source, SOURCES)
        _one_of("depth kind", self.depth_kind, ("disparity", "depth"))
        _one_of("edges", self.edges, EDGES)
        for name in ("videos", "ply"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{name} must be true or false, got {getattr(self, name)!r}")
        if self.videos and not self.paths:
            raise ConfigError("videos are on but no camera path is chosen")

    def make_options(self, weights: Path | None = None) -> MakeOptions:
        """The :class:`~photo3d.folder.MakeOptions` of this request (GLB, viewer and
        :data:`SPLATS` always; videos as ``photo3d make`` renders them; ``weights``:
        the learned fill's weights folder)."""
        from photo3d.render.animate import VideoSpec
        from photo3d.render.renderer import video_settings

        config = Config().with_(size=self.size or None, inpainter=self.fill,
                                edges=self.edges)
        videos = tuple(VideoSpec(path=p) for p in self.paths) if self.videos else ()
        chosen = (("weights", weights),) if weights is not None and self.fill == "learned" else ()
        return MakeOptions(config=config, depth_kind=self.depth_kind, inpainter_options=chosen,
                           save=SaveOptions(ply="binary" if self.ply else None, glb=True,
                                            viewer=True, videos=videos,
                                            render_settings=video_settings(),
                                            exports=(SPLATS,)))


def _one_of(what: str, value: object, allowed: tuple[str, ...]) -> None:
    if not isinstance(value, str) or value not in allowed:
        raise ConfigError(f"unknown {what} {value!r}: choose from {', '.join(allowed)}")


@dataclass(frozen=True)
class JobResult:
    """What one request made, all inside its folder.

    Attributes:
        out: the 3D photo folder.
        glb: ``out/mesh.glb``.
        splats: ``out/splats.spz``, the Gaussian splats (:data:`SPLATS`).
        viewer: ``out/viewer.html``.
        zip: the zip of everything.
        depth_preview: the colour depth map (``(H, W, 3)`` PNG, near = yellow).
        videos: the videos, in the order of the camera paths.
        size: ``(width, height)`` of the working image.
        seconds: wall time of the request.
        summary: one line for people (size, passes, depth source, time).
        warnings: every warning ``photo3d make`` would print, one line each (the
            depth's: flat, inverted, ...; the photo's: decoded at 8 bits, ...).
        notes: its notes (a small photo is upscaled to the working size).
    """

    out: Path
    glb: Path
    splats: Path
    viewer: Path
    zip: Path
    depth_preview: Path
    videos: tuple[Path, ...]
    size: tuple[int, int]
    seconds: float
    summary: str
    warnings: tuple[str, ...] = field(default=())
    notes: tuple[str, ...] = field(default=())

    def status(self) -> str:
        """The summary, then each warning and note on a line of its own (as
        ``photo3d make`` prints them)."""
        return "\n".join([self.summary, *(f"warning: {w}" for w in self.warnings),
                           *(f"note: {n}" for n in self.notes)])


def run_job(photo: Path, folder: Path, *, options: JobOptions, depth: Path | None = None,
            right: Path | None = None, name: str = "photo",
            progress: Callable[[float, str], None] | None = None,
            cancel: threading.Event | None = None) -> Iterator[JobResult]:
    """Make ``photo`` into a 3D photo inside the empty request folder ``folder``.

    A generator: it yields the 3D photo as soon as its folder is written, and, when
    videos are asked for, once more after they are rendered (the videos are added to
    the folder as ``photo3d render`` adds them, and the zip is written again), so
    that the page can show the 3D photo while the videos render.

    Args:
        photo: the photo file (checked by :func:`photo3d.ui.workspace.check_upload`).
        folder: the request's folder (:meth:`photo3d.ui.workspace.Workspace.request`).
        options: the client's choices.
        depth: a depth map file, or None.
        right: the right view of a stereo pair, or None.
        name: the photo's name for the zip (``NAME-3d.zip``; sanitised).
        progress: ``progress(fraction, label)`` with ``fraction`` in [0, 1] over the
            whole request (:class:`~photo3d.ui.progress.StageMeter`).
        cancel: when set, the request stops at its next progress report (the
            caller removes its folder).

    Yields:
        :class:`JobResult` without videos, then (if asked for) with them.

    Raises:
        Photo3DError: a bad file or option (one line; the output folder is not left
            behind).
        JobCancelled: ``cancel`` was set.
    """
    from photo3d.ui.notes import collect_warnings

    with collect_warnings() as notes:
        yield from _run_job(photo, folder, options=options, depth=depth, right=right,
                            name=name, progress=progress, cancel=cancel, notes=notes)


def _run_job(photo, folder, *, options, depth, right, name, progress, cancel,
             notes: list[str]) -> Iterator[JobResult]:
    from photo3d.depth.export import export_depth
    from photo3d.folder import make_folder, prepare

    start = time.perf_counter()
    if depth is not None and right is not None:
        raise ConfigError("give a depth map or a right view, not both")
    if options.source == "model" and (depth is not None or right is not None):
        raise ConfigError("depth source 'model' estimates the depth: remove the uploaded "
                          "depth map or right view, or choose 'auto'")
    meter = StageMeter(videos=options.videos)

    def report(stage: str, fraction: float) -> None:
        if cancel is not None and cancel.is_set():
            raise JobCancelled("the request was cancelled")
        if progress is not None:
            progress(*meter(stage, fraction))

    def say(line: str) -> None:  # a line of its own (the download of weights)
        report("depth", 0.0)  # stops here when cancelled
        if progress is not None:
            progress(0.0, line)

    found: dict = {}

    def on_depth(estimate, image) -> None:
        report("depth", 1.0)
        found["estimate"] = estimate
        found["previews"] = export_depth(estimate, folder / "depth.png")
        found["upscaled"] = _upscaled(image.shape[:2], make.config.size)

    report("depth", 0.0)
    weights = None
    if options.fill == "learned":
        from photo3d.ui.learned import learned_weights

        weights = learned_weights(say)
    make = options.make_options(weights)
    inpainter = prepare(make)
    depth_model = None
    if options.source == "model":
        from photo3d.depth.fetch import default_depth_model

        depth_model = default_depth_model()
    out = folder / "out"
    still = dataclasses.replace(make, save=dataclasses.replace(make.save, videos=()))
    photo3d = make_folder(photo, out, options=still, depth=depth, right=right,
                          depth_model=depth_model, inpainter=inpainter, progress=report,
                          on_depth=on_depth,
                          need_bytes=output_bytes(make.config, make.save))
    bundle = folder / f"{safe_stem(name)}-3d.zip"
    zip_folder(out, bundle, extra=found["previews"], progress=lambda f: report("zip", f))
    uploads = [p for p in (photo, depth, right) if p is not None]
    estimate = found["estimate"]
    w, h = photo3d.stats["working_size"]
    said = [*estimate.warnings, *notes]
    result = JobResult(out=out, glb=out / "mesh.glb", splats=out / SPLATS,
                       viewer=out / "viewer.html", zip=bundle,
                       depth_preview=found["previews"][1], videos=(), size=(w, h),
                       seconds=time.perf_counter() - start, summary="",
                       warnings=tuple(dict.fromkeys(redact(n, uploads) for n in said)),
                       notes=tuple(found["upscaled"]))
    line = (f"{w}x{h}, {photo3d.stats['passes']} inpainting pass(es), depth from "
            f"{redact(estimate.source, uploads)}")
    if not make.save.videos:
        yield dataclasses.replace(result, summary=f"3D photo made in {result.seconds:.1f} s: "
                                                  f"{line}")
        return
    yield dataclasses.replace(result, summary=f"3D photo made in {result.seconds:.1f} s "
                                              f"({line}); rendering the videos...")
    from photo3d.output import write_videos

    videos = write_videos(photo3d, None, out, make.save.videos,
                          settings=make.save.render_settings,
                          progress=report)
    zip_folder(out, bundle, extra=found["previews"], progress=lambda f: report("rezip", f))
    seconds = time.perf_counter() - start
    said = [*result.warnings, *(redact(n, uploads) for n in notes)]
    result = dataclasses.replace(result, warnings=tuple(dict.fromkeys(said)))
    yield dataclasses.replace(result, videos=tuple(videos), seconds=seconds,
                              summary=f"3D photo and {len(videos)} video(s) made in "
                                      f"{seconds:.1f} s: {line}")


def _upscaled(shape: tuple[int, int], size: int | None) -> list[str]:
    """The note ``photo3d make`` prints when a photo is smaller than the working size.

    Example:
        >>> _upscaled((240, 320), 1024)
        ['the photo is 320x240; it is upscaled to a 1024x768 working size (size 0 keeps its size)']
    """
    from photo3d.config import working_shape

    if size is None or max(shape) >= size:
        return []
    h, w = working_shape(shape, size)
    return [f"the photo is {shape[1]}x{shape[0]}; it is upscaled to a {w}x{h} working size "
            "(size 0 keeps its size)"]


def redact(text: str, paths: list[Path]) -> str:
    """``text`` with each of ``paths`` replaced by its file name, so that messages
    shown to a client never reveal the server's folders.

    Example:
        >>> redact("cannot read photo /srv/up/3f/a b.png: truncated", [Path("/srv/up/3f/a b.png")])
        'cannot read photo a b.png: truncated'
    """
    for path in sorted(paths, key=lambda p: -len(str(p))):
        text = text.replace(str(path), path.name)
    return text
