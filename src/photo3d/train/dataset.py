"""Training folders and their preparation: targets plus the region-pair pool.

A training folder is a folder of photos plus an optional folder of depth maps
matched by file stem (``images/cat.jpg`` <-> ``depth/cat.png``; any format
:func:`photo3d.io.depth.read_depth` reads), plus optional *shape-only* depth maps
(``shapes/``) that contribute region shapes but never pixels (use it for a benchmark
scene whose pixels must not be trained on).

Preparation (once per run folder, cached) brings every image to the working size
(longer side ``region_size``, shorter side at least the crop size) and, where there
is depth, runs the pipeline's preprocessing (normalised, sharpened disparity and the
background silhouettes of linked depth edges, exactly what inference sees) and
extracts at most 3 region pairs (:mod:`photo3d.train.pairs`). Every image is a
paste *target*; images with depth (and shape-only maps) are also region *sources*.

A folder of photos alone (no depth map, no shape-only map) can train the colour net:
its region shapes then come from ``builtin_shapes`` synthetic scenes
(:func:`photo3d.train.builtin.scene_disparity`, seeds from
:data:`~photo3d.train.builtin.FIRST_SEED` on, at the working size), shape-only
sources whose pixels are never drawn.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photo3d.config import Config, working_shape
from photo3d.depth.normalize import prepare_depth
from photo3d.errors import InputError, OutputError
from photo3d.files.atomic import write_json, writing
from photo3d.files.folders import IMAGE_SUFFIXES, depth_by_key, files_in
from photo3d.files.temps import is_temp_of
from photo3d.io.bounded import read_json
from photo3d.io.depth import read_depth
from photo3d.io.images import read_image
from photo3d.progress import StageProgress
from photo3d.stages.preprocess import preprocess, resize
from photo3d.train.pairs import RegionPair, extract_region_pairs

KINDS = ("edge", "depth", "color")
CACHE_VERSION = 1
BUILTIN_SHAPES = 12
"""Synthetic scenes that give the region shapes of a folder without any depth."""


@dataclass(frozen=True)
class TrainingFile:
    """One entry of a training folder.

    Attributes:
        name: file stem.
        image: the photo (None for a shape-only depth map).
        depth: its depth map, or None.
    """

    name: str
    image: Path | None
    depth: Path | None


@dataclass(frozen=True)
class Target:
    """A paste target at working size.

    Attributes:
        image: ``(H, W, 3) float32`` in [0, 1].
        disparity: ``(H, W) float32`` normalised, sharpened disparity, or None.
        edges: ``(H, W) bool`` background silhouette pixels of linked depth edges
            (the pipeline's edge pixels), or None.
    """

    image: np.ndarray
    disparity: np.ndarray | None
    edges: np.ndarray | None


def _files(folder: Path, suffixes: tuple[str, ...]) -> list[Path]:
    return files_in(folder, suffixes)


def _depth_by_stem(folder: Path | None, what: str) -> dict[str, Path]:
    return depth_by_key(folder, what)


def find_training_files(images: str | Path, *, depth: str | Path | None = None,
                        shapes: str | Path | None = None) -> list[TrainingFile]:
    """List a training folder: photos (with their depth maps by stem), then shape-only maps.

    Args:
        images: folder of photos (.jpg, .jpeg, .png, .tif, .tiff, .webp).
        depth: folder of depth maps named like the photos (optional).
        shapes: folder of depth maps used only for region shapes (optional).

    Returns:
        Photos sorted by name, then shape-only maps sorted by name.

    Raises:
        InputError: a folder is missing, or there is no photo.

    Example:
        >>> import tempfile
        >>> d = Path(tempfile.mkdtemp())
        >>> (d / "a.jpg").touch(); (d / "b.png").touch()
        >>> [(f.name, f.depth) for f in find_training_files(d)]
        [('a', None), ('b', None)]
    """
    images = Path(images)
    if not images.is_dir():
        raise InputError(f"images folder {images} does not exist or is not a folder")
    photos = _files(images, IMAGE_SUFFIXES)
    if not photos:
        raise InputError(f"no photos in {images} (looked for {', '.join(IMAGE_SUFFIXES)})")
    depths = _depth_by_stem(Path(depth) if depth is not None else None, "depth")
    files = [TrainingFile(p.stem, p, depths.get(p.stem)) for p in photos]
    files += [TrainingFile(stem, None, p) for stem, p in
              sorted(_depth_by_stem(Path(shapes) if shapes is not None else None,
                                    "shapes").items())]
    return files


def target_shape(shape: tuple[int, int], *, region_size: int, crop: int) -> tuple[int, int]:
    """Working ``(H, W)``: longer side ``region_size`` unless the shorter side would
    drop below ``crop``.

    Example:
        >>> target_shape((100, 400), region_size=256, crop=128)
        (128, 512)
    """
    h, w = shape
    long_side = max(region_size, -(-crop * max(h, w) // min(h, w)))
    return working_shape((h, w), long_side)


def _pairs(disparity: np.ndarray, image: np.ndarray | None, index: int, *,
           region_size: int, crop: int, depth_kind: str, max_pairs: int, seed: int):
    """``(preprocessed, pairs)`` of one depth map (and its photo, if any)."""
    dep = prepare_depth(disparity, image.shape[:2] if image is not None else disparity.shape,
                        kind=depth_kind)
    if image is None:
        image = np.zeros((*dep.disparity.shape, 3), np.float32)
    shape = target_shape(image.shape[:2], region_size=region_size, crop=crop)
    config = Config(size=max(shape))
    pre = preprocess(image, dep.disparity, config=config)
    pairs = extract_region_pairs(pre, config=config, source=index, max_pairs=max_pairs,
                                 rng=np.random.default_rng([seed, index]))
    return pre, pairs


def _prepare_one(f: TrainingFile, index: int, *, region_size: int, crop: int, depth_kind: str,
                 max_pairs: int, seed: int) -> tuple[Target | None, list[RegionPair]]:
    img = read_image(f.image) if f.image is not None else None
    if f.depth is None:
        shape = target_shape(img.shape[:2], region_size=region_size, crop=crop)
        return Target(np.clip(resize(img, shape), 0, 1), None, None), []
    pre, pairs = _pairs(read_depth(f.depth), img, index, region_size=region_size, crop=crop,
                        depth_kind=depth_kind, max_pairs=max_pairs, seed=seed)
    if f.image is None:
        return None, pairs
    return Target(pre.image, pre.disparity, pre.edges.labels > 0), pairs


def _builtin_pairs(count: int, first: int, *, region_size: int, crop: int, max_pairs: int,
                   seed: int) -> list[RegionPair]:
    """Region pairs of ``count`` synthetic scenes, sources ``first, first + 1, ...``."""
    from photo3d.train.builtin import FIRST_SEED, scene_disparity

    width = max(region_size, crop * 4 // 3)
    pairs: list[RegionPair] = []
    for i in range(count):
        disparity = scene_disparity(FIRST_SEED + i, width, width * 3 // 4)
        pairs += _pairs(disparity, None, first + i, region_size=region_size, crop=crop,
                        depth_kind="disparity", max_pairs=max_pairs, seed=seed)[1]
    return pairs


class TrainingData:
    """Prepared targets and the region-pair pool.

    Attributes:
        names: ``(T,)`` names of the targets (photos).
        has_depth: ``(T,) bool`` targets with depth.
        pool: every region pair (``source`` indexes the training files; shape-only
            maps come after the photos, so they are never a target).
    """

    def __init__(self, names: list[str], has_depth: np.ndarray, pool: list[RegionPair],
                 targets: list[Target | Path]) -> None:
        self.names = names
        self.has_depth = np.asarray(has_depth, bool)
        self.pool = pool
        self._targets = targets
        self._sources = np.unique([p.source for p in pool]).astype(np.int64)
        self._eligible: dict[str, np.ndarray] = {}

    def __len__(self) -> int:
        return len(self.names)

    def target(self, index: int) -> Target:
        """Target ``index`` (loaded from the cache if it lives there)."""
        t = self._targets[index]
        if isinstance(t, Target):
            return t
        with np.load(t, allow_pickle=False) as f:
            return Target(f["image"].astype(np.float32) / 255.0,
                          f["disparity"] if "disparity" in f else None,
                          f["edges"] if "edges" in f else None)

    def random_pair(self, target: int, rng: np.random.Generator) -> RegionPair:
        """A pair drawn uniformly from those of images other than ``target`` (one must
        exist: see :meth:`eligible`)."""
        while True:
            pair = self.pool[int(rng.integers(len(self.pool)))]
            if pair.source != target:
                return pair

    def eligible(self, kind: str) -> np.ndarray:
        """Targets usable for ``kind``: with depth for the edge and depth nets, any for
        colour; and with at least one region pair from another image."""
        if kind not in self._eligible:
            ok = self.has_depth.copy() if kind in ("edge", "depth") else np.ones(len(self), bool)
            if self._sources.size == 0:
                ok[:] = False  # no pairs at all
            elif self._sources.size == 1 and self._sources[0] < len(self):
                ok[self._sources[0]] = False  # its own pairs are the only ones
            self._eligible[kind] = np.flatnonzero(ok)
        return self._eligible[kind]

    def check(self, kind: str) -> None:
        """Raise :class:`InputError` (one line) unless ``kind`` can be trained."""
        if kind not in KINDS:
            raise InputError(f"unknown net {kind!r}; expected one of {', '.join(KINDS)}")
        if not self.pool:
            raise InputError(f"no region pairs: none of the {len(self)} photos (or shape maps) "
                             "has a depth map with depth edges (give --depth DIR with maps "
                             "named like the photos)")
        if kind in ("edge", "depth") and not self.has_depth.any():
            raise InputError(f"the {kind} net needs training photos with depth: none of the "
                             f"{len(self)} photos has a depth map (matched by file stem)")
        if not self.eligible(kind).size:
            need = "photo with depth" if kind in ("edge", "depth") else "photo"
            raise InputError(f"the {kind} net needs a {need} other than the one image whose "
                             "depth gives the region shapes (regions are pasted onto "
                             "*different* images)")


def _signature(files: list[TrainingFile], options: dict) -> str:
    parts = [json.dumps(options, sort_keys=True), str(CACHE_VERSION)]
    for f in files:
        for p in (f.image, f.depth):
            st = p.stat() if p is not None else None
            parts.append(f"{p}:{st.st_size}:{st.st_mtime_ns}" if st else "-")
    # surrogateescape: a file name that is not UTF-8 keeps its bytes (os.fsencode)
    return hashlib.sha256("\n".join(parts).encode("utf-8", "surrogateescape")).hexdigest()


def _save_pool(path: Path, pool: list[RegionPair]) -> None:
    shapes = np.array([p.context.shape for p in pool], np.int64).reshape(-1, 2)
    flat = [np.concatenate([p.context.ravel(), p.synthesis.ravel()]) for p in pool]
    with writing(path) as target:
        np.savez_compressed(target, shapes=shapes, sources=np.array([p.source for p in pool]),
                            masks=(np.packbits(np.concatenate(flat)) if flat
                                   else np.zeros(0, np.uint8)))


def _load_pool(path: Path) -> list[RegionPair]:
    with np.load(path, allow_pickle=False) as f:
        shapes, sources = f["shapes"], f["sources"]
        sizes = shapes.prod(1)
        bits = np.unpackbits(f["masks"], count=int(2 * sizes.sum())).astype(bool)
    pool, at = [], 0
    for (h, w), n, src in zip(shapes, sizes, sources, strict=True):
        ctx = bits[at:at + n].reshape(h, w)
        syn = bits[at + n:at + 2 * n].reshape(h, w)
        pool.append(RegionPair(ctx, syn, int(src)))
        at += 2 * n
    return pool


def _cache_signature(cache: Path) -> str | None:
    """The signature of a complete cache in ``cache``, None if there is none."""
    try:
        index = read_json(cache / "index.json")
    except InputError:  # missing, or not photo3d's
        return None
    return index.get("signature") if isinstance(index, dict) else None


def _clear_cache(cache: Path) -> None:
    """Remove the cache folder ``cache`` if it holds only files a preparation writes.

    Raises:
        OutputError: it holds anything else (named); nothing is removed.
    """
    if not cache.exists():
        return
    if not cache.is_dir() or cache.is_symlink():
        raise OutputError(f"data cache {cache} is not a folder photo3d wrote; move it away")
    targets = cache / "targets"
    mine = ("index.json", "pool.npz", "targets")
    foreign = [p.name for p in cache.iterdir() if p.name not in mine
               and not any(is_temp_of(p.name, name) for name in mine)]
    if targets.is_dir() and not targets.is_symlink():
        foreign += [f"targets/{p.name}" for p in targets.iterdir()
                    if not (p.is_file() and p.suffix == ".npz" and p.stem.isdigit())]
    elif targets.exists():
        foreign.append("targets")
    if foreign:
        raise OutputError(f"data cache {cache} holds {', '.join(sorted(foreign)[:3])}, "
                          "which photo3d did not write; move it away")
    shutil.rmtree(cache)


def prepare_data(files: list[TrainingFile], *, crop: int, region_size: int,
                 depth_kind: str = "disparity", max_pairs: int = 3, seed: int = 0,
                 builtin_shapes: int = BUILTIN_SHAPES, cache: str | Path | None = None,
                 progress: StageProgress | None = None) -> TrainingData:
    """Prepare targets and the pool; reuse ``cache`` if it was made from the same
    files (path, size, mtime) and options.

    Args:
        files: from :func:`find_training_files`.
        crop: training crop size (targets are at least this large).
        region_size: working size (longer side) of preprocessing and region growth.
        depth_kind: what the depth maps hold, ``"disparity"`` or ``"depth"``.
        max_pairs: region pairs per image (paper: at most 3).
        seed: seeds the choice of pairs.
        builtin_shapes: synthetic scenes giving the region shapes when no file has a
            depth map (see the module docstring; 0: none).
        cache: folder for the prepared data (None: keep everything in memory).
        progress: ``progress("prepare", fraction)``.

    Returns:
        :class:`TrainingData`.

    Example:
        >>> import tempfile
        >>> from photo3d.io.images import write_image
        >>> d = Path(tempfile.mkdtemp())
        >>> write_image(d / "a.png", np.full((32, 48, 3), 0.5, np.float32))
        >>> data = prepare_data(find_training_files(d), crop=32, region_size=48,
        ...                     builtin_shapes=0)
        >>> data.target(0).image.shape, len(data.pool)
        ((32, 48, 3), 0)
        >>> data = prepare_data(find_training_files(d), crop=32, region_size=48,
        ...                     builtin_shapes=2)  # shapes from two synthetic scenes
        >>> len(data.pool) > 0, data.eligible("color").tolist(), data.eligible("depth").size
        (True, [0], 0)
    """
    builtin = builtin_shapes if not any(f.depth is not None for f in files) else 0
    options = dict(crop=crop, region_size=region_size, depth_kind=depth_kind,
                   max_pairs=max_pairs, seed=seed, builtin_shapes=builtin)
    report = progress or (lambda stage, fraction: None)
    photos = [f for f in files if f.image is not None]
    files = photos + [f for f in files if f.image is None]  # target i = file i
    sig = _signature(files, options)
    cache = Path(cache) if cache is not None else None
    names = [f.name for f in photos]
    has_depth = np.array([f.depth is not None for f in photos], bool)
    if cache is not None and _cache_signature(cache) == sig:
        report("prepare", 1.0)
        targets: list[Target | Path] = [cache / "targets" / f"{i:06d}.npz"
                                        for i in range(len(photos))]
        return TrainingData(names, has_depth, _load_pool(cache / "pool.npz"), targets)
    if cache is not None:
        _clear_cache(cache)  # stale, or left incomplete by an interrupted preparation
        (cache / "targets").mkdir(parents=True)
    pool: list[RegionPair] = []
    targets = []
    for i, f in enumerate(files):
        target, pairs = _prepare_one(f, i, region_size=region_size, crop=crop,
                                     depth_kind=depth_kind, max_pairs=max_pairs, seed=seed)
        pool += pairs
        if target is not None:
            if cache is None:
                targets.append(target)
            else:
                path = cache / "targets" / f"{i:06d}.npz"
                arrays = {"image": np.round(target.image * 255).astype(np.uint8)}
                if target.disparity is not None:
                    arrays.update(disparity=target.disparity, edges=target.edges)
                with writing(path) as target:
                    np.savez(target, **arrays)
                targets.append(path)
        report("prepare", (i + 1) / (len(files) + builtin))
    if builtin:
        pool += _builtin_pairs(builtin, len(files), region_size=region_size, crop=crop,
                               max_pairs=max_pairs, seed=seed)
        report("prepare", 1.0)
    if cache is not None:
        _save_pool(cache / "pool.npz", pool)
        write_json(cache / "index.json", {"signature": sig, "options": options, "names": names,
                                          "pairs": len(pool)})  # last: marks the cache complete
    return TrainingData(names, has_depth, pool, targets)
