"""Shared canvases (docs/learned.md): patches of one pass filled together, never reading
another edge's foreground."""

from __future__ import annotations

import numpy as np
import pytest

from photo3d.inpaint.canvas import joint_patch, share_canvases
from photo3d.structures.patch import Patch


def strip(x0: int, *, ctx_cols: int, syn_cols: int, disparity: float, h: int = 16,
          y0: int = 0) -> Patch:
    """Context ``ctx_cols`` wide from ``x0``, synthesis right of it."""
    w = ctx_cols + syn_cols
    ctx = np.zeros((h, w), bool)
    ctx[:, :ctx_cols] = True
    color = np.full((h, w, 3), disparity, np.float32) * ctx[..., None]
    return Patch(color, np.float32(disparity) * ctx.astype(np.float32),
                 np.zeros((h, w), np.float32), ctx, ~ctx, (y0, x0))


def test_every_patch_lands_in_one_canvas_and_no_hole_covers_a_context():
    rng = np.random.default_rng(0)
    patches = [strip(int(rng.integers(0, 60)), ctx_cols=int(rng.integers(4, 12)),
                     syn_cols=int(rng.integers(4, 12)), disparity=0.3,
                     y0=int(rng.integers(0, 20))) for _ in range(30)]
    canvases = share_canvases(patches)
    members = sorted(i for c in canvases for i in c.members)
    assert members == list(range(30))
    assert len(canvases) < 30  # some sharing happened
    for c in canvases:
        y0, x0 = c.patch.origin
        for i in c.members:
            p = patches[i]
            win = (slice(p.origin[0] - y0, p.origin[0] - y0 + p.shape[0]),
                   slice(p.origin[1] - x0, p.origin[1] - x0 + p.shape[1]))
            # the member's hole is a hole of the canvas, its context a context
            assert not (c.patch.context[win] & p.synthesis & ~p.context).any()
            assert c.patch.context[win][p.context].all()


def test_two_layers_at_one_position_never_share_a_canvas():
    a = strip(0, ctx_cols=6, syn_cols=6, disparity=0.2)
    b = strip(0, ctx_cols=6, syn_cols=6, disparity=0.6)  # same positions, other layer
    assert sorted(c.members for c in share_canvases([a, b])) == [(0,), (1,)]
    assert joint_patch([a, b]) is None


def test_a_foreground_beside_a_hole_is_hidden_from_it():
    """A: background context (0.2) then its hole; B: a nearer surface (0.7) right of
    A's hole (B's context). Sharing would let A's hole see what hides it."""
    a = strip(0, ctx_cols=8, syn_cols=8, disparity=0.2)
    b = strip(17, ctx_cols=8, syn_cols=4, disparity=0.7)
    assert len(share_canvases([a, b])) == 2
    j = joint_patch([a, b], reach=4)
    assert not j.context[:, 16:20].any()  # B's pixels within 4 px of A's hole: hidden
    assert j.context[:, 20:25].all() and j.context[:, :8].all()
    far = strip(17, ctx_cols=8, syn_cols=4, disparity=0.2)  # same depth: no foreground
    assert joint_patch([a, far], reach=4).context[:, 17:25].all()


@pytest.mark.parametrize("share", [False, True])
def test_shared_and_per_patch_filling_agree_on_one_patch(share):
    torch = pytest.importorskip("torch")
    from photo3d.inpaint.learned import LearnedInpainter
    from photo3d.nets import InpaintingNets, build_net

    torch.manual_seed(0)
    nets = InpaintingNets(build_net("edge", width=0.125, blocks=1).eval(),
                          build_net("depth", levels=3, width=0.125).eval(),
                          build_net("color", levels=3, width=0.125).eval(), "cpu", {})
    p = strip(0, ctx_cols=20, syn_cols=12, disparity=0.3, h=24)
    ref = LearnedInpainter(nets=nets, share=False).inpaint([p])[0]
    out = LearnedInpainter(nets=nets, share=share).inpaint([p])[0]
    np.testing.assert_allclose(out.color, ref.color, atol=1e-5)
    np.testing.assert_allclose(out.disparity, ref.disparity, atol=1e-5)
