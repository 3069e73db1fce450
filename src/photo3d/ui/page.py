"""The web page and the API of ``photo3d ui`` (Gradio Blocks).

Inputs: the photo, an optional depth map, an optional right view and the options
of :class:`~photo3d.ui.job.JobOptions`. Outputs: the 3D photo in photo3d's own
viewer (``viewer.html`` in a sandboxed frame: scripts run, but without access to
the page, its cookies or the network), the depth map, the videos, ``mesh.glb`` and a
zip of the whole folder. Errors are one line in the status box.

The same job is the API endpoint ``/make`` (parameters ``photo``, ``depth``,
``right``, ``size``, ``fill``, ``source``, ``depth_kind``, ``videos``, ``paths``,
``ply``; every one but ``photo`` has a default), returning the GLB, the zip, the
depth preview and the videos; an error is raised to the client as one line. Page
and API share one queue with ``workers`` places.

Gradio is imported when :func:`build_app` is called (extra ``photo3d[ui]``).
"""

from __future__ import annotations

import html
from collections.abc import Iterator
from typing import TYPE_CHECKING

from photo3d.errors import Photo3DError, require
from photo3d.files.folders import DEPTH_SUFFIXES, PHOTO_SUFFIXES
from photo3d.ui.job import CAMERA_PATHS, FILLS, SOURCES, JobOptions, JobResult
from photo3d.ui.runner import RequestError, Runner
from photo3d.ui.warmup import Warmup

if TYPE_CHECKING:
    import gradio

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
`mesh.glb` and a zip of every file. Without a depth map, photo3d uses the one embedded
in portrait photos, else estimates one."""


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
    with gr.Blocks(title="photo3d", analytics_enabled=False,
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
                status = gr.Textbox(label="Status", interactive=False, max_lines=1,
                                    elem_id="photo3d-status")
                with gr.Accordion("Options", open=False, elem_id="photo3d-options"):
                    size = gr.Slider(0, 2048, value=1024, step=64,
                                     label="Working size (px, longer side; 0 keeps the "
                                           "photo's size)", elem_id="photo3d-size")
                    fill = gr.Radio(list(FILLS), value="structured", label="Fill")
                    source = gr.Radio(list(SOURCES), value="auto", label="Depth source "
                                      "(auto: the depth map, else the right view, else the "
                                      "photo's own, else the depth model)")
                    depth_kind = gr.Radio(["disparity", "depth"], value="disparity",
                                          label="The depth map holds (disparity: near = "
                                                "bright)")
                    videos = gr.Checkbox(True, label="Videos", elem_id="photo3d-videos-on")
                    paths = gr.CheckboxGroup(list(CAMERA_PATHS), value=["circle"],
                                             label="Camera paths")
                    ply = gr.Checkbox(False, label="Also the full mesh as PLY (large)")
            with gr.Column(scale=2, min_width=480):
                viewer = gr.HTML(elem_id="photo3d-viewer", min_height=120)
                with gr.Row():
                    glb = gr.File(label="mesh.glb", interactive=False, elem_id="photo3d-glb")
                    bundle = gr.File(label="Every file (zip)", interactive=False,
                                     elem_id="photo3d-zip")
                with gr.Row():
                    depth_view = gr.Image(label="Depth used", type="filepath",
                                          interactive=False, elem_id="photo3d-depthmap")
                    video_view = gr.Gallery(label="Videos", columns=2, interactive=False,
                                            elem_id="photo3d-videos")
                video_files = gr.File(file_count="multiple", visible=False)

        inputs = [photo, depth, right, size, fill, source, depth_kind, videos, paths, ply]

        def make_page(photo, depth=None, right=None, size=1024, fill="structured",
                      source="auto", depth_kind="disparity", videos=True, paths=("circle",),
                      ply=False, progress=gr.Progress()):  # noqa: B008 - Gradio's way
            try:
                shown = False
                for result in _make(runner, progress, photo, depth, right, size, fill,
                                    source, depth_kind, videos, paths, ply):
                    line = "; ".join([result.summary]
                                     + [f"warning: {w}" for w in result.warnings])
                    videos_out = [str(v) for v in result.videos]
                    if shown:  # the videos' turn: the 3D photo, depth and GLB stay
                        yield (gr.skip(), gr.skip(), videos_out, gr.skip(), str(result.zip),
                               line)
                    else:
                        yield (viewer_frame(result), str(result.depth_preview), videos_out,
                               str(result.glb), str(result.zip), line)
                    shown = True
            except RequestError as err:  # after the 3D photo (its videos): it stays
                kept = (gr.skip(),) * 5 if shown else (None,) * 5
                yield *kept, f"Error: {err}"

        def make(photo, depth=None, right=None, size=1024, fill="structured", source="auto",
                 depth_kind="disparity", videos=True, paths=("circle",), ply=False,
                 progress=gr.Progress()):  # noqa: B008 - Gradio's way
            try:
                *_, result = _make(runner, progress, photo, depth, right, size, fill, source,
                                   depth_kind, videos, paths, ply)
            except RequestError as err:
                raise gr.Error(str(err), print_exception=False) from None
            return (str(result.glb), str(result.zip), str(result.depth_preview),
                    [str(v) for v in result.videos])

        queue = dict(concurrency_id="make", concurrency_limit=workers)
        button.click(make_page, inputs,
                     [viewer, depth_view, video_view, glb, bundle, status],
                     api_visibility="private", **queue)
        trigger = gr.Button(visible=False)
        trigger.click(make, inputs, [glb, bundle, depth_view, video_files], api_name="make",
                      **queue)

        timer = gr.Timer(1.0, active=warmup.state != "ready")

        def warm_state():
            return warmup.message(), gr.Timer(active=warmup.state in ("running",
                                                                      "not started"))

        timer.tick(warm_state, None, [ready, timer], queue=False, api_visibility="private")
        demo.load(warm_state, None, [ready, timer], queue=False, api_visibility="private")
    return demo


def _make(runner: Runner, progress, photo, depth, right, size, fill, source, depth_kind,
          videos, paths, ply) -> Iterator[JobResult]:
    """Check the options and run one request (the page's and the API's): the
    results :meth:`~photo3d.ui.runner.Runner.run` yields."""
    try:
        options = JobOptions(size=size, fill=fill, source=source, depth_kind=depth_kind,
                             videos=bool(videos), paths=tuple(paths or ()), ply=bool(ply))
    except Photo3DError as err:
        raise RequestError(str(err)) from None

    def report(fraction: float, label: str) -> None:
        progress(fraction, desc=label)

    return runner.run(photo, options=options, depth=depth, right=right, progress=report)
