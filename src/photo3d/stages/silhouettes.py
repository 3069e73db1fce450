"""Soft silhouettes: coverage (alpha) and foreground colour of the mixed pixels along
occluding contours, before the LDI is cut (issue 44, item 3).

A photo's pixels along a foreground's outline see part foreground, part background.
Cut hard, the foreground carries those mixed colours (and, where the depth map is
fatter than the object, pure background colours) into every novel view, as a halo.
Here every near-side pixel within ``band`` pixels of a cut link (the *fringe*) is
explained as ``I = alpha * F + (1 - alpha) * B``: ``F`` from the pure foreground
pixels of a ``(2 radius + 1)^2`` window (those at least ``band`` steps inside the
near side, walking along uncut links; in a structure thinner than ``2 band``, its
innermost pixels), ``B`` from the window's background pixels
(farther by at least the discontinuity threshold). Of all ``(F, B)`` sample pairs the
one that explains ``I`` best is taken (sampling-based matting, as Robust Matting /
Shared Matting do; the window means alone were measured worse:
``benchmarks/bench_alpha.py``). The pixel's LDI colour becomes its foreground
estimate ``(I - (1 - alpha) B) / alpha`` (the sampled ``F`` when ``alpha < 0.5``), so
composited over the background it gives the photo back; the far side behind it is
inpainted like any other hidden area and never sees the mixed colour (it lies on the
other side of the cut).

The near and far sides follow the cut mask of :func:`photo3d.stages.edges.link_edges`:
for each cut link the pixel of larger disparity is near.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numba
import numpy as np

from photo3d.config import Config
from photo3d.structures.ldi import LDI

_FAR = 1 << 20  # distance of pixels the walk from the near seeds did not reach
MAX_SAMPLES = 16
"""Foreground and background samples per fringe pixel the pairs are formed from (every
k-th of the window's, in raster order)."""
MIN_CONTRAST2 = 0.05 ** 2
"""Squared RGB distance below which a foreground and a background sample are too alike
to tell a mixed pixel's coverage (the pixel then stays opaque)."""


@dataclass(frozen=True)
class Silhouettes:
    """Coverage and colour of the input layer after :func:`soft_silhouettes`.

    Attributes:
        alpha: ``(H, W) float32`` in [0, 1]; 1 outside the fringe.
        color: ``(H, W, 3) float32`` in [0, 1]: the photo, with each fringe pixel's
            foreground colour estimate.
        fringe: number of pixels with ``alpha < 1``.
        background: ``(H, W, 3) float32`` the background colour estimated behind each
            fringe pixel (the photo's colour where ``alpha`` is 0), or None (no fringe).
        photo: ``(H, W, 3) float32`` the photo, or None (no fringe).
    """

    alpha: np.ndarray
    color: np.ndarray
    fringe: int
    background: np.ndarray | None = None
    photo: np.ndarray | None = None

    def behind(self) -> Behind | None:
        """The fringe's pixels, background estimates and photo colours for
        :func:`paint_behind`, or None (no fringe).

        Example:
            >>> img = np.zeros((8, 12, 3), np.float32); img[:, 6:] = 1.0; img[:, 6] = 0.25
            >>> disp = np.zeros((8, 12), np.float32); disp[:, 6:] = 1.0
            >>> cuts = np.zeros((8, 12), np.uint8); cuts[:, 5] = 2
            >>> behind = soft_silhouettes(img, disp, cuts).behind()
            >>> behind.pixels[:2].tolist(), behind.background[0].tolist()
            ([6, 18], [0.0, 0.0, 0.0])
        """
        if self.background is None or self.photo is None:
            return None
        pixels = np.flatnonzero(self.alpha < 1.0)
        return Behind(pixels, self.color.reshape(-1, 3)[pixels],
                      self.background.reshape(-1, 3)[pixels], self.photo.reshape(-1, 3)[pixels])


@dataclass(frozen=True)
class Behind:
    """What :func:`paint_behind` needs of the fringe once the hidden areas are filled.

    Attributes:
        pixels: ``(K,) int64`` the fringe's raster indices in the photo.
        foreground: ``(K, 3) float32`` the matting's foreground colours.
        background: ``(K, 3) float32`` the background colour the matting estimated
            behind each (the photo's own colour where ``alpha`` is 0).
        photo: ``(K, 3) float32`` the photo's (mixed) colour there.
    """

    pixels: np.ndarray
    foreground: np.ndarray
    background: np.ndarray
    photo: np.ndarray


def paint_behind(ldi: LDI, behind: Behind, *, threshold: float,
                 index: tuple[np.ndarray, np.ndarray] | None = None) -> LDI:
    """Give the nearest LDI pixel behind each fringe pixel (farther by more than
    ``threshold`` at the same lattice position: the inpainted layer) the background
    colour the photo shows there, and each fringe pixel the foreground colour that,
    composited over it, gives the photo back.

    The inpainting fills the hidden area behind a silhouette from context a few pixels
    away (never from the mixed pixels); right behind the fringe the photo itself shows
    the background through the mixed pixels, by ``1 - alpha``. How much of the
    matting's estimate the layer takes follows that share:

    * ``alpha < 0.5``: the estimate (it is the photo's colour with the sampled
      foreground taken out: mostly background), the fringe the sampled foreground;
    * ``alpha >= 0.5``: ``(1 - alpha) * estimate + alpha * inpainted`` (the estimate
      is then one background sample of the window, the one that explained the mixed
      colour best: often not the colour behind; a noisy speckle in novel views when
      taken whole), and the fringe's colour becomes ``(photo - (1 - alpha) * that)
      / alpha``.

    Args:
        ldi: the LDI after inpainting; its first ``H * W`` pixels are the photo.
        behind: :meth:`Silhouettes.behind`.
        threshold: disparity difference that makes a pixel lie behind.
        index: ``ldi.position_index()`` if the caller has it (a merge's).

    Returns:
        The LDI with those colours (positions, links and alpha unchanged).

    Example:
        >>> from photo3d.stages.ldi import from_image
        >>> ldi = from_image(np.ones((1, 2, 3), np.float32), np.ones((1, 2), np.float32))
        >>> two = replace(ldi, y=np.r_[ldi.y, 0].astype(np.int32),
        ...     x=np.r_[ldi.x, 1].astype(np.int32), color=np.r_[ldi.color, [[0.5] * 3]],
        ...     disparity=np.r_[ldi.disparity, 0.0].astype(np.float32),
        ...     links=np.r_[ldi.links, [[-1] * 4]].astype(np.int32), label=np.r_[ldi.label, 2],
        ...     alpha=np.array([1.0, 0.25, 1.0], np.float32))
        >>> black, white = np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32)
        >>> out = paint_behind(two, Behind(np.array([1]), white, black, black), threshold=0.04)
        >>> out.color[2].tolist(), out.color[1].tolist()  # alpha 0.25: the estimates
        ([0.0, 0.0, 0.0], [1.0, 1.0, 1.0])
        >>> two = replace(two, alpha=np.array([1.0, 0.75, 1.0], np.float32))
        >>> out = paint_behind(two, Behind(np.array([1]), white, black, np.full((1, 3), 0.5,
        ...                    np.float32)), threshold=0.04)
        >>> out.color[2].tolist(), out.color[1].round(4).tolist()  # 0.25 * 0 + 0.75 * 0.5
        ([0.375, 0.375, 0.375], [0.5417, 0.5417, 0.5417])
    """
    pixels = behind.pixels
    if pixels.size == 0:
        return ldi
    starts, order = ldi.position_index() if index is None else index
    cols = ldi.width + 2 * ldi.border
    y, x = np.divmod(pixels, ldi.width)
    pos = (y + ldi.border) * cols + (x + ldi.border)
    target = _behind(starts, order, pos, pixels, ldi.disparity, np.float32(threshold))
    ok = target >= 0
    front, target = pixels[ok], target[ok]
    a = ldi.alpha[front][:, None]
    solid = a >= 0.5
    color = ldi.color.copy()
    color[pixels] = behind.foreground
    back = np.where(solid, (1.0 - a) * behind.background[ok] + a * color[target],
                    behind.background[ok])
    color[target] = back
    fore = (behind.photo[ok] - (1.0 - a) * back) / np.maximum(a, 0.5)
    color[front] = np.where(solid, np.clip(fore, 0.0, 1.0), color[front])
    return replace(ldi, color=color)


@numba.njit(cache=True)
def _behind(starts, order, pos, pixels, disparity, threshold):  # pragma: no cover - numba
    out = np.full(pixels.size, -1, np.int64)
    for i in range(pixels.size):
        front = disparity[pixels[i]]
        best = -np.inf
        for s in range(starts[pos[i]], starts[pos[i] + 1]):
            j = order[s]
            d = disparity[j]
            if d < front - threshold and d > best:
                best = d
                out[i] = j
    return out


def soft_silhouettes(image: np.ndarray, disparity: np.ndarray, cuts: np.ndarray, *,
                     band: int = 2, radius: int = 3, threshold: float = 0.04,
                     method: str = "pairs") -> Silhouettes:
    """Alpha and foreground colour of the near side's mixed pixels along each cut.

    Args:
        image: ``(H, W, 3) float32`` sRGB in [0, 1].
        disparity: ``(H, W) float32`` normalised disparity (larger = nearer), the one
            the cuts were found on.
        cuts: ``(H, W) uint8`` cut directions per pixel (bit ``d`` set: the link in
            direction ``d`` = left, right, up, down is cut), as
            :attr:`photo3d.stages.edges.DepthEdges.cuts`.
        band: fringe depth in pixels (near-side pixels fewer than ``band`` steps from
            a cut; 0 = no fringe).
        radius: half side of the sampling window, pixels.
        threshold: disparity difference that makes a window pixel background.
        method: ``pairs`` (best ``(F, B)`` sample pair) or ``means`` (the window's
            mean foreground and background colours).

    Returns:
        :class:`Silhouettes`.

    Example:
        >>> img = np.zeros((8, 12, 3), np.float32); img[:, 6:] = 1.0  # white foreground
        >>> img[:, 6] = 0.25                                          # a 25 % mixed column
        >>> disp = np.zeros((8, 12), np.float32); disp[:, 6:] = 1.0
        >>> cuts = np.zeros((8, 12), np.uint8); cuts[:, 5] = 2  # right of column 5
        >>> sil = soft_silhouettes(img, disp, cuts)
        >>> sil.fringe, round(float(sil.alpha[4, 6]), 2), sil.color[4, 6].tolist()
        (8, 0.25, [1.0, 1.0, 1.0])
    """
    if method not in ("pairs", "means"):
        raise ValueError(f"method must be 'pairs' or 'means', got {method!r}")
    image = np.ascontiguousarray(image, np.float32)
    disparity = np.ascontiguousarray(disparity, np.float32)
    cuts = np.ascontiguousarray(cuts, np.uint8)
    alpha = np.ones(disparity.shape, np.float32)
    color = image.copy()
    if band <= 0 or not cuts.any():
        return Silhouettes(alpha, color, 0)
    dist = _near_distance(disparity, cuts, np.int32(band + 2 * radius), np.float32(threshold))
    back = image.copy()
    _matte(image, disparity, dist, np.int32(band), np.int32(radius), np.float32(threshold),
           method == "pairs", alpha, color, back)
    return Silhouettes(alpha, color, int(np.count_nonzero(alpha < 1.0)), back, image)


def silhouettes_of(image: np.ndarray, disparity: np.ndarray, cuts: np.ndarray, *,
                   config: Config, working_size: int) -> Silhouettes:
    """:func:`soft_silhouettes` with ``config``'s settings (unless ``config.edges`` is
    ``soft``: none, alpha 1 everywhere and the photo's colours).

    Args:
        image, disparity, cuts: as :func:`soft_silhouettes`, at the working size.
        config: the pipeline configuration (:attr:`~photo3d.config.Config.edges`,
            :class:`~photo3d.config.SilhouetteConfig`).
        working_size: longer side of the working image (spatial sizes scale with it).

    Example:
        >>> img = np.zeros((8, 12, 3), np.float32); img[:, 6:] = 1.0; img[:, 6] = 0.25
        >>> disp = np.zeros((8, 12), np.float32); disp[:, 6:] = 1.0
        >>> cuts = np.zeros((8, 12), np.uint8); cuts[:, 5] = 2  # right of column 5
        >>> silhouettes_of(img, disp, cuts, config=Config(edges="align"), working_size=1024).fringe
        0
        >>> silhouettes_of(img, disp, cuts, config=Config(edges="soft"), working_size=1024).fringe
        8
    """
    if config.edges != "soft":
        return Silhouettes(np.ones(disparity.shape, np.float32),
                           np.array(image, np.float32, copy=True), 0)
    sil = config.silhouettes
    return soft_silhouettes(image, disparity, cuts, band=config.spatial(sil.band, working_size),
                            radius=config.spatial(sil.radius, working_size),
                            threshold=config.preprocess.discontinuity, method=sil.method)


def _near_distance(disparity: np.ndarray, cuts: np.ndarray, limit: np.int32,
                   threshold: np.float32) -> np.ndarray:
    """``(H, W) int32`` steps along uncut 4-neighbour links from the nearest *near*
    pixel of a cut link (0 on those pixels), up to ``limit``; ``_FAR`` elsewhere. A
    link is cut when either end has its bit (the edges mark one end); the walk never
    steps across a disparity difference above ``threshold`` (a step whose edge was
    too short to be cut)."""
    return _walk(disparity, cuts, limit, threshold)


@numba.njit(cache=True)
def _walk(disparity, cuts, limit, threshold):  # pragma: no cover - numba
    h, w = disparity.shape
    dist = np.full((h, w), _FAR, np.int32)
    queue = np.empty(h * w, np.int64)
    head, tail = 0, 0
    dy = (0, 0, -1, 1)
    dx = (-1, 1, 0, 0)
    for y in range(h):
        for x in range(w):
            c = cuts[y, x]
            if c == 0:
                continue
            for d in range(4):  # the cut link's nearer end (either may hold the bit)
                if c & (1 << d):
                    qy, qx = y + dy[d], x + dx[d]
                    if not (0 <= qy < h and 0 <= qx < w):
                        continue
                    sy, sx = (y, x) if disparity[y, x] > disparity[qy, qx] else (qy, qx)
                    if dist[sy, sx] != 0:
                        dist[sy, sx] = 0
                        queue[tail] = sy * w + sx
                        tail += 1
    while head < tail:
        p = queue[head]
        head += 1
        y, x = p // w, p % w
        nd = dist[y, x] + 1
        if nd > limit:
            continue
        c = cuts[y, x]
        for d in range(4):
            if c & (1 << d):
                continue
            qy, qx = y + dy[d], x + dx[d]
            if not (0 <= qy < h and 0 <= qx < w) or cuts[qy, qx] & (1 << (d ^ 1)):
                continue
            if abs(disparity[qy, qx] - disparity[y, x]) > threshold:  # a step not cut
                continue
            if dist[qy, qx] > nd:
                dist[qy, qx] = nd
                queue[tail] = qy * w + qx
                tail += 1
    return dist


@numba.njit(cache=True)
def _matte(image, disparity, dist, band, radius, threshold, pairs, alpha, color,
           back):  # pragma: no cover - numba
    h, w = disparity.shape
    side = 2 * radius + 1
    fs = np.empty((side * side, 3), np.float32)
    bs = np.empty((side * side, 3), np.float32)
    bf = np.zeros(3, np.float32)
    bb = np.zeros(3, np.float32)
    for y in range(h):
        for x in range(w):
            if dist[y, x] >= band:
                continue
            dp = disparity[y, x]
            # foreground samples: the window's near-side pixels at least `band` steps
            # in, or (a structure thinner than 2 band) its innermost ones
            inner = 0
            for qy in range(max(0, y - radius), min(h, y + radius + 1)):
                for qx in range(max(0, x - radius), min(w, x + radius + 1)):
                    dq = dist[qy, qx]
                    if inner < dq < _FAR and abs(disparity[qy, qx] - dp) <= threshold:
                        inner = dq
            need = min(band, inner) if inner > 0 else band
            nf, nb = 0, 0
            for qy in range(max(0, y - radius), min(h, y + radius + 1)):
                for qx in range(max(0, x - radius), min(w, x + radius + 1)):
                    dq = dist[qy, qx]
                    same = abs(disparity[qy, qx] - dp) <= threshold
                    if need <= dq < _FAR and same:
                        for c in range(3):
                            fs[nf, c] = image[qy, qx, c]
                        nf += 1
                    elif disparity[qy, qx] <= dp - threshold and dq == _FAR:
                        for c in range(3):
                            bs[nb, c] = image[qy, qx, c]
                        nb += 1
            if nf == 0 or nb == 0:
                continue
            i0, i1, i2 = image[y, x, 0], image[y, x, 1], image[y, x, 2]
            best, ba = np.inf, 1.0
            if pairs:  # at most about MAX_SAMPLES of each, evenly spread over the window
                for i in range(0, nf, (nf + MAX_SAMPLES - 1) // MAX_SAMPLES):
                    for j in range(0, nb, (nb + MAX_SAMPLES - 1) // MAX_SAMPLES):
                        d0 = fs[i, 0] - bs[j, 0]
                        d1 = fs[i, 1] - bs[j, 1]
                        d2 = fs[i, 2] - bs[j, 2]
                        n2 = d0 * d0 + d1 * d1 + d2 * d2
                        if n2 < MIN_CONTRAST2:  # F and B alike: no evidence
                            continue
                        a = ((i0 - bs[j, 0]) * d0 + (i1 - bs[j, 1]) * d1
                             + (i2 - bs[j, 2]) * d2) / n2
                        a = min(max(a, 0.0), 1.0)
                        r0 = i0 - bs[j, 0] - a * d0
                        r1 = i1 - bs[j, 1] - a * d1
                        r2 = i2 - bs[j, 2] - a * d2
                        cost = (r0 * r0 + r1 * r1 + r2 * r2) / n2
                        if cost < best:
                            best, ba = cost, a
                            for c in range(3):
                                bf[c] = fs[i, c]
                                bb[c] = bs[j, c]
            else:
                for c in range(3):
                    bf[c] = fs[:nf, c].mean()
                    bb[c] = bs[:nb, c].mean()
                d0, d1, d2 = bf[0] - bb[0], bf[1] - bb[1], bf[2] - bb[2]
                n2 = d0 * d0 + d1 * d1 + d2 * d2
                if n2 >= MIN_CONTRAST2:
                    a = ((i0 - bb[0]) * d0 + (i1 - bb[1]) * d1 + (i2 - bb[2]) * d2) / n2
                    ba = min(max(a, 0.0), 1.0)
                    best = 0.0
            if best == np.inf or ba >= 0.97:
                continue
            if ba <= 0.03:
                ba = 0.0
            alpha[y, x] = ba
            for c in range(3):
                if ba >= 0.5:
                    v = (image[y, x, c] - (1.0 - ba) * bb[c]) / ba
                    color[y, x, c] = min(max(v, 0.0), 1.0)
                    back[y, x, c] = bb[c]
                else:
                    color[y, x, c] = bf[c]
                    v = (image[y, x, c] - ba * bf[c]) / (1.0 - ba)
                    back[y, x, c] = min(max(v, 0.0), 1.0)


KERNELS = (
    (_walk, "(float32[:, ::1], uint8[:, ::1], int32, float32)"),
    (_behind, "(int64[::1], int64[::1], int64[::1], int64[::1], float32[::1], float32)"),
    (_matte, "(float32[:, :, ::1], float32[:, ::1], int32[:, ::1], int32, int32, float32, "
             "boolean, float32[:, ::1], float32[:, :, ::1], float32[:, :, ::1])"),
)
