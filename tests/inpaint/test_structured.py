import numpy as np
import pytest
from conftest import exact_config

import photo3d
from photo3d.inpaint import get_inpainter
from photo3d.inpaint.continuation import continue_edges
from photo3d.inpaint.exemplar import exemplar_fill
from photo3d.inpaint.structured import piecewise_diffuse
from photo3d.structures.patch import Patch

H, W = 96, 128
SLOPE, ROW0 = 0.2, 45.0  # hidden edge: y = ROW0 + SLOPE * (x - 64), pixel centres


def slanted(h=H, w=W):
    """Dark above a straight slanted edge, bright below, with a faint texture."""
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    bright = yy > ROW0 + SLOPE * (xx - 64)
    rng = np.random.default_rng(1)
    img = np.where(bright, 0.8, 0.2)[..., None] + rng.normal(0, 0.01, (h, w, 3))
    return np.clip(img, 0, 1).astype(np.float32), bright


def first_bright_row(column: np.ndarray) -> float:
    return float(np.argmax(column > 0.5))


def test_continued_line_follows_a_slanted_edge():
    img, bright = slanted()
    ctx = np.ones((H, W), bool)
    ctx[20:80, 50:90] = False  # the hole cuts the edge
    lines = continue_edges(img * ctx[..., None], np.zeros((H, W), np.float32), ctx, ~ctx)
    assert lines[~ctx].sum() > 30 and not lines[ctx].any()
    ys, xs = np.nonzero(lines)
    truth = ROW0 + SLOPE * (xs + 0.5 - 64) - 0.5
    assert np.abs(ys - truth).max() <= 2.0


def test_piecewise_diffusion_does_not_cross_a_barrier():
    v = np.zeros((10, 10, 1), np.float32)
    v[:5, 0] = 1.0  # context column: white above, black below
    ctx = np.zeros((10, 10), bool)
    ctx[:, 0] = True
    bar = np.zeros((10, 10), bool)
    bar[5, 1:] = True
    out = piecewise_diffuse(v, ctx, ~ctx, bar)
    np.testing.assert_allclose(out[:5, 1:, 0], 1.0, atol=1e-2)
    np.testing.assert_allclose(out[6:, 1:, 0], 0.0, atol=1e-2)


def test_exemplar_sources_never_leave_the_context():
    rng = np.random.default_rng(0)
    img = rng.random((30, 30, 3)).astype(np.float32)
    ctx = np.zeros((30, 30), bool)
    ctx[:, :12] = True
    syn = np.zeros((30, 30), bool)
    syn[:, 12:20] = True
    poisoned = img.copy()
    poisoned[~ctx & ~syn] = 1e6  # foreground: must never be copied
    a = exemplar_fill(poisoned, ctx, syn, copy=True)
    assert a[syn].max() <= img[ctx].max() + 1e-6
    # every copied value exists in the context (copy mode copies pixels)
    values = {tuple(v) for v in img[ctx].round(6)}
    assert all(tuple(v) in values for v in a[syn].round(6))
    # deterministic for a seed
    np.testing.assert_array_equal(a, exemplar_fill(poisoned, ctx, syn, copy=True))


def test_structured_backend_keeps_the_context_and_fills_in_range():
    img, _ = slanted(40, 40)
    ctx = np.zeros((40, 40), bool)
    ctx[:, :15] = True
    p = Patch(img * ctx[..., None], np.full((40, 40), 0.3, np.float32) * ctx,
              np.zeros((40, 40), np.float32), ctx, ~ctx, (0, 0))
    (r,) = get_inpainter("structured").inpaint([p])
    assert r.color.shape == (40, 40, 3) and r.disparity.shape == (40, 40)
    assert r.color.min() >= 0 and r.color.max() <= 1
    np.testing.assert_allclose(r.disparity[~ctx], 0.3, atol=1e-3)


def hidden_layer(photo) -> np.ndarray:
    """(H, W) grey value of the inpainted background layer, NaN where none."""
    ldi = photo.ldi
    new = np.arange(ldi.size) >= H * W
    out = np.full((H, W), np.nan, np.float32)
    sel = new & (ldi.y >= 0) & (ldi.y < H) & (ldi.x >= 0) & (ldi.x < W)
    out[ldi.y[sel], ldi.x[sel]] = ldi.color[sel].mean(axis=1)
    return out


@pytest.mark.parametrize("name", ["structured"])
def test_hidden_straight_edge_is_continued_within_2px(name):
    """The edge behind a foreground square continues to within
    2 px of the truth, sharply (diffusion smears it over many rows)."""
    img, bright = slanted()
    disp = np.ones((H, W), np.float32)
    disp[25:75, 54:78] = 3.0  # foreground square hides the middle of the edge
    cfg = exact_config(synthesis_iterations=30, context_iterations=60)
    layer = hidden_layer(photo3d.make(img, depth=disp, config=cfg.with_(inpainter=name)))
    smear = hidden_layer(photo3d.make(img, depth=disp, config=cfg.with_(inpainter="diffusion")))
    errors, widths, diffusion_widths = [], [], []
    for x in range(56, 76):
        col = layer[25:75, x]
        assert np.isfinite(col).all(), "the whole column behind the square is filled"
        truth = float(np.argmax(bright[25:75, x]))
        errors.append(abs(first_bright_row(col) - truth))
        widths.append(int(((col > 0.3) & (col < 0.7)).sum()))
        diffusion_widths.append(int(((smear[25:75, x] > 0.3) & (smear[25:75, x] < 0.7)).sum()))
    assert max(errors) <= 2.0
    assert max(widths) <= 2 < min(diffusion_widths)


def test_patches_know_how_much_the_photo_was_enlarged():
    seen = []

    class Spy:
        name, margin = "spy", 1

        def inpaint(self, patches, *, progress=None, pass_index=0):
            seen.extend(p.scale for p in patches)
            return get_inpainter("diffusion").inpaint(patches)

    img = np.random.default_rng(0).random((48, 64, 3)).astype(np.float32)
    disp = np.ones((48, 64), np.float32)
    disp[12:36, 20:44] = 3.0
    photo3d.make(img, depth=disp, config=photo3d.Config(size=128), inpainter=Spy())
    assert seen and all(s == pytest.approx(2.0) for s in seen)


def test_texture_patches_are_sized_in_photo_pixels(monkeypatch):
    import photo3d.inpaint.structured as st

    radii = []

    def spy(image, context, synthesis, *, radius, **kw):
        radii.append(radius)
        return image

    monkeypatch.setattr(st, "exemplar_fill", spy)
    col = np.zeros((20, 30, 3), np.float32)
    ctx = np.zeros((20, 30), bool)
    ctx[:, :15] = True
    inp = get_inpainter("structured")
    for scale in (1.0, 3.2):
        inp.fill(Patch(col, np.zeros((20, 30), np.float32), np.zeros((20, 30), np.float32),
                       ctx, ~ctx, (0, 0), scale))
    assert radii == [2, 5]


def test_structured_backend_reports_its_continued_lines_as_edges():
    img, _ = slanted()
    ctx = np.ones((H, W), bool)
    ctx[20:80, 50:90] = False
    p = Patch(img * ctx[..., None], np.full((H, W), 0.3, np.float32) * ctx,
              np.zeros((H, W), np.float32), ctx, ~ctx, (0, 0))
    inp = get_inpainter("structured")
    (r,) = inp.inpaint([p])
    lines = continue_edges(p.color, p.disparity, ctx, ~ctx, **inp.structure)
    assert lines.sum() > 30
    np.testing.assert_array_equal(r.edges > 0, lines)
