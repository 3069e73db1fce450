"""Write and read the self-contained interactive viewer page (``viewer.html``).

One HTML file per 3D photo that opens anywhere, also from ``file://`` and offline:
no server, no network, no external script or font (a Content-Security-Policy in the
page forbids every load). It holds

* ``<script id="photo3d-header" type="application/json">``: the header of
  :func:`photo3d.viewer._codec.encode_mesh` (sizes, fields of view, quantisation
  bounds, section offsets) plus ``animate``;
* ``<script id="photo3d-data" type="application/octet-stream">``: the base64 of the
  compressed mesh (positions quantised to uint16, colours uint8, faces as byte
  planes of small deltas; about 1/12 of the GLB for the 1024 px sample);
* the viewer (``viewer.js``, package data): a small WebGL2 renderer with the
  projection of :mod:`photo3d.camera` (OpenCV axes, intrinsics from the mesh's
  fields of view, principal point at the centre), so at a fixed camera the page
  shows what :class:`photo3d.render.renderer.Renderer` renders. Pointer, touch,
  wheel and device tilt move the camera by at most the shifts of the authors'
  ``circle`` path, through a damped spring; until the user interacts the camera
  follows that path.

Test and link hooks: ``viewer.html#camera=x,y,z&static=1`` (camera position in the
input camera's frame, no animation) and ``window.photo3dViewer`` (``ready``,
``setCamera``, ``setAnimate``, ``pixels()``; see the top of ``viewer.js``).
"""

from __future__ import annotations

import base64
import html
import json
import os
import re
from importlib import resources
from pathlib import Path

from photo3d.errors import InputError, OutputError
from photo3d.files.atomic import open_write
from photo3d.io.bounded import loads_json, read_bytes
from photo3d.structures.mesh import Mesh, TexturedMesh
from photo3d.viewer._codec import decode_mesh, encode_mesh

PathLike = str | os.PathLike[str]

VIEWER_FILE = "viewer.html"
MAX_VIEWER_BYTES = 2 << 30
"""The largest page :func:`read_viewer` reads (the bound of ``mesh.glb``,
:data:`photo3d.io.glb.MAX_GLB_BYTES`; the 1024 px sample's page is 1.8 MB)."""
_SCRIPT_RE = r'<script type="{kind}" id="{id}">(.*?)</script>'


def write_viewer(mesh: Mesh | TexturedMesh, path: PathLike, *, title: str = "photo3d",
                 animate: bool = True) -> Path:
    """Write the interactive viewer page of ``mesh``.

    Args:
        mesh: vertices ``(N, 3) float32`` OpenCV camera frame of the input view with
            ``z > 0``, colors ``(N, 3) uint8`` sRGB, labels ``(N,) uint8``, faces
            ``(M, 3) int32``; ``width``, ``height``, ``hfov``, ``vfov`` give the
            camera (principal point at the centre). A
            :class:`~photo3d.structures.mesh.TexturedMesh` is embedded with its texture (JPEG).
        path: file to create (overwritten), usually ``OUT/viewer.html``.
        title: page title (plain text; escaped).
        animate: start with the camera moving along the authors' ``circle`` path
            (until the user interacts); False keeps it still.

    Returns:
        ``path`` as a :class:`~pathlib.Path`.

    Raises:
        InputError: not a mesh, empty mesh, wrong shapes, non-finite vertices or
            ``z <= 0``.
        OutputError: ``path`` cannot be written.

    Example:
        >>> import numpy as np, tempfile, pathlib
        >>> mesh = Mesh(np.array([[0, 0, 1], [1, 0, 1], [0, 1, 1]], np.float32),
        ...             np.zeros((3, 3), np.uint8), np.ones(3, np.uint8),
        ...             np.array([[0, 2, 1]], np.int32), 4, 4, 1.0, 1.0)
        >>> path = write_viewer(mesh, pathlib.Path(tempfile.mkdtemp()) / "viewer.html")
        >>> read_viewer(path).faces.shape
        (1, 3)
    """
    if not isinstance(mesh, Mesh | TexturedMesh):
        raise InputError(f"mesh must be a photo3d Mesh or TexturedMesh (Photo3D.mesh(), "
                         f".light_mesh()), got a {type(mesh).__name__}")
    header, payload = encode_mesh(mesh)
    header["animate"] = bool(animate)
    before, after = _template().split("{{DATA}}")
    header_json = json.dumps(header, separators=(",", ":")).replace("<", "\\u003c")
    # a folder name that is not UTF-8 (lone surrogates, os.fsdecode): its bytes as \xNN
    title = title.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
    before = before.replace("{{TITLE}}", html.escape(title)).replace("{{HEADER}}", header_json)
    after = after.replace("{{SCRIPT}}", _script())
    path = Path(path)
    try:
        with open_write(path) as f:
            f.write(before.encode("utf-8"))
            f.write(base64.b64encode(payload))
            f.write(after.encode("utf-8"))
    except OSError as err:
        raise OutputError(f"cannot write viewer {path}: {err.strerror or err}") from None
    return path


def read_viewer(path: PathLike) -> Mesh | TexturedMesh:
    """Read the mesh back from a page written by :func:`write_viewer`.

    Positions come back within the quantisation error (see
    :mod:`photo3d.viewer._codec`), colours and labels exactly, faces rotated so
    that their largest index is last (same winding).

    Raises:
        InputError: one line; the file is missing, not a regular file, larger than
            :data:`MAX_VIEWER_BYTES`, not a photo3d viewer page, or its header or
            data are damaged (every field is checked; the payload is decompressed
            only up to the size its header declares, faces must index its vertices).
    """
    path = Path(path)
    if not os.path.lexists(path):
        raise InputError(f"viewer file not found: {path}")
    data = read_bytes(path, max_bytes=MAX_VIEWER_BYTES, what=f"viewer {path}")  # no FIFO
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise InputError(f"cannot read viewer {path}: {err}") from None
    parts = [
        re.search(_SCRIPT_RE.format(kind=kind, id=name), text, re.DOTALL)
        for kind, name in (("application/json", "photo3d-header"),
                           ("application/octet-stream", "photo3d-data"))
    ]
    if not all(parts):
        raise InputError(f"{path} is not a photo3d viewer page (no embedded mesh)")
    try:
        header = loads_json(parts[0].group(1), what=f"{path}'s header")
        payload = base64.b64decode(parts[1].group(1), validate=True)
        return decode_mesh(header, payload)
    except ValueError as err:  # InputError too: one line naming the file
        raise InputError(f"{path}: damaged viewer data: {err}") from None


def _template() -> str:
    return resources.files(__package__).joinpath("template.html").read_text(encoding="utf-8")


def _script() -> str:
    script = resources.files(__package__).joinpath("viewer.js").read_text(encoding="utf-8")
    if "</script" in script.lower() or "<!--" in script:  # would upset the HTML parser
        raise RuntimeError("viewer.js must not contain '</script' or '<!--'")
    return script
