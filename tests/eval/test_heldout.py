"""The held-out fill benchmark: region shapes from the real first pass, deterministic
placement, fills that see only the context, scores, and ``photo3d eval --heldout``."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from conftest import texture
from PIL import Image

import photo3d
from photo3d.cli import main
from photo3d.config import Config, PreprocessConfig, RegionConfig
from photo3d.errors import InputError
from photo3d.eval.heldout import (
    PSNR_CAP,
    ReplicateFill,
    backend,
    border_masks,
    evaluate_heldout,
    evaluate_photo,
    fill,
    make_border,
)
from photo3d.eval.heldout_data import first_pass_shapes, photo_files, place
from photo3d.structures.patch import InpaintResult

# edges "exact": the held-out shapes come from the depth alone (no photo to align to),
# so make hands its backend the same shapes only without aligning depth edges
CONFIG = Config(size=None, spatial_scale=1.0, edges="exact",
                regions=RegionConfig(synthesis_iterations=10, context_iterations=14,
                                     edge_dilation=2, border=6),
                preprocess=PreprocessConfig(min_edge_length=5))


def disparity(h: int = 96, w: int = 128) -> np.ndarray:
    """A far plane with two near boxes: several depth edges."""
    d = np.ones((h, w), np.float32)
    d[20:60, 24:64] = 3.0
    d[50:80, 80:116] = 2.0
    return d


@pytest.fixture(scope="module")
def bank():
    return first_pass_shapes(disparity(), source="boxes", config=CONFIG,
                             min_synthesis=32, min_context=32)


def photo(seed: int = 0, h: int = 96, w: int = 128) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.clip(texture(h, w, seed) + rng.normal(0, 0.03, (h, w, 3)), 0, 1).astype(np.float32)


def crop(a: np.ndarray) -> np.ndarray:
    ys, xs = np.nonzero(a)
    return a[ys.min():ys.max() + 1, xs.min():xs.max() + 1]


class Spy:
    """Records the masks of the first pass's patches, fills with the context mean."""

    name, margin = "spy", 3

    def __init__(self):
        self.seen = []

    def inpaint(self, patches, *, progress=None, pass_index=0):
        out = []
        for p in patches:
            if pass_index == 0:
                self.seen.append((p.context.copy(), p.synthesis & ~p.context))
            mean = p.color[p.context].mean(axis=0) if p.context.any() else np.zeros(3)
            out.append(InpaintResult(np.broadcast_to(mean, (*p.shape, 3)).astype(np.float32),
                                     np.full(p.shape, p.disparity[p.context].min(), np.float32),
                                     np.zeros(p.shape, np.float32)))
        return out


def test_region_shapes_are_the_pairs_make_hands_its_backend():
    spy = Spy()
    photo3d.make(photo(), depth=disparity(), config=CONFIG, inpainter=spy)
    shapes = first_pass_shapes(disparity(), source="boxes", config=CONFIG,
                               min_synthesis=0, min_context=0)
    assert len(shapes) == len(spy.seen) >= 2
    for s, (ctx, syn) in zip(shapes, spy.seen, strict=True):
        union = ctx | syn
        ys, xs = np.nonzero(union)
        box = (slice(ys.min(), ys.max() + 1), slice(xs.min(), xs.max() + 1))
        assert np.array_equal(s.context, ctx[box]) and np.array_equal(s.synthesis, syn[box])
        assert s.context.any() and s.synthesis.any() and not (s.context & s.synthesis).any()
        assert crop(s.context | s.synthesis).shape == s.shape  # cropped to the bounding box


def test_small_regions_are_left_out(bank):
    every = first_pass_shapes(disparity(), source="boxes", config=CONFIG,
                              min_synthesis=0, min_context=0)
    big = max(int(s.synthesis.sum()) for s in every)
    kept = first_pass_shapes(disparity(), source="boxes", config=CONFIG, min_synthesis=big,
                             min_context=0)
    assert len(kept) == sum(int(s.synthesis.sum()) >= big for s in every) < len(every)
    assert all(s.source == "boxes" for s in bank) and len(bank) >= 2


def test_placement_depends_on_seed_and_name_only(bank, tmp_path):
    a = place((96, 128), bank, "a.png", count=3)
    assert a == place((96, 128), bank, "a.png", count=3)
    assert a != place((96, 128), bank, "b.png", count=3)
    assert a != place((96, 128), bank, "a.png", count=3, seed=1)
    assert len({p.shape for p in a}) == len(a)
    for p in a:
        h, w = bank[p.shape].shape
        assert 0 <= p.y <= 96 - h and 0 <= p.x <= 128 - w
    for i, name in enumerate(("c.png", "a.png", "b.jpg")):
        Image.fromarray((photo(i) * 255).astype(np.uint8)).save(tmp_path / name)
    files = photo_files(tmp_path)
    kw = dict(methods=["replicate"], count=2, size=128, border=16, lpips=False, bank=bank)
    forward = evaluate_heldout(files, **kw).to_dict()["photos"]
    backward = evaluate_heldout(files[::-1][:2], **kw).to_dict()["photos"]
    for name in backward:
        assert backward[name] == {**forward[name], "seconds": backward[name]["seconds"]}


class Peek:
    """Reads every pixel it is given: the patch's colour plus its mean over the patch."""

    name, margin = "peek", 4

    def inpaint(self, patches, *, progress=None, pass_index=0):
        return [InpaintResult(p.color + p.color.mean(axis=(0, 1)), p.disparity, p.edges)
                for p in patches]


@pytest.mark.parametrize("method", ["peek", "diffusion", "structured", "replicate", "learned"])
def test_a_fill_never_sees_pixels_outside_the_context(bank, method):
    if method == "learned":
        pytest.importorskip("torch")
    fill_with = Peek() if method == "peek" else backend(method)
    image = photo(3)
    rng = np.random.default_rng(1)
    for p in place(image.shape[:2], bank, "x.png", count=2):
        s = bank[p.shape]
        known = np.zeros(image.shape[:2], bool)
        known[p.y:p.y + s.shape[0], p.x:p.x + s.shape[1]] = s.context
        poisoned = np.where(known[..., None], image, rng.random(image.shape)).astype(np.float32)
        clean = fill(fill_with, image, s.context, s.synthesis, (p.y, p.x))
        dirty = fill(fill_with, poisoned, s.context, s.synthesis, (p.y, p.x))
        assert np.array_equal(clean[s.synthesis], dirty[s.synthesis])
    ctx, ring = border_masks(image.shape[:2], 12, 10)
    poisoned = np.where(ctx[..., None], image, 1 - image).astype(np.float32)
    assert np.array_equal(fill(fill_with, image, ctx, ring, (0, 0))[ring],
                          fill(fill_with, poisoned, ctx, ring, (0, 0))[ring])


class Oracle:
    """Returns the true photo under its patch (found through the patch's origin)."""

    name, margin = "oracle", 5

    def __init__(self, image):
        self.padded = np.pad(image, ((self.margin,) * 2, (self.margin,) * 2, (0, 0)))

    def inpaint(self, patches, *, progress=None, pass_index=0):
        out = []
        for p in patches:
            y, x = p.origin[0] + self.margin, p.origin[1] + self.margin
            color = self.padded[y:y + p.shape[0], x:x + p.shape[1]]
            out.append(InpaintResult(color, p.disparity, np.zeros(p.shape, np.float32)))
        return out


def test_a_perfect_fill_scores_perfectly_and_a_blank_one_does_not(bank):
    pytest.importorskip("torch")
    image = photo(4)

    class Blank(ReplicateFill):
        def inpaint(self, patches, **kw):
            return [InpaintResult(np.zeros((*p.shape, 3), np.float32), p.disparity, p.edges)
                    for p in patches]

    rec = evaluate_photo(image, "p.png", {"oracle": Oracle(image), "blank": Blank()},
                         bank=bank, count=3, border=16)
    for part in ("regions", "border"):
        perfect, blank = rec[part]["oracle"], rec[part]["blank"]
        assert perfect["lpips"] < 1e-6 and perfect["psnr"] == PSNR_CAP
        assert perfect["ssim"] == pytest.approx(1.0)
        assert blank["lpips"] > 0.1 and blank["psnr"] < 15 and blank["ssim"] < 0.5


def test_make_border_scores_what_make_puts_past_the_frame():
    flat = np.full((80, 96, 3), 0.4, np.float32)
    small = Config(size=None)
    same = make_border(flat, config=small, ring=8, lpips=False)
    assert same["psnr"] > 40 and same["inner_psnr"] > 40
    noisy = make_border(photo(5, 80, 96), config=small, ring=8, lpips=False)
    assert noisy["inner_psnr"] > 30 > noisy["psnr"]
    with pytest.raises(InputError, match="too small"):
        make_border(flat[:20], ring=8)


def test_eval_heldout_writes_results_and_refuses_bad_folders(tmp_path, capsys):
    photos = tmp_path / "photos"
    photos.mkdir()
    for i, name in enumerate(("one.png", "two.jpg")):
        Image.fromarray((photo(i, 120, 160) * 255).astype(np.uint8)).save(photos / name)
    (photos / "notes.txt").write_text("not a photo")
    (photos / "broken.png").write_bytes(b"\x89PNG not really")
    out = tmp_path / "ev"
    assert main(["eval", "--heldout", str(photos), "--methods", "replicate", "--no-lpips",
                 "--per-photo", "2", "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "one.png:" in err and "two.jpg:" in err  # a progress line per photo
    assert sorted(p.name for p in out.iterdir()) == ["results.json", "results.md"]
    record = json.loads((out / "results.json").read_text())
    assert record["methods"] == ["replicate"] and sorted(record["photos"]) == ["one.png",
                                                                              "two.jpg"]
    assert set(record["mean"]) == {"regions", "border", "make_border"}
    assert len(record["photos"]["one.png"]["placements"]) == 2
    assert list(record["skipped"]) == ["broken.png"] and "broken.png: skipped" in err
    assert "| replicate |" in (out / "results.md").read_text()
    assert main(["eval", "--heldout", str(photos), "--methods", "replicate", "--no-lpips",
                 "--per-photo", "1", "-o", str(out), "--overwrite", "-q"]) == 0
    assert len(json.loads((out / "results.json").read_text())["photos"]["one.png"]
               ["placements"]) == 1
    capsys.readouterr()
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "notes.txt").write_text("x")
    for folder in (tmp_path / "missing", empty, photos / "one.png"):
        target = tmp_path / "never"
        assert main(["eval", "--heldout", str(folder), "-o", str(target), "-q"]) == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("photo3d: error:")
        assert not target.exists()
    assert main(["eval", "--heldout", str(photos), "--methods", "magic", "-o",
                 str(tmp_path / "never")]) == 2
    assert "unknown method" in capsys.readouterr().err
    shutil.rmtree(out)
