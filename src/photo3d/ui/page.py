"""The web page and the API of ``photo3d ui`` (Gradio Blocks).

Inputs: the photo, an optional depth map, an optional right view and the options
of :class:`~photo3d.ui.job.JobOptions`. Outputs: the 3D photo in photo3d's own
viewer (``viewer.html`` in a sandboxed frame: scripts run, but without access to
the page, its cookies or the network), the depth map, the videos, ``mesh.glb``, the
Gaussian splats (``splats.spz``) and a zip of the whole folder. The status box says
what was made, then every warning ``photo3d make`` would print, a line each; an
error is one line there.

The same job is the API endpoint ``/make`` (parameters ``photo``, ``depth``,
``right``, ``size``, ``fill``, ``source``, ``depth_kind``, ``videos``, ``paths``,
``ply``, ``edges``; every one but ``photo`` has a default), returning the GLB, the
zip (which holds ``splats.spz`` too), the depth preview and the videos; an error is
raised to the client as one line (the server logs no traceback for it). Page and API share
one queue with ``workers`` places.

Both take what the client sent as it is (Gradio's own conversions are off, so every
value is checked once, by :class:`~photo3d.ui.job.JobOptions` and
:func:`~photo3d.ui.workspace.check_upload`, and a bad one is one line), run the
request in a thread of its own (:meth:`~photo3d.ui.runner.Runner.submit`) and set
its cancel event when the client cancels or goes away. Files are returned by their
address only (:mod:`photo3d.ui.gate`): a result carries no path of the server.

Gradio is imported when :func:`build_app` is called (extra ``photo3d[ui]``).
"""

from __future__ import annotations

import asyncio
import html
from collections.abc import AsyncIterator
from contextlib import aclosing
from pathlib import Path
from typing import TYPE_CHECKING

from photo3d.config import EDGES
from photo3d.errors import Photo3DError, require
from photo3d.files.folders import DEPTH_SUFFIXES, PHOTO_SUFFIXES
from photo3d.ui.gate import result_url
from photo3d.ui.job import CAMERA_PATHS, FILLS, MAX_SIZE, SOURCES, JobOptions, JobResult
from photo3d.ui.learned import NOTE as LEARNED_NOTE
from photo3d.ui.runner import RequestError, Runner
from photo3d.ui.warmup import Warmup

if TYPE_CHECKING:
    import gradio

DEFAULT = JobOptions()
"""The options of a request that sets none (the page's and the API's defaults)."""

PHOTO_TYPES = list(PHOTO_SUFFIXES)
"""Photo files the page offers (everything ``photo3d make`` reads)."""

DEPTH_TYPES = list(DEPTH_SUFFIXES)
"""Depth map files (docs/guarantees.md: 8/16-bit grey PNG, ``.npy``, ``.pfm``, float TIFF)."""

CSS = """
#photo3d-viewer iframe { display: block; width: 100%; border: 0; border-radius: 8px;
                         background: #111; }
#photo3d-status textarea { font-family: ui-monospace, monospace; }
"""

INTRO = """# photo3d
Turn one photo into a 3D photo: a layered depth image whose hidden parts are filled in,
shown below in photo3d's viewer (move the pointer over it), with its depth map, videos,
`mesh.glb`, its Gaussian splats (`splats.spz`) and a zip of every file. Without a depth
map, photo3d uses the one embedded in portrait photos, else estimates one."""


def load_gradio():
    """The ``gradio`` module, or :class:`~photo3d.errors.MissingExtra` naming ``ui``."""
    return require("gradio", "ui", purpose="photo3d ui", package="gradio")


def theme():
    """Gradio's default theme with the system's fonts (nothing loaded from the web)."""
    gr = load_gradio()
    return gr.themes.Default(font=["ui-sans-serif", "system-ui", "sans-serif"],
                             font_mono=["ui-monospace", "monospace"])


def viewer_frame(result: JobResult) -> str:
    """The HTML of a sandboxed frame showing ``result``'s ``viewer.html``.

    ``sandbox="allow-scripts"`` without ``allow-same-origin``: the viewer runs in an
    opaque origin, and its own Content-Security-Policy forbids every load.
    """
    page = result.viewer.read_text(encoding="utf-8")
    w, h = result.size
    return (f'<iframe sandbox="allow-scripts" allow="accelerometer *; gyroscope *" '
            f'title="3D photo" '
            f'style="aspect-ratio: {w} / {h}; max-height: 70vh" '
            f'srcdoc="{html.escape(page, quote=True)}"></iframe>')


def build_app(runner: Runner, warmup: Warmup, *, workers: int = 1,
              ttl: float = 3600.0) -> gradio.Blocks:
    """The page and the ``/make`` endpoint around ``runner``.

    Args:
        runner: makes the photos.
        warmup: its state is shown at the top of the page until it is ready.
        workers: requests made at once (the page and the API share them).
        ttl: seconds Gradio keeps uploaded files (as the runner's workspace keeps
            results).
    """
    gr = load_gradio()
    every = int(max(1, min(60, ttl // 4)))
    with _checked_blocks(gr)(title="photo3d", analytics_enabled=False,
                             delete_cache=(every, int(max(1, ttl)))) as demo:
        gr.Markdown(INTRO)
        ready = gr.Markdown(warmup.message(), elem_id="photo3d-warmup")
        with gr.Row():
            with gr.Column(scale=1, min_width=320):
                photo = gr.File(label="Photo (JPEG, PNG, TIFF, WebP, HEIC)", type="filepath",
                                file_types=PHOTO_TYPES, elem_id="photo3d-photo")
                depth = gr.File(label="Depth map (optional)", type="filepath",
                                file_types=DEPTH_TYPES, elem_id="photo3d-depth")
                right = gr.File(label="Right view of a stereo pair (optional)",
                                type="filepath", file_types=PHOTO_TYPES,
                                elem_id="photo3d-right")
                button = gr.Button("Make the 3D photo", variant="primary",
                                   elem_id="photo3d-make")
                status = gr.Textbox(label="Status", interactive=False, lines=1, max_lines=8,
                                    elem_id="photo3d-status")
                with gr.Accordion("Options", open=False, elem_id="photo3d-options"):
                    size = gr.Slider(0, MAX_SIZE, value=DEFAULT.size, step=64,
                                     label="Working size (px, longer side; 0 keeps the "
                                           "photo's size)", elem_id="photo3d-size")
                    fill = gr.Radio(list(FILLS), value=DEFAULT.fill, label="Fill",
                                    info=LEARNED_NOTE, elem_id="photo3d-fill")
                    source = gr.Radio(list(SOURCES), value=DEFAULT.source, label="Depth source "
                                      "(auto: the depth map, else the right view, else the "
                                      "photo's own, else the depth model)")
                    depth_kind = gr.Radio(["disparity", "depth"], value=DEFAULT.depth_kind,
                                          label="The depth map holds (disparity: near = "
                                                "bright)")
                    videos = gr.Checkbox(DEFAULT.videos, label="Videos",
                                         elem_id="photo3d-videos-on")
                    paths = gr.CheckboxGroup(list(CAMERA_PATHS), value=list(DEFAULT.paths),
                                             label="Camera paths")
                    ply = gr.Checkbox(DEFAULT.ply, label="Also the full mesh as PLY (large)")
                    edges = gr.Radio(list(EDGES), value=DEFAULT.edges, label="Depth edges "
                                     "(align: moved onto the photo's colour edges; soft: "
                                     "also soft silhouettes; exact: where the depth map "
                                     "puts them)",
                                     elem_id="photo3d-edges")
            with gr.Column(scale=2, min_width=480):
                viewer = gr.HTML(elem_id="photo3d-viewer", min_height=120)
                with gr.Row():
                    glb = gr.File(label="mesh.glb", interactive=False, elem_id="photo3d-glb")
                    splats = gr.File(label="splats.spz (Gaussian splats)", interactive=False,
                                     elem_id="photo3d-splats")
                    bundle = gr.File(label="Every file (zip)", interactive=False,
                                     elem_id="photo3d-zip")
                with gr.Row():
                    depth_view = gr.Image(label="Depth used", type="filepath",
                                          interactive=False, elem_id="photo3d-depthmap")
                    video_view = gr.Gallery(label="Videos", columns=2, interactive=False,
                                            elem_id="photo3d-videos")
                video_files = gr.File(file_count="multiple", visible=False)

        inputs = [photo, depth, right, size, fill, source, depth_kind, videos, paths, ply,
                  edges]

        async def make_page(photo, depth=None, right=None, size=DEFAULT.size,
                            fill=DEFAULT.fill, source=DEFAULT.source,
                            depth_kind=DEFAULT.depth_kind, videos=DEFAULT.videos,
                            paths=DEFAULT.paths, ply=DEFAULT.ply, edges=DEFAULT.edges,
                            progress=gr.Progress(), request=None):  # noqa: B008
            served = Served(runner, request)
            shown = False
            try:
                async with aclosing(_results(runner, progress, photo, depth, right, size,
                                             fill, source, depth_kind, videos, paths,
                                             ply, edges)) as results:
                    async for result in results:
                        videos_out = served.gallery(result.videos)
                        if shown:  # the videos' turn: the 3D photo, depth, GLB, splats stay
                            yield (gr.skip(), gr.skip(), videos_out, gr.skip(), gr.skip(),
                                   served.file(result.zip), result.status())
                        else:
                            yield (viewer_frame(result), served.file(result.depth_preview),
                                   videos_out, served.file(result.glb),
                                   served.file(result.splats), served.file(result.zip),
                                   result.status())
                        shown = True
            except RequestError as err:  # after the 3D photo (its videos): it stays
                kept = (gr.skip(),) * 6 if shown else (None,) * 6
                yield *kept, f"Error: {err}"

        async def make(photo, depth=None, right=None, size=DEFAULT.size, fill=DEFAULT.fill,
                       source=DEFAULT.source, depth_kind=DEFAULT.depth_kind,
                       videos=DEFAULT.videos, paths=DEFAULT.paths, ply=DEFAULT.ply,
                       edges=DEFAULT.edges,
                       progress=gr.Progress(), request=None):  # noqa: B008
            served = Served(runner, request)
            final = None
            try:
                async with aclosing(_results(runner, progress, photo, depth, right, size,
                                             fill, source, depth_kind, videos, paths,
                                             ply, edges)) as results:
                    async for result in results:
                        final = result
            except RequestError as err:
                raise gr.Error(str(err), print_exception=False) from None
            return (served.file(final.glb), served.file(final.zip),
                    served.file(final.depth_preview), [served.file(v) for v in final.videos])

        for handler in (make_page, make):  # Gradio passes the request to a gr.Request
            handler.__annotations__ = {"request": gr.Request}
        # The values arrive and leave as sent: checked by JobOptions and check_upload
        # (one line, no traceback in the log), files returned by their address only.
        queue = dict(concurrency_id="make", concurrency_limit=workers, preprocess=False,
                     postprocess=False)
        button.click(make_page, inputs,
                     [viewer, depth_view, video_view, glb, splats, bundle, status],
                     api_visibility="private", **queue)
        trigger = gr.Button(visible=False)
        # the API's four outputs stay as they are (its clients unpack them): the
        # splats reach it in the zip
        trigger.click(make, inputs, [glb, bundle, depth_view, video_files], api_name="make",
                      **queue)

        timer = gr.Timer(1.0, active=warmup.state != "ready")

        def warm_state():
            return warmup.message(), gr.Timer(active=warmup.state in ("running",
                                                                      "not started"))

        timer.tick(warm_state, None, [ready, timer], queue=False, api_visibility="private")
        demo.load(warm_state, None, [ready, timer], queue=False, api_visibility="private")
    return demo


def _checked_blocks(gr):
    """``gr.Blocks`` whose own checks of what a client sent (how many values, a file
    value's form, a file not uploaded to this server) fail as one line for the
    client (:func:`bad_request`), without a traceback in the server's log."""

    class Blocks(gr.Blocks):
        async def preprocess_data(self, *args, **kwargs):
            try:
                return await super().preprocess_data(*args, **kwargs)
            except gr.Error:
                raise
            except Exception as err:  # a malformed request: one line, no traceback
                raise gr.Error(bad_request(err), print_exception=False) from None

    return Blocks


def bad_request(err: Exception) -> str:
    r"""One line for a request Gradio refused before photo3d saw it.

    Example:
        >>> bad_request(ValueError("not enough input values (needed: 10, got: 1).\n"
        ...                        "Wanted inputs: ..."))
        'bad request: not enough input values (needed: 10, got: 1).'
    """
    kind = type(err).__name__
    if kind == "InvalidPathError":
        return "bad request: a file was not uploaded to this server"
    if kind == "ValidationError":
        return ("bad request: a file must be sent as an uploaded file (a FileData value, "
                "as gradio_client's handle_file sends it)")
    lines = str(err).strip().splitlines()
    return f"bad request: {lines[0] if lines else kind}"


class Served:
    """The files of one request's results as Gradio's file values, by address only:
    each is published (:meth:`~photo3d.ui.workspace.Workspace.publish`) and given as
    a URL of the origin the client reached (:func:`~photo3d.ui.gate.result_url`)."""

    def __init__(self, runner: Runner, request) -> None:
        self.workspace = runner.workspace
        self.origin = origin_of(request)

    def file(self, path: Path) -> dict:
        """A Gradio ``FileData`` whose path and URL are the file's address."""
        url = result_url(self.origin, self.workspace.publish(path), path.name)
        size = path.stat().st_size if path.is_file() else None  # None: cancelled meanwhile
        return {"path": url, "url": url, "size": size, "orig_name": path.name,
                "mime_type": None, "is_stream": False, "meta": {"_type": "gradio.FileData"}}

    def gallery(self, videos) -> list[dict]:
        """The videos as a Gallery's value."""
        return [{"video": self.file(v), "caption": None} for v in videos]


def origin_of(request) -> str:
    """``SCHEME://HOST`` the client used (``Host:`` was checked by the gate; a proxy's
    ``X-Forwarded-Proto`` is honoured).

    Example:
        >>> class Request:
        ...     headers = {"host": "localhost:7860", "x-forwarded-proto": "https"}
        >>> origin_of(Request()), origin_of(None)
        ('https://localhost:7860', 'http://127.0.0.1')
    """
    headers = getattr(request, "headers", None) or {}
    host = headers.get("host") or "127.0.0.1"
    scheme = (headers.get("x-forwarded-proto") or "").split(",")[0].strip().lower()
    if scheme not in ("http", "https"):
        url = getattr(request, "url", None)
        scheme = getattr(url, "scheme", None) or str(url or "http:").split(":")[0]
    return f"{scheme if scheme in ('http', 'https') else 'http'}://{host}"


def _upload(value, what: str) -> tuple[str | None, str | None]:
    """``(server path, the client's file name)`` of a file input as Gradio sends it
    (``FileData``: a dict with ``path``), or ``(None, None)``."""
    if value is None:
        return None, None
    if isinstance(value, dict) and isinstance(value.get("path"), str):
        name = value.get("orig_name")
        return value["path"], name if isinstance(name, str) else None
    raise RequestError(f"the {what} must be a file uploaded to this server")


async def _results(runner: Runner, progress, photo, depth, right, size, fill, source,
                   depth_kind, videos, paths, ply, edges) -> AsyncIterator[JobResult]:
    """Check what the client sent and run the request in its own thread (the page's
    and the API's): the results :meth:`~photo3d.ui.runner.Runner.run` yields. When the
    consumer stops early (the client cancelled: Gradio cancels the task or closes
    this generator), the request's cancel event is set: it stops at its next
    progress report and its folder is removed."""
    try:
        options = JobOptions(size=size, fill=fill, source=source, depth_kind=depth_kind,
                             videos=videos, paths=paths, ply=ply, edges=edges)
    except Photo3DError as err:
        raise RequestError(str(err)) from None
    (photo, name), (depth, _), (right, _) = (_upload(photo, "photo"),
                                             _upload(depth, "depth map"),
                                             _upload(right, "right view"))
    loop = asyncio.get_running_loop()
    events: asyncio.Queue = asyncio.Queue()

    def listener(kind: str, value) -> None:  # from the request's thread
        try:
            loop.call_soon_threadsafe(events.put_nowait, (kind, value))
        except RuntimeError:  # the server's loop is closed: nobody listens
            pass

    cancel = runner.submit(photo, options=options, listener=listener, depth=depth,
                           right=right, name=name)
    try:
        while True:
            kind, value = await events.get()
            if kind == "progress":
                progress(value[0], desc=value[1])
            elif kind == "result":
                yield value
            elif kind == "error":
                raise value
            else:
                return
    finally:
        cancel.set()  # no-op once finished; a cancelled or abandoned request stops
