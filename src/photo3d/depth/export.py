"""Write the depth the pipeline would use, for ``photo3d depth`` (look, edit, reuse).

:func:`export_depth` writes two files:

* ``NAME.png``: 16-bit grey **disparity** normalised to 0..65535 (near = bright),
  whatever the source's kind: the pipeline's own normalised disparity (unknowns
  filled from the background side, min-max normalised, paper Sec. 3.1). It is what
  depth networks write, so ``photo3d make IMAGE --depth NAME.png`` (default
  ``--depth-kind disparity``) reproduces the same 3D photo.
* ``NAME_preview.png``: 8-bit RGB with the viridis colour map (near = yellow, far =
  dark purple), a perceptually uniform map built from its 9 anchor colours.

Both are written atomically (:mod:`photo3d.files.atomic`) and replace earlier files
only once both are complete.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from PIL import Image

from photo3d.depth.normalize import normalize, prepare_depth
from photo3d.depth.sources import DepthEstimate
from photo3d.errors import OutputError
from photo3d.files.atomic import atomic_path
from photo3d.io.depth import write_depth_png16

PathLike = str | os.PathLike[str]

_VIRIDIS_ANCHORS = np.array(
    [[0x44, 0x01, 0x54], [0x47, 0x2D, 0x7B], [0x3B, 0x52, 0x8B], [0x2C, 0x72, 0x8E],
     [0x21, 0x90, 0x8C], [0x27, 0xAD, 0x81], [0x5D, 0xC8, 0x63], [0xAA, 0xDC, 0x32],
     [0xFD, 0xE7, 0x25]], np.float64)
_t = np.linspace(0.0, 1.0, len(_VIRIDIS_ANCHORS))
VIRIDIS = np.stack(
    [np.interp(np.linspace(0.0, 1.0, 256), _t, _VIRIDIS_ANCHORS[:, c]) for c in range(3)], 1
).round().astype(np.uint8)
"""``(256, 3) uint8`` viridis lookup table, linear between its 9 anchor colours."""


def colorize(values: np.ndarray) -> np.ndarray:
    """Map values in [0, 1] to viridis colours.

    Args:
        values: ``(H, W)`` floats; clipped to [0, 1], NaN becomes 0.

    Returns:
        ``(H, W, 3) uint8``.

    Example:
        >>> colorize(np.array([[0.0, 1.0]])).tolist()
        [[[68, 1, 84], [253, 231, 37]]]
    """
    v = np.nan_to_num(np.clip(np.asarray(values, np.float64), 0.0, 1.0), nan=0.0)
    return VIRIDIS[np.round(v * 255).astype(np.int64)]


def depth_outputs(out_png: PathLike) -> tuple[Path, Path]:
    """The two files :func:`export_depth` writes for ``out_png``: ``(png, preview)``.

    Example:
        >>> [p.name for p in depth_outputs("out/d.png")]
        ['d.png', 'd_preview.png']
    """
    out_png = Path(out_png)
    return out_png, out_png.with_name(out_png.stem + "_preview.png")


def check_depth_output(out_png: PathLike, *, inputs: Iterable[PathLike] = ()) -> Path:
    """Refuse an output that is not a ``.png`` or would replace one of ``inputs``.

    Both files :func:`export_depth` writes are checked (the PNG and its preview),
    through symbolic and hard links. Returns ``out_png`` as a Path.

    Raises:
        OutputError: one line naming the output and the input it would replace.

    Example:
        >>> try:
        ...     check_depth_output("d.png", inputs=["d.png"])
        ... except OutputError as err:
        ...     print(err)
        depth output d.png is the input d.png; choose another file name
    """
    out_png = Path(out_png)
    if out_png.suffix.lower() != ".png":
        raise OutputError(f"depth output {out_png} must be a .png file")
    for out in depth_outputs(out_png):
        for given in inputs:
            if _same_file(out, Path(given)):
                raise OutputError(f"depth output {out} is the input {given}; "
                                  "choose another file name")
    return out_png


def _same_file(a: Path, b: Path) -> bool:
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist
        return False


def export_depth(estimate: DepthEstimate, out_png: PathLike, *,
                 inputs: Iterable[PathLike] = ()) -> tuple[Path, Path]:
    """Write the normalised disparity as a 16-bit PNG plus a colour preview.

    Args:
        estimate: from :func:`photo3d.depth.sources.resolve_depth`.
        out_png: the ``.png`` to write (replaced, never through a symbolic link); the
            preview goes beside it as ``<stem>_preview.png``. The folder must exist.
        inputs: files the run read (photo, depth map); neither output may be one.

    Returns:
        ``(png_path, preview_path)``.

    Raises:
        OutputError: ``out_png`` is not a ``.png``, would replace one of
            ``inputs`` (:func:`check_depth_output`) or cannot be written; files
            already there are left as they were.

    Example:
        >>> import pathlib, tempfile
        >>> from photo3d.io.depth import read_depth
        >>> est = DepthEstimate(np.array([[1.0, 2.0], [4.0, 4.0]], np.float32), "depth", "demo")
        >>> png, preview = export_depth(est, pathlib.Path(tempfile.mkdtemp()) / "d.png")
        >>> read_depth(png).tolist(), preview.name
        ([[65535.0, 21845.0], [0.0, 0.0]], 'd_preview.png')
    """
    out_png = check_depth_output(out_png, inputs=inputs)
    depth = np.asarray(estimate.depth)
    prepared = prepare_depth(depth, depth.shape, kind=estimate.kind)
    norm, _, _ = normalize(prepared.disparity)
    _, preview = depth_outputs(out_png)
    # the preview is renamed into place first, the depth last, and only when both exist
    with (atomic_path(out_png, follow_symlinks=False) as tmp_png,
          atomic_path(preview, follow_symlinks=False) as tmp_preview):
        write_depth_png16(tmp_png, norm, vmin=0.0, vmax=1.0)
        Image.fromarray(colorize(norm)).save(tmp_preview, format="PNG")
    return out_png, preview
