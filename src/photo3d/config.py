"""Configuration: frozen, nested dataclasses with one docstring per field.

Change a value with :func:`dataclasses.replace` (or :meth:`Config.with_`), never in
place. Spatial sizes are given for a 1024 px working size (the paper's tuning) and
scaled by ``size / 1024`` at run time (:meth:`Config.spatial`).

Example:
    >>> cfg = Config().with_(size=512, inpainter="diffusion")
    >>> cfg.size, cfg.spatial(40)
    (512, 20)
"""

from __future__ import annotations

import dataclasses
import json
import math
import numbers
from dataclasses import dataclass, field
from typing import Any

from photo3d.errors import ConfigError

REFERENCE_SIZE = 1024
EDGES = ("align", "soft", "exact")
"""The values of :attr:`Config.edges`."""


@dataclass(frozen=True)
class PreprocessConfig:
    """Depth sharpening and edge detection (paper, Sec. 3.1)."""

    filter_windows: tuple[int, ...] = (7, 7, 5, 5, 5)
    """Bilateral median filter passes, one window size each (authors' code)."""
    sigma_spatial: float = 4.0
    """Spatial sigma of the bilateral median filter, pixels."""
    sigma_intensity: float = 0.5
    """Range sigma of the bilateral median filter, in normalised disparity."""
    filter_sigma_color: float = 0.1
    """``edges="align"``/``"soft"``: colour sigma of the bilateral median filter (RGB
    distance, colours in [0, 1]; its weights also fall with the photo's colour
    difference from the centre pixel, so thin structures the photo shows survive it;
    0 = off, the paper's filter, as with ``edges="exact"``)."""
    filter_thin_width: int = 5
    """``edges="align"``/``"soft"``: where the colour-guided and the paper's median
    disagree, the colour-guided one's values are kept only in parts narrower than this
    (working px: a ``width x width`` opening removes them;
    :func:`photo3d.stages.filters.keep_thin`), the paper's elsewhere (0: the
    colour-guided median everywhere)."""
    filter_thin_length: int = 32
    """``edges="align"``/``"soft"``: and only in those parts at least this long (px at
    1024, the bounding box's longer side): a pole or a wire, not a stereo matcher's
    speckle along an edge (0: any length)."""
    discontinuity: float = 0.04
    """Neighbour disparity difference (normalised) that marks a discontinuity."""
    min_edge_length: int = 10
    """Linked depth edges shorter than this (px at 1024) are dropped."""
    attach_short: bool = True
    """Short segments touching a long edge join it instead of being dropped (the
    paper drops them; their links then stretch into streaks in novel views)."""
    grow_foreground: float = 1.0
    """The near side of every depth discontinuity grows by this many pixels of the
    input photo (at least one working pixel; 0 = off). The photo's pixels along an
    occluding contour mix both sides' colours; on the far side they would stay
    behind as a thin foreground-coloured line along every revealed area, on the near
    side they move with the object they mostly show, and the background behind them
    is inpainted. The input view is unchanged."""
    align_radius: int = 4
    """``edges="align"``: window radius of the colour-guided median that moves depth
    steps onto the photo's colour edges, in working pixels (:mod:`photo3d.stages.align`;
    not scaled with the working size: its time grows with the cube of the radius, and 4
    keeps ``make`` at 1024 px within about 15 % of its time without it)."""
    align_iterations: int = 4
    """``edges="align"``: passes of that median (each moves a step up to about the
    radius)."""
    align_sigma_color: float = 0.1
    """``edges="align"``: colour sigma of that median (RGB distance, colours in [0, 1])."""
    ramp_passes: int = 4
    """``edges="align"``: passes that turn ramps across depth steps (smooth network or
    stereo depth) into steps at their middle before the bilateral median
    (:func:`photo3d.stages.steps.sharpen_ramps`; ramps up to about twice as many
    working pixels wide; 0 = off)."""


@dataclass(frozen=True)
class RegionConfig:
    """Context and synthesis regions (paper, Sec. 3.2)."""

    synthesis_iterations: int = 40
    """Flood-fill steps of the synthesis region (px at 1024)."""
    context_iterations: int = 100
    """Flood-fill steps of the context region (px at 1024)."""
    thin_context: float = 0.5
    """An edge whose context has fewer pixels than this fraction of its synthesis region
    (its background is a sliver between two depth edges: a mirror's stem, a gap in
    a railing) also takes as context the pixels at or behind its depth that bound the
    synthesis region, grown ``thin_context_iterations`` px along their own layer;
    without them a few pixels of the sliver colour the whole region (0: never)."""
    context_around: bool = True
    """Every edge's context also takes the pixels at its synthesis region's depth (within
    the discontinuity threshold) that bound that region, grown
    ``thin_context_iterations`` px along their own layer: what surrounds a hidden area
    at its depth, not only the side it was seen from (the paper's context is that side
    alone; the classical fills gain from the rest; the learned backend keeps the
    paper's, which its nets were trained on, and so does ``thin_context``)."""
    thin_context_iterations: int = 10
    """Flood-fill steps of that extra context (px at 1024)."""
    edge_dilation: int = 5
    """Synthesis region dilated into the context near the edge (px at 1024): these
    pixels, often a mix of foreground and background colour where colour and depth
    edges are misaligned, are hidden from the inpainter."""
    overwrite_dilation: bool = False
    """Also replace the visible pixels of that band with the inpainted values
    (removes foreground-coloured fringes, but the input view no longer reproduces
    the photo exactly near depth edges)."""
    border: int = 60
    """Width of the extrapolated frame around the image (px at 1024; 0 = none)."""
    border_fill: str = "texture"
    """How the extrapolated frame gets its colours, from the photo's outer band
    (``border_context`` wide): ``texture`` (the photo's texture continued:
    :func:`photo3d.inpaint.frame.fill_frame`), an inpainting backend's name
    (:func:`photo3d.inpaint.available`), or ``replicate`` (the outermost pixels
    copied outward: streaks). Its depth always continues the outermost pixels'."""
    border_context: int = 120
    """Width of the photo's outer band the border fill reads (px at 1024)."""
    max_passes: int = 3
    """Multi-layer inpainting: at most this many passes (stops when no new edge)."""


@dataclass(frozen=True)
class SilhouetteConfig:
    """Soft silhouettes: coverage of the mixed pixels along occluding contours
    (:mod:`photo3d.stages.silhouettes`; with :attr:`Config.edges` ``soft`` only)."""

    band: int = 3
    """Near-side pixels this close to a depth edge (px at 1024) get an alpha and a
    foreground colour (``benchmarks/bench_alpha.py``)."""
    radius: int = 4
    """Half side of the window their foreground and background colours are sampled
    from (px at 1024)."""
    method: str = "pairs"
    """``pairs``: the foreground / background sample pair that explains the pixel's
    colour best; ``means``: the window's mean colours."""


@dataclass(frozen=True)
class Config:
    """Everything that changes what :func:`photo3d.make` computes."""

    size: int | None = 1024
    """Longer side of the working image in pixels (None: keep the input size)."""
    depth_kind: str = "disparity"
    """How to read the depth input: ``disparity`` (near = large) or ``depth``."""
    inpainter: str = "structured"
    """Inpainting backend name (see :func:`photo3d.inpaint.available`); the default,
    ``structured``, was chosen by measurement on held-out photos, the stereo pairs
    and time (``docs/fills.md``)."""
    edges: str = "soft"
    """Where the depth edges go: ``soft`` (the default) moves every depth step onto
    the photo's colour edge within a few pixels before the LDI is cut (depth from
    networks and stereo is fat or smooth at silhouettes) and gives the mixed pixels
    along each occluding contour a coverage (alpha) and their foreground colour (soft
    silhouettes, :attr:`silhouettes`); ``align`` only moves the steps; ``exact`` keeps
    them where the depth map puts them (depth known to be exact, or the old
    behaviour). Chosen by measurement (``docs/edges.md``)."""
    metric: bool = False
    """Keep the depth input's units (needs ``depth_kind="depth"``): z of every LDI pixel
    is the input depth instead of the authors' normalised [1/3, 20] range."""
    spatial_scale: float | None = None
    """Factor applied to spatial sizes (None: working size / 1024, as the paper)."""
    preprocess: PreprocessConfig = field(default_factory=PreprocessConfig)
    regions: RegionConfig = field(default_factory=RegionConfig)
    silhouettes: SilhouetteConfig = field(default_factory=SilhouetteConfig)

    def __post_init__(self) -> None:
        whole = isinstance(self.size, numbers.Integral) and not isinstance(self.size, bool)
        if self.size is not None and not (whole and 16 <= self.size <= 16384):
            raise ConfigError(f"size must be between 16 and 16384 (a whole number) or None, "
                              f"got {self.size!r}")
        scale = self.spatial_scale
        if scale is not None and not (isinstance(scale, numbers.Real) and 0 < scale < math.inf):
            raise ConfigError(f"spatial_scale must be a number > 0 or None, got {scale!r}")
        if self.depth_kind not in ("disparity", "depth"):
            raise ConfigError(f"depth_kind must be 'disparity' or 'depth', got {self.depth_kind!r}")
        if self.edges not in EDGES:
            raise ConfigError(f"edges must be one of {', '.join(EDGES)}, got {self.edges!r}")
        if self.silhouettes.method not in ("pairs", "means"):
            raise ConfigError("silhouettes.method must be 'pairs' or 'means', got "
                              f"{self.silhouettes.method!r}")
        if self.metric and self.depth_kind != "depth":
            raise ConfigError("metric=True needs depth_kind='depth' (metric depth input)")

    def with_(self, **changes: Any) -> Config:
        """A copy with top-level fields replaced (nested: pass a new sub-config)."""
        return dataclasses.replace(self, **changes)

    def spatial(self, pixels: int, working_size: int | None = None) -> int:
        """Scale a size tuned for 1024 px to the working size (at least 1).

        ``working_size`` is the longer side actually used (defaults to ``size``).
        """
        if pixels <= 0:
            return 0
        scale = self.spatial_scale
        if scale is None:
            scale = (working_size or self.size or REFERENCE_SIZE) / REFERENCE_SIZE
        return max(1, round(pixels * scale))

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able dictionary (saved beside every output)."""
        return dataclasses.asdict(self)

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Config:
        """Inverse of :meth:`to_dict`; unknown keys raise :class:`ConfigError`."""
        data = dict(data)
        try:
            pre = data.pop("preprocess", {})
            if "filter_windows" in pre:
                pre = {**pre, "filter_windows": tuple(pre["filter_windows"])}
            reg = data.pop("regions", {})
            sil = data.pop("silhouettes", {})
            return cls(preprocess=PreprocessConfig(**pre), regions=RegionConfig(**reg),
                       silhouettes=SilhouetteConfig(**sil), **data)
        except TypeError as err:
            raise ConfigError(f"bad configuration: {err}") from None


def working_shape(shape: tuple[int, int], size: int | None) -> tuple[int, int]:
    """``(H, W)`` after resizing the longer side to ``size`` (:attr:`Config.size`;
    None keeps the shape): the shape every stage works at.

    Example:
        >>> working_shape((500, 741), 1024)
        (691, 1024)
    """
    h, w = shape
    if size is None:
        return h, w
    s = size / max(h, w)
    return max(1, round(h * s)), max(1, round(w * s))


PRESETS: dict[str, Config] = {
    "default": Config(),
    "fast": Config(size=640),
}
"""Named configurations (``photo3d make --preset NAME``)."""
