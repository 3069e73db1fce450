"""The learned backend: wiring of the three nets around each patch, and which nets
``learned`` runs (the paper's by default, downloaded once; ``--weights compact`` the
shipped ones).

Random compact nets check shapes and that nothing outside the context is read; stub
nets with known outputs check thresholds, depth conversion, rescaling and batching.
"""

from __future__ import annotations

import copy
import dataclasses
import functools

import numpy as np
import pytest
from conftest import exact_config, texture, two_planes

torch = pytest.importorskip("torch")

import photo3d  # noqa: E402
import photo3d.inpaint.learned  # noqa: E402,F401  (registers "learned")
from photo3d.camera import DepthMapping  # noqa: E402
from photo3d.errors import ConfigError, InputError  # noqa: E402
from photo3d.inpaint import get_inpainter  # noqa: E402
from photo3d.inpaint.learned import LearnedInpainter, close_gaps  # noqa: E402
from photo3d.nets import InpaintingNets, build_net, save_safetensors  # noqa: E402
from photo3d.structures.patch import Patch  # noqa: E402

SMALL = {"edge": dict(width=0.125, blocks=1), "depth": dict(levels=3, width=0.125),
         "color": dict(levels=3, width=0.125)}


def random_nets(seed: int = 0) -> InpaintingNets:
    torch.manual_seed(seed)
    built = {k: build_net(k, **cfg).eval() for k, cfg in SMALL.items()}
    return InpaintingNets(**built, device=torch.device("cpu"), sources={})


class Const(torch.nn.Module):
    """Stub net: a constant output with ``channels`` channels; records input shapes."""

    def __init__(self, channels: int, value: float) -> None:
        super().__init__()
        self.channels, self.value, self.calls = channels, value, []

    def forward(self, x):
        self.calls.append(x.clone())
        return torch.full((x.shape[0], self.channels, *x.shape[2:]), self.value)


def stub_nets(edge=0.5, depth=0.0, color=0.25) -> InpaintingNets:
    return InpaintingNets(Const(1, edge), Const(1, depth), Const(3, color),
                          torch.device("cpu"), {})


def make_patch(h=40, w=56, seed=0, split=24, edge_col=True) -> Patch:
    """Context on the left (with a column of edge pixels at its border), synthesis
    right of it, an unrelated strip (neither) on the far right."""
    rng = np.random.default_rng(seed)
    ctx = np.zeros((h, w), bool)
    ctx[:, :split] = True
    syn = np.zeros((h, w), bool)
    syn[:, split:w - 8] = True
    edges = np.zeros((h, w), np.float32)
    if edge_col:
        edges[:, split - 1] = 1
    color = rng.random((h, w, 3)).astype(np.float32) * ctx[..., None]
    disp = (0.2 + 0.3 * rng.random((h, w))).astype(np.float32) * ctx
    return Patch(color, disp, edges, ctx, syn, (0, 0))


FAKE = {kind: f"not the authors' {kind} net ".encode() * 1000 for kind in SMALL}
AUTHORS_FILES = ["edge-model.pth", "depth-model.pth", "color-model.pth"]


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache, and the fake files' sums as the authors'; returns the folder
    the authors' weights go to."""
    import hashlib

    from photo3d.nets import weights

    monkeypatch.setenv("PHOTO3D_CACHE", str(tmp_path / "cache"))
    for kind, data in FAKE.items():
        monkeypatch.setitem(weights.OFFICIAL_SHA256, kind, hashlib.sha256(data).hexdigest())
    return tmp_path / "cache" / "authors"


@pytest.fixture
def offline(cache, monkeypatch):
    """The authors' URL at a port nothing listens on."""
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    monkeypatch.setenv("PHOTO3D_AUTHORS_URL", f"http://127.0.0.1:{port}/model/")
    return cache


@pytest.fixture
def mirror(cache, tmp_path, monkeypatch):
    """A local mirror (``file://``) of the (fake) authors' files."""
    served = tmp_path / "mirror"
    served.mkdir()
    for kind, data in FAKE.items():
        (served / f"{kind}-model.pth").write_bytes(data)
    monkeypatch.setenv("PHOTO3D_AUTHORS_URL", served.as_uri())
    return cache


def test_learned_without_weights_is_the_papers_nets_and_offline_says_what_to_do(offline):
    with pytest.raises(InputError) as err:
        get_inpainter("learned")  # not the shipped compact nets, silently
    message = str(err.value)
    assert message.startswith("cannot download http://127.0.0.1:") and "\n" not in message
    assert f"into {offline}" in message
    assert message.endswith("or run the small nets shipped with photo3d: --weights compact")


def test_learned_without_weights_downloads_the_authors_files_once(mirror):
    with pytest.raises(InputError, match="cannot read edge-model.pth: not a PyTorch state"):
        get_inpainter("learned")  # downloaded, then the loader sees they are fakes
    assert sorted(p.name for p in mirror.iterdir()) == sorted(AUTHORS_FILES)
    assert photo3d.inpaint.learned.default_weights() == mirror


@pytest.fixture
def files(tmp_path):
    from photo3d.io.images import write_image

    img, disp = two_planes(64, 96)
    write_image(tmp_path / "photo.png", img)
    np.save(tmp_path / "depth.npy", disp)
    return tmp_path


def make_learned(files, *extra: str) -> int:
    from photo3d.cli import main

    return main(["make", str(files / "photo.png"), "--depth", str(files / "depth.npy"),
                 "-o", str(files / "out"), "--size", "96", "--no-video", "--no-viewer",
                 "--inpainter", "learned", *extra])


def test_make_learned_offline_is_one_line_naming_the_shipped_nets(files, offline, capsys):
    assert make_learned(files, "-q") == 2
    err = capsys.readouterr().err
    assert err.startswith("photo3d: error: cannot download ") and err.count("\n") == 1
    assert f"into {offline}, or run the small nets shipped with photo3d: --weights " \
           "compact" in err
    assert not (files / "out").exists()


def test_make_learned_downloads_the_authors_weights_with_progress(files, mirror, capsys):
    from photo3d.nets.authors import authors_url

    assert make_learned(files) == 2  # the fake files are no state dicts: the loader says so
    err = capsys.readouterr().err.splitlines()
    assert err[0] == f"downloading the authors' weights from {authors_url()} into {mirror}"
    assert err[-1].startswith("photo3d: error: cannot read edge-model.pth")
    assert sorted(p.name for p in mirror.iterdir()) == sorted(AUTHORS_FILES)


def test_weights_compact_runs_the_shipped_nets(files, offline):
    import json

    assert make_learned(files, "--weights", "compact", "-q") == 0
    meta = json.loads((files / "out" / "config.json").read_text())
    assert meta["inpainter"]["weights"] == "bundled compact"


def test_bundled_compact_weights_load_and_fit_the_size_limit():
    folder = photo3d.inpaint.learned.bundled_weights()
    files = sorted(folder.glob("*.safetensors"))
    assert [f.name for f in files] == ["color.safetensors", "depth.safetensors",
                                       "edge.safetensors"]
    assert sum(f.stat().st_size for f in files) <= 20 * 2**20
    inp = get_inpainter("learned", weights=folder, device="cpu")
    assert inp.nets.sources == {k: "safetensors" for k in SMALL}
    assert inp.nets.edge.config["width"] < 1 and inp.nets.color.config["width"] < 1
    r = inp.inpaint([make_patch()])[0]
    syn = make_patch().synthesis
    assert np.isfinite(r.color).all() and 0 <= r.disparity[syn].min()


def test_registered_and_loads_weights(tmp_path):
    for kind, net in random_nets().__dict__.items():
        if kind in SMALL:
            save_safetensors(net, tmp_path / f"{kind}.safetensors")
    inp = get_inpainter("learned", weights=tmp_path, device="cpu")
    assert isinstance(inp, LearnedInpainter) and inp.margin == 20
    assert inp.nets.sources == {k: "safetensors" for k in SMALL}


def test_random_nets_give_finite_results_of_the_patch_shape():
    patches = [make_patch(), make_patch(33, 70, seed=1)]
    calls = []
    results = LearnedInpainter(nets=random_nets()).inpaint(
        patches, progress=lambda done, total: calls.append((done, total)))
    assert calls[-1] == (2, 2) and [d for d, _ in calls] == sorted(d for d, _ in calls)
    for p, r in zip(patches, results, strict=True):
        h, w = p.shape
        assert r.color.shape == (h, w, 3) and r.disparity.shape == (h, w)
        assert r.edges.shape == (h, w)
        for a in (r.color, r.disparity, r.edges):
            assert a.dtype == np.float32 and np.isfinite(a).all()
        assert r.color.min() >= 0 and r.color.max() <= 1
        assert r.disparity.min() >= 0 and r.disparity.max() <= 1


def test_never_reads_outside_the_context():
    p = make_patch()
    rng = np.random.default_rng(5)
    outside = ~p.context
    poisoned = Patch(np.where(outside[..., None], rng.random(p.color.shape) * 50, p.color),
                     np.where(outside, 7.0 + rng.random(p.shape), p.disparity),
                     np.where(outside, 1.0, p.edges), p.context, p.synthesis, p.origin)
    inp = LearnedInpainter(nets=random_nets(), edge_threshold=0.5)
    a, b = inp.inpaint([p])[0], inp.inpaint([poisoned])[0]
    syn = p.synthesis
    np.testing.assert_array_equal(a.color[syn], b.color[syn])
    np.testing.assert_array_equal(a.disparity[syn], b.disparity[syn])
    np.testing.assert_array_equal(a.edges[syn], b.edges[syn])


def test_edge_threshold_and_repeats():
    p = make_patch()
    nets = stub_nets(edge=0.003)  # just above the authors' 0.002 everywhere
    r = LearnedInpainter(nets=nets, paths=False).inpaint([p])[0]
    np.testing.assert_array_equal(r.edges, np.maximum(p.edges, p.synthesis))
    # once, then a repeat with the new edges fed back; it finds the same edges, so a
    # third run would see the same input: none follows
    assert len(nets.edge.calls) == 2
    fed_back = nets.edge.calls[-1][0, 4].numpy()
    assert fed_back.sum() == pytest.approx((p.edges + p.synthesis).sum())
    nets = stub_nets(edge=0.001)
    r = LearnedInpainter(nets=nets).inpaint([p])[0]
    np.testing.assert_array_equal(r.edges, p.edges)
    assert len(nets.edge.calls) == 1  # nothing new: no repeats
    nets = stub_nets()
    LearnedInpainter(nets=nets).inpaint([make_patch(edge_col=False)])
    assert nets.edge.calls == []  # no context edge touches the synthesis region


@pytest.mark.parametrize("share", [True, False])
def test_new_edges_are_reported_as_thin_paths_from_context_edges(share):
    # the stub edge net fires over the whole synthesis region: a blob touching the
    # context's edge column
    p = make_patch()
    nets = stub_nets(edge=0.003)
    r = LearnedInpainter(nets=nets, share=share).inpaint([p])[0]
    syn = p.synthesis & ~p.context
    new = (r.edges > 0) & syn
    assert new.any()
    # one pixel thick along the blob's long side (rows), connected to the context edge
    assert (new.sum(axis=1) <= 2).mean() > 0.9 and new.sum() < 0.1 * syn.sum()
    np.testing.assert_array_equal(r.edges[p.context], p.edges[p.context])
    # what the depth net saw is the edge net's own output (the authors' input)
    fed = nets.depth.calls[-1][0, 1].numpy()
    assert fed.sum() >= syn.sum()


def test_inputs_are_laid_out_like_the_authors():
    p = make_patch(40, 56)
    nets = stub_nets()
    LearnedInpainter(nets=nets).inpaint([p])
    x = nets.edge.calls[0][0].numpy()
    assert x.shape == (7, 128, 128)  # zero-padded to multiples of 128, centred
    y0, x0 = (128 - 40) // 2, (128 - 56) // 2
    crop = x[:, y0:y0 + 40, x0:x0 + 56]
    assert x.sum() == pytest.approx(crop.sum(), rel=1e-6)
    np.testing.assert_allclose(crop[:3], np.moveaxis(p.color, 2, 0))
    inv = 1 / DepthMapping().depth(p.disparity)
    np.testing.assert_allclose(crop[3][p.context], (inv / inv[p.context].max())[p.context],
                               rtol=1e-6)
    np.testing.assert_array_equal(crop[5:], np.stack([p.context, p.synthesis]))
    d = nets.depth.calls[0][0, :, y0:y0 + 40, x0:x0 + 56].numpy()
    logz = np.log(DepthMapping().depth(p.disparity))
    np.testing.assert_allclose(d[0][p.context], (logz - logz[p.context].mean())[p.context],
                               atol=1e-5)
    assert not d[0][~p.context].any()
    np.testing.assert_array_equal(d[3], close_gaps(p.context, p.synthesis))
    c = nets.color.calls[0][0, :, y0:y0 + 40, x0:x0 + 56].numpy()
    assert c.shape[0] == 6 and not c[:3][:, p.synthesis].any()


def test_close_gaps_fills_narrow_gaps_only():
    ctx = np.zeros((30, 90), bool)
    ctx[:, :20] = True
    syn = np.zeros((30, 90), bool)
    syn[5:25, 30:40] = True  # 10 px from the context: closed by a 41 px square
    syn[5:25, 85:88] = True  # 45 px from the synthesis block: stays open
    hole = close_gaps(ctx, syn)
    assert hole[syn].all() and not hole[ctx].any()
    assert hole[10:20, 20:30].all()  # the gap between context and synthesis
    assert not hole[10:20, 45:80].any()


def test_depth_round_trip_and_constant_colour():
    p = make_patch()
    flat = Patch(p.color, np.where(p.context, 0.4, 0).astype(np.float32), p.edges,
                 p.context, p.synthesis, p.origin)
    r = LearnedInpainter(nets=stub_nets(depth=0.0, color=0.25)).inpaint([flat])[0]
    # a zero (mean) log-depth prediction gives back the context's disparity
    np.testing.assert_allclose(r.disparity[p.synthesis], 0.4, rtol=1e-5)
    np.testing.assert_allclose(r.color[p.synthesis], 0.25)


def test_large_patch_is_shrunk_for_the_colour_net():
    p = make_patch(600, 640, split=300)
    nets = stub_nets(color=0.75)
    r = LearnedInpainter(nets=nets).inpaint([p])[0]
    assert r.color.shape == (600, 640, 3)
    np.testing.assert_allclose(r.color, 0.75, atol=1e-6)
    # sqrt(600 * 640) = 620 > 512: longer side to 512 (a multiple of 128), then padding
    assert tuple(nets.color.calls[0].shape[2:]) == (512, 512)
    assert not nets.color.calls[0][0, 3].any()  # the authors drop edges when shrinking
    assert tuple(nets.depth.calls[0].shape[2:]) == (640, 640)  # depth: full size


def test_batches_give_the_same_results_as_single_patches():
    nets = random_nets(3)
    patches = [make_patch(seed=s) for s in range(3)]
    together = LearnedInpainter(nets=nets, edge_threshold=0.5).inpaint(patches)
    alone = [LearnedInpainter(nets=nets, edge_threshold=0.5, batch_size=1).inpaint([p])[0]
             for p in patches]
    for a, b in zip(together, alone, strict=True):
        np.testing.assert_allclose(a.color, b.color, atol=1e-5)
        np.testing.assert_allclose(a.disparity, b.disparity, atol=1e-5)


def test_make_with_the_learned_backend():
    img, disp = two_planes()
    photo = photo3d.make(img, depth=disp, config=exact_config(),
                         inpainter=LearnedInpainter(nets=random_nets()))
    assert photo.stats["pixels_added"][0] > 0
    assert np.isfinite(photo.ldi.color).all() and np.isfinite(photo.ldi.disparity).all()


def test_edge_net_runs_in_the_first_pass_only():
    nets = stub_nets(edge=0.9)
    inp = LearnedInpainter(nets=nets, paths=False)
    first = inp.inpaint([make_patch()], pass_index=0)[0]
    runs = len(nets.edge.calls)
    assert runs == 2  # one run + a repeat (that changes nothing: the second is skipped)
    later = inp.inpaint([make_patch()], pass_index=1)[0]
    assert len(nets.edge.calls) == runs  # no edge net in pass 1
    assert len(nets.depth.calls) == 2 and len(nets.color.calls) == 2
    syn = make_patch().synthesis
    assert first.edges[syn].all() and not later.edges[syn].any()
    LearnedInpainter(nets=nets, edge_passes=2).inpaint([make_patch()], pass_index=1)
    assert len(nets.edge.calls) == runs + 2


def test_edge_unit_sets_the_edge_padding_only():
    nets = stub_nets()  # no architecture known: the authors' 128
    LearnedInpainter(nets=nets, edge_unit=8).inpaint([make_patch(h=40, w=56)])
    assert tuple(nets.edge.calls[0].shape[2:]) == (40, 56)
    assert tuple(nets.depth.calls[0].shape[2:]) == (128, 128)
    with pytest.raises(ConfigError, match="multiple of 4"):
        LearnedInpainter(nets=nets, edge_unit=6)


class Recorded(torch.nn.Module):
    """Wraps a net, keeping its ``config`` and ``input_multiple``; records input shapes."""

    def __init__(self, net) -> None:
        super().__init__()
        self.net, self.config, self.shapes = net, net.config, []
        self.input_multiple = net.input_multiple

    def forward(self, x):
        self.shapes.append(tuple(x.shape[2:]))
        return self.net(x)


def test_padding_unit_follows_the_architecture():
    torch.manual_seed(0)
    compact = {k: Recorded(build_net(k, **cfg).eval()) for k, cfg in SMALL.items()}
    nets = InpaintingNets(**compact, device=torch.device("cpu"), sources={})
    inp = LearnedInpainter(nets=nets, edge_threshold=0.5)
    assert inp.units == {"edge": 4, "depth": 8, "color": 8}  # 2**levels, levels=3
    inp.inpaint([make_patch(h=42, w=50)])
    assert compact["edge"].shapes[0] == (44, 52)
    # columns 42..49 hold neither context nor synthesis: dropped (trim), 42 -> 48
    assert compact["depth"].shapes == compact["color"].shapes == [(48, 48)]
    authors = build_net("edge")  # not run: only its config is read
    big = InpaintingNets(authors, compact["depth"], compact["color"], torch.device("cpu"), {})
    assert LearnedInpainter(nets=big).units["edge"] == 128
    assert LearnedInpainter(nets=big, edge_unit=8).units["edge"] == 8


def bf16_rounded(nets: InpaintingNets) -> InpaintingNets:
    """Copies of ``nets`` that round their weights and every module's inputs and
    outputs to bfloat16 but compute in float32: the rounding that bf16 autocast
    cannot avoid, without its arithmetic (which differs between CPUs)."""

    def r16(x):
        if isinstance(x, tuple):
            return tuple(r16(a) for a in x)
        return x.bfloat16().float() if torch.is_tensor(x) and x.is_floating_point() else x

    def rounded(net: torch.nn.Module) -> torch.nn.Module:
        net = copy.deepcopy(net)
        with torch.no_grad():
            for t in [*net.parameters(), *net.buffers()]:
                if t.is_floating_point():
                    t.copy_(r16(t))
        for m in net.modules():
            m.register_forward_pre_hook(lambda _, args: r16(args))
            m.register_forward_hook(lambda _, args, out: r16(out))
        return net

    return dataclasses.replace(nets, edge=rounded(nets.edge), depth=rounded(nets.depth),
                               color=rounded(nets.color))


def test_bf16_stays_close_to_fp32():
    """bf16 moves the fills about as far from the fp32 ones as the same rounding
    done in fp32 arithmetic does (:func:`bf16_rounded`), a reference measured on the
    CPU at hand: a fixed bound (0.01) held on one CPU's bf16 arithmetic and not on
    another's (0.0101). Not less than half (so it ran in bf16, not fp32) and not more
    than twice (so it is not broken)."""
    nets = random_nets(5)
    p = make_patch(seed=2)

    def fill(n: InpaintingNets, **kw):
        return LearnedInpainter(nets=n, edge_threshold=0.5, **kw).inpaint([p])[0]

    a, b, r = fill(nets), fill(nets, precision="bf16"), fill(bf16_rounded(nets))
    for name in ("color", "disparity"):
        bf16 = np.abs(getattr(a, name) - getattr(b, name))[p.synthesis].mean()
        rounding = np.abs(getattr(a, name) - getattr(r, name))[p.synthesis].mean()
        # measured (AMD EPYC): bf16 / rounding 1.11 (colour), 1.10 (disparity); over
        # six seeds 0.90 to 1.18 (rounding only weights and the nets' inputs: 1.3 to 7)
        assert rounding > 0 and rounding / 2 < bf16 < 2 * rounding, (name, bf16, rounding)
    with pytest.raises(ConfigError, match="precision"):
        LearnedInpainter(nets=nets, precision="fp8")


@pytest.mark.parametrize("colour", [(0.2, 0.6, 0.2), (0.8, 0.75, 0.6), (0.15, 0.2, 0.7)])
def test_the_shipped_colour_net_fills_with_the_colour_of_the_context(colour):
    """The shipped compact colour net once painted every hole orange-brown (about
    (0.6, 0.46, 0.35) beside green, beige or blue). Beside a textured context of one
    colour, the fill must take about that colour."""
    rng = np.random.default_rng(0)
    h, w = 96, 128
    ctx = np.zeros((h, w), bool)
    ctx[:, :60] = True
    syn = np.zeros((h, w), bool)
    syn[:, 60:100] = True
    color = np.clip(np.asarray(colour, np.float32) + rng.normal(0, 0.04, (h, w, 3)), 0, 1)
    patch = Patch((color * ctx[..., None]).astype(np.float32),
                  np.full((h, w), 0.3, np.float32) * ctx, np.zeros((h, w), np.float32),
                  ctx, syn, (0, 0))
    inp = LearnedInpainter(weights=photo3d.inpaint.learned.bundled_weights(), device="cpu")
    fill = inp.inpaint([patch])[0].color[syn].mean(0)
    np.testing.assert_allclose(fill, colour, atol=0.08)


# --- The joint edge run on crops ---

@functools.lru_cache(maxsize=1)
def scene_patches() -> tuple[Patch, ...]:
    """The first pass's patches of a textured background with a nearer disc and a
    nearer box far from it (the pipeline's own regions)."""
    h, w = 192, 384
    disp = np.ones((h, w), np.float32)
    yy, xx = np.mgrid[0:h, 0:w]
    disp[(yy - 50) ** 2 + (xx - 60) ** 2 < 20**2] = 2.0
    disp[120:160, 290:340] = 2.5
    captured = []

    class Capture(LearnedInpainter):
        def inpaint(self, patches, *, progress=None, pass_index=0):
            if pass_index == 0:
                captured.extend(patches)
            return super().inpaint(patches, progress=progress, pass_index=pass_index)

    photo3d.make(texture(h, w, seed=3), depth=disp, inpainter=Capture(nets=stub_nets()),
                 config=exact_config(synthesis_iterations=12, context_iterations=24))
    return tuple(captured)


def without_norm(net: torch.nn.Module) -> torch.nn.Module:
    """``net`` with its instance norms removed: each output pixel then depends only on
    inputs within the receptive field (under 32 px for the SMALL edge net)."""
    for module in list(net.modules()):
        for name, child in list(module.named_children()):
            if isinstance(child, torch.nn.InstanceNorm2d):
                setattr(module, name, torch.nn.Identity())
    return net


def padded_area(windows, unit: int) -> int:
    return sum(-(-(y1 - y0) // unit) * unit * (-(-(x1 - x0) // unit) * unit)
               for y0, x0, y1, x1 in windows)


@pytest.mark.parametrize("unit", [4, 32])
def test_cropped_edge_runs_give_the_full_canvas_results(unit):
    """Crops with a halo wider than the net's reach, aligned with its strides, give the
    same edges (and so the same depth and colour) inside every synthesis region as one
    run over the whole joint canvas, from fewer pixels."""
    patches = scene_patches()
    assert len(patches) >= 2
    nets = dataclasses.replace(random_nets(1), edge=without_norm(random_nets(1).edge))
    full = LearnedInpainter(nets=nets, edge_threshold=0.5, edge_unit=unit, edge_halo=None)
    crop = LearnedInpainter(nets=nets, edge_threshold=0.5, edge_unit=unit, edge_halo=32)
    a, b = full.inpaint(patches), crop.inpaint(patches)
    found = 0
    for p, ra, rb in zip(patches, a, b, strict=True):
        syn = p.synthesis & ~p.context
        np.testing.assert_array_equal(ra.edges[syn], rb.edges[syn])
        np.testing.assert_allclose(ra.disparity[syn], rb.disparity[syn], atol=1e-6)
        np.testing.assert_allclose(ra.color[syn], rb.color[syn], atol=1e-6)
        found += int((rb.edges[syn] > 0).sum())
    assert 0 < found < sum(int((p.synthesis & ~p.context).sum()) for p in patches)
    assert len(crop.edge_runs[0]) > 1 and len(full.edge_runs[0]) == 1
    assert padded_area(crop.edge_runs[0], unit) < padded_area(full.edge_runs[0], unit)


def test_cropped_edge_runs_stay_close_under_instance_norm():
    """With instance norm every output depends on the whole input, so crops cannot be
    exact: inside the synthesis regions their edge probabilities (random nets) must
    move less than merely padding the whole canvas to multiples of 8 instead of 4
    moves them."""
    from photo3d.inpaint.canvas import joint_patch
    from photo3d.inpaint.crops import cover
    from photo3d.inpaint.netinputs import NetInputs
    from photo3d.inpaint.netrun import run_batched

    joint = joint_patch([p for p in scene_patches() if NetInputs.touches(p)])
    it = NetInputs(joint, DepthMapping())
    x, syn = it.edge_input(it.edges), it.syn > 0
    cpu = torch.device("cpu")
    for seed in (1, 2):
        net = random_nets(seed).edge
        ref, padded = (run_batched(net, [x], device=cpu, unit=u)[0][0] for u in (4, 8))
        crops = cover(syn, halo=64, unit=4, max_pixels=10**6, phase=4)
        assert padded_area([c.window for c in crops], 4) < padded_area([(0, 0, *syn.shape)], 4)
        got = np.full(syn.shape, np.nan, np.float32)
        for c, o in zip(crops, run_batched(net, [c.take(x) for c in crops], device=cpu,
                                           unit=4), strict=True):
            got[c.slices()] = o[0][c.local()]
        moved, by_padding = np.abs(got - ref)[syn], np.abs(padded - ref)[syn]
        # measured (seeds 1, 2): mean 0.036 / 0.046, max 0.15 / 0.18; padding: mean
        # 0.084 / 0.081, max 0.40 / 0.35
        assert moved.mean() < by_padding.mean() and moved.max() < by_padding.max()


@pytest.mark.parametrize(("halo", "unit", "max_pixels"),
                         [(0, 4, 10**6), (16, 8, 40_000), (64, 128, 600_000), (None, 128, 10**5)])
def test_crop_cores_hold_every_target_pixel_once_with_its_halo(halo, unit, max_pixels):
    from photo3d.inpaint.crops import cover

    rng = np.random.default_rng(4)
    h, w = 300, 500
    target = np.zeros((h, w), bool)
    for _ in range(12):  # scattered strips and blobs
        y, x = rng.integers(0, h - 20), rng.integers(0, w - 20)
        target[y:y + rng.integers(3, 60), x:x + rng.integers(3, 120)] = True
    crops = cover(target, halo=halo, unit=unit, max_pixels=max_pixels, phase=4)
    count = np.zeros((h, w), int)
    for c in crops:
        y0, x0, y1, x1 = c.window
        cy0, cx0, cy1, cx1 = c.core
        assert y0 <= cy0 < cy1 <= y1 and x0 <= cx0 < cx1 <= x1
        count[c.slices()] += 1
        assert c.take(target[None]).shape[1:] == (y1 - y0, x1 - x0)
        # a crop of the input of one run over the whole canvas (padded, centred)
        for lo, hi, clo, chi, size in ((y0, y1, cy0, cy1, h), (x0, x1, cx0, cx1, w)):
            full = -(-size // unit) * unit
            off = (full - size) // 2
            assert (hi - lo) % unit == 0 and -off <= lo and hi <= full - off
            if halo is None:
                continue
            assert (lo + off) % 4 == 0  # the net's strides in the whole run's phase
            assert lo == -off or clo - lo >= halo  # the halo, or the input's border
            assert hi == full - off or hi - chi >= halo
        assert (y1 - y0) * (x1 - x0) <= max_pixels
    assert (count[target] == 1).all() and (count <= 1).all()
    if halo is not None and halo < 64:
        assert sum((c.window[2] - c.window[0]) * (c.window[3] - c.window[1])
                   for c in crops) < h * w  # it did crop


class Grow(torch.nn.Module):
    """Stub edge net: its input edges grown by one pixel (a 3 x 3 maximum)."""

    def __init__(self) -> None:
        super().__init__()
        self.calls = []

    def forward(self, x):
        self.calls.append(x.clone())
        return torch.nn.functional.max_pool2d(x[:, 4:5], 3, stride=1, padding=1)


@pytest.mark.parametrize("share", [True, False])
def test_edge_repeats_run_where_edges_changed_and_stop_when_none_did(share):
    """A grows its new edges by a column per run (wide synthesis); B's one-column
    synthesis is full after the first run, so the second repeat skips B."""
    a = make_patch(40, 56, split=24)  # synthesis columns 24..47, context edge at 23
    b = make_patch(40, 33, split=24, seed=1)
    b = Patch(b.color, b.disparity, b.edges, b.context, b.synthesis, (0, 200))
    assert b.synthesis[0].sum() == 1
    nets = InpaintingNets(Grow(), Const(1, 0.0), Const(3, 0.5), torch.device("cpu"), {})
    inp = LearnedInpainter(nets=nets, share=share, edge_unit=8, edge_halo=8, paths=False)
    ra, rb = inp.inpaint([a, b])
    new_a = ra.edges * a.synthesis
    np.testing.assert_array_equal(np.nonzero(new_a.any(0))[0], [24, 25, 26])  # 3 runs
    assert rb.edges[b.synthesis].all()
    if share:
        windows = inp.edge_runs
        assert len(windows) == 3
        reach = [max(x1 for _, _, _, x1 in run) for run in windows]
        assert reach[0] > 200 and reach[1] > 200  # B's crop: changed by the first run
        assert reach[2] < 100  # the second repeat only where A changed
    else:
        assert sum(c.shape[0] for c in nets.edge.calls) == 5  # A and B, A and B, A
    # B alone, however many repeats are allowed: the first repeat changes nothing
    nets.edge.calls.clear()
    LearnedInpainter(nets=nets, share=share, edge_unit=8, edge_halo=8,
                     edge_repeats=5).inpaint([b])
    assert sum(c.shape[0] for c in nets.edge.calls) == 2  # B alone: run + one repeat


@pytest.mark.parametrize("share", [True, False])
def test_depth_and_colour_canvases_lose_the_margin_that_only_adds_padding(share):
    """Rows 0..19 and 120..139 hold neither context nor synthesis: 140 rows would pad
    to 256, their 100 rows pad to 128. Every synthesis pixel is still filled."""
    rows = (np.arange(140) >= 20) & (np.arange(140) < 120)
    base = make_patch(140, 56)
    ctx, syn = base.context & rows[:, None], base.synthesis & rows[:, None]
    p = Patch(base.color * ctx[..., None], np.where(ctx, 0.4, 0).astype(np.float32),
              base.edges * ctx, ctx, syn, (3, 7))
    nets = stub_nets(depth=0.0, color=0.25)
    r = LearnedInpainter(nets=nets, share=share, paths=False).inpaint([p])[0]
    assert tuple(nets.edge.calls[0].shape[2:]) == (256, 128)  # the edge net: as before
    assert tuple(nets.depth.calls[0].shape[2:]) == tuple(nets.color.calls[0].shape[2:]) \
        == (128, 128)
    assert r.color.shape == (140, 56, 3) and r.disparity.shape == (140, 56)
    np.testing.assert_allclose(r.color[syn], 0.25)
    np.testing.assert_allclose(r.disparity[syn], 0.4, rtol=1e-5)
    assert r.edges[syn].all()  # the stub edge net's 0.5 everywhere


def test_trim_keeps_every_mask_pixel_and_never_pads_more():
    from photo3d.inpaint.canvas import trim
    from photo3d.inpaint.netrun import padded_shape

    rng = np.random.default_rng(2)
    for _ in range(30):
        h, w = (int(v) for v in rng.integers(20, 400, 2))
        ctx = np.zeros((h, w), bool)
        syn = np.zeros((h, w), bool)
        y, x = int(rng.integers(0, h - 5)), int(rng.integers(0, w - 5))
        ctx[y:y + int(rng.integers(1, h)), x:x + int(rng.integers(1, w))] = True
        syn[y:, x + 3:] = True
        syn &= ~ctx
        p = Patch(np.zeros((h, w, 3), np.float32), np.zeros((h, w), np.float32),
                  np.zeros((h, w), np.float32), ctx, syn, (int(y), 5))
        for unit in (8, 128):
            t = trim(p, unit)
            assert all(a <= b for a, b in zip(padded_shape(*t.shape, unit),
                                              padded_shape(h, w, unit), strict=True))
            dy, dx = t.origin[0] - p.origin[0], t.origin[1] - p.origin[1]
            assert dy >= 0 and dx >= 0 and dy + t.shape[0] <= h and dx + t.shape[1] <= w
            assert t.context.sum() == ctx.sum() and t.synthesis.sum() == syn.sum()


@pytest.mark.parametrize("seed", [0, 1])
def test_random_nets_do_not_make_later_passes_explode(seed, monkeypatch):
    """Random (the poorest) nets leave steps all over their fills. With the
    merge's fill rules every pass finds fewer new edges than the one before; without
    them the second pass found about three times the first's, and, since new edges
    are only where the next pass can fill (issue 35), still more than with them."""
    pytest.importorskip("skimage")
    import photo3d.stages.merge
    from photo3d.sample import motorcycle

    s = motorcycle()
    cfg = photo3d.Config(size=256, inpainter="learned")

    def edges(rules: bool) -> list[int]:
        monkeypatch.setitem(photo3d.stages.merge.merge_fills.__kwdefaults__, "link_fills",
                            rules)
        monkeypatch.setitem(photo3d.stages.merge.take.__kwdefaults__, "clamp", rules)
        backend = LearnedInpainter(nets=random_nets(seed), paths=rules)
        return photo3d.make(s.left, depth=np.asarray(s.disparity), config=cfg,
                            inpainter=backend).stats["edges"]

    now, before = edges(True), edges(False)
    assert all(b < a for a, b in zip(now, now[1:], strict=False)), now
    assert before[1] > now[1]  # what the rules prevent (the test can fail)


def refine_nets(seed: int | None = None) -> InpaintingNets:
    """Random compact edge and depth nets and a tiny refine colour net (fresh: zero
    residual; with ``seed``: every parameter random)."""
    nets = random_nets(0)
    color = build_net("color", arch="refine", channels=4, levels=2, blocks=1).eval()
    if seed is not None:
        g = torch.Generator().manual_seed(seed)
        with torch.no_grad():
            for p in color.parameters():
                p.copy_(torch.randn(p.shape, generator=g) * 0.3)
    return dataclasses.replace(nets, color=color)


@pytest.mark.parametrize("size", [(40, 56), (600, 640)])  # the second is shrunk
def test_a_fresh_refine_net_gives_the_diffusion_fill(size):
    p = make_patch(*size, split=size[1] // 2, edge_col=False)
    diffusion = get_inpainter("diffusion").inpaint([p])[0]
    r = LearnedInpainter(nets=refine_nets()).inpaint([p])[0]
    np.testing.assert_allclose(r.color[p.synthesis], diffusion.color[p.synthesis], atol=1e-6)


@pytest.mark.parametrize("size", [(40, 56), (600, 640)])
def test_a_refine_net_adds_its_residual_to_the_diffusion_fill(size):
    p = make_patch(*size, split=size[1] // 2, edge_col=False)  # no edges: see fill_colors
    diffusion = get_inpainter("diffusion").inpaint([p])[0]
    inp = LearnedInpainter(nets=refine_nets(seed=1))
    r = inp.inpaint([p])[0]
    assert r.color.shape == (*size, 3) and np.isfinite(r.color).all()
    assert 0 <= r.color.min() and r.color.max() <= 1
    change = np.abs(r.color - diffusion.color)[p.synthesis].mean()
    assert change > 1e-3
    # the colour path alone (fill_colors, the held-out score's) gives the same colours
    alone = inp.fill_colors([p])[0]
    np.testing.assert_allclose(alone[p.synthesis], r.color[p.synthesis], atol=1e-6)


def test_make_with_a_refine_weights_folder(files):
    weights = files / "weights"
    weights.mkdir()
    nets = refine_nets(seed=2)
    for kind in ("edge", "depth", "color"):
        save_safetensors(getattr(nets, kind), weights / f"{kind}.safetensors",
                         dtype=torch.float16 if kind == "color" else None)
    out = files / "out"
    assert make_learned(files, "--weights", str(weights), "-q") == 0
    import json

    meta = json.loads((out / "config.json").read_text())
    assert meta["stats"]["pixels_added"][0] > 0


def test_huge_weights_are_refused_before_anything_is_saved(files, capsys):
    """Finite weights of 1e30 make the nets give NaN or infinity: every hole would be
    NaN, in a photo3d.npz photo3d's own reader refuses."""
    weights = files / "weights"
    weights.mkdir()
    for kind, net in random_nets().__dict__.items():
        if kind in SMALL:
            with torch.no_grad():
                for p in net.parameters():
                    p.fill_(1e30)
            save_safetensors(net, weights / f"{kind}.safetensors")
    out = files / "out"
    assert make_learned(files, "--weights", str(weights), "-q") != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "net gave NaN or infinite values with weights " + str(weights) in err
    assert err.endswith("the weights are not usable") and not out.exists()
