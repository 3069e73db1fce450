"""Soft silhouettes (issue 44, item 3): coverage and colours of the fringe, the layer
behind it, the switch, the file format and how the fringe is drawn."""

from __future__ import annotations

import json
import warnings
import zipfile
from dataclasses import replace

import numpy as np
import pytest

import photo3d
from photo3d.camera import Camera, Intrinsics
from photo3d.config import Config
from photo3d.io.npz import FORMAT_VERSION, load_npz, save_npz
from photo3d.stages.silhouettes import soft_silhouettes

RED = np.array([0.9, 0.1, 0.1], np.float32)


def _edge_scene(offset: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A red foreground right of ``x = 20 + offset`` over a green-grey wall with a
    vertical texture, 4x4 supersampled: image, exact coverage, disparity, cuts."""
    h, w = 24, 40
    xs = (np.arange(w * 4) + 0.5) / 4
    cover = (xs >= 20 + offset).reshape(w, 4).mean(axis=1)
    wall = np.stack([0.3 + 0.1 * np.sin(np.arange(w)), 0.6 + 0.0 * np.arange(w),
                     0.4 + 0.05 * np.cos(np.arange(w))], axis=1).astype(np.float32)
    row = cover[:, None] * RED + (1 - cover[:, None]) * wall
    image = np.repeat(row[None], h, axis=0).astype(np.float32)
    disp = np.repeat((np.arange(w) + 0.5 >= 20 + offset)[None], h, 0).astype(np.float32)
    disp = 0.2 + 0.6 * disp
    cuts = np.zeros((h, w), np.uint8)
    step = np.flatnonzero(np.diff(disp[0]) != 0)[0]  # link step -> step + 1 is cut
    cuts[:, step] = 2
    return image, np.repeat(cover[None], h, 0), disp, cuts


@pytest.mark.parametrize("offset", [0.25, 0.5, 0.75])
@pytest.mark.parametrize("method", ["pairs", "means"])
def test_alpha_of_a_mixed_column_is_its_coverage(offset, method):
    image, cover, disp, cuts = _edge_scene(offset)
    # the near side grown by one pixel (as preprocess does): the mixed column is near
    disp = np.maximum(disp, np.roll(disp, -1, axis=1))
    cuts = np.roll(cuts, -1, axis=1)
    sil = soft_silhouettes(image, disp, cuts, band=2, radius=3)
    mixed = (cover > 0) & (cover < 1)
    assert np.abs(sil.alpha[mixed] - cover[mixed]).max() < 0.1
    assert sil.alpha[cover == 1].min() == 1.0  # pure foreground stays opaque
    # the mixed pixels' colours become the foreground's (red), not the mixture
    big = mixed & (cover >= 0.5)
    assert not big.any() or np.abs(sil.color[big] - RED).max() < 0.1


def test_no_cut_no_fringe():
    image, _, disp, _ = _edge_scene(0.5)
    sil = soft_silhouettes(image, disp, np.zeros(disp.shape, np.uint8))
    assert sil.fringe == 0 and np.array_equal(sil.color, image)


def _pole(spread: int) -> tuple[np.ndarray, np.ndarray]:
    """A 4 px red pole (x in [30, 34)) at depth 2 over a textured wall at depth 6,
    its depth spread ``spread`` px onto the wall (depth input)."""
    rng = np.random.default_rng(0)
    h, w = 48, 64
    image = np.empty((h, w, 3), np.float32)
    image[:] = (0.35 + 0.1 * rng.random((h, w, 1))) * np.array([0.6, 1.0, 0.8], np.float32)
    image[:, 30:34] = RED
    depth = np.full((h, w), 6.0, np.float32)
    depth[:, 30 - spread:34 + spread] = 2.0
    return image, depth


def _reddish(colors: np.ndarray) -> np.ndarray:
    return (colors[:, 0] > 0.6) & (colors[:, 1] < 0.3)


def test_spread_depth_leaves_no_pole_colour_behind_or_around_the_pole():
    image, depth = _pole(spread=2)
    config = Config(size=None, depth_kind="depth", spatial_scale=1.0, edges="soft")
    aligned = photo3d.make(image, depth=depth, config=config).ldi
    near = (aligned.depth() < 4.0) & (aligned.label == 1)
    assert not (near & ((aligned.x < 29) | (aligned.x > 34))).any()  # the step moved back
    # without the alignment, the matting alone: the spread pixels become transparent
    config = config.with_(preprocess=replace(config.preprocess, align_iterations=0))
    ldi = photo3d.make(image, depth=depth, config=config).ldi
    far = ldi.depth() > 4.0
    assert _reddish(ldi.color[far]).sum() == 0  # the wall's layer never takes the pole
    # the wall's pixels the spread depth put on the pole's layer are made transparent
    near = ~far & (ldi.label == 1)
    wall_coloured = near & ((ldi.x < 29) | (ldi.x > 34))
    assert wall_coloured.sum() > 0
    assert ldi.alpha[wall_coloured].max() < 0.1
    assert ldi.alpha[near & (ldi.x >= 30) & (ldi.x < 34)].min() > 0.9


@pytest.mark.parametrize("edges", ["exact", "align"])
def test_other_edges_keep_the_hard_cut(edges):
    image, depth = _pole(spread=2)
    config = Config(size=None, depth_kind="depth", spatial_scale=1.0, edges=edges)
    ldi = photo3d.make(image, depth=depth, config=config).ldi
    assert not ldi.soft and np.array_equal(ldi.color[:image.shape[0] * image.shape[1]],
                                           image.reshape(-1, 3))
    soft = photo3d.make(image, depth=depth, config=config.with_(edges="soft")).ldi
    assert soft.soft


def test_config_edges_round_trip_and_old_configs():
    cfg = Config(edges="exact")
    assert Config.from_dict(json.loads(cfg.to_json())) == cfg
    old = Config().to_dict()
    del old["edges"], old["silhouettes"]
    assert Config.from_dict(old).edges == Config().edges == "soft"
    assert Config.from_dict(Config(edges="soft").to_dict()).edges == "soft"
    with pytest.raises(ValueError, match="edges must be"):
        Config(edges="alpha")


def _small_soft_ldi():
    image, depth = _pole(spread=1)
    config = Config(size=None, depth_kind="depth", spatial_scale=1.0, edges="soft")
    return photo3d.make(image, depth=depth, config=config).ldi


def test_npz_stores_alpha_and_reads_version_2(tmp_path):
    ldi = _small_soft_ldi()
    assert ldi.soft
    save_npz(ldi, tmp_path / "a.npz")
    back, _ = load_npz(tmp_path / "a.npz")
    assert np.array_equal(back.alpha, ldi.alpha) and FORMAT_VERSION == 3
    # a version 2 file: the same arrays without alpha
    with np.load(tmp_path / "a.npz") as f:
        arrays = {k: f[k] for k in f.files if k != "alpha"}
    header = json.loads(arrays["header"].tobytes().decode())
    header["version"] = 2
    arrays["header"] = np.frombuffer(json.dumps(header).encode(), np.uint8)
    np.savez(tmp_path / "b.npz", **arrays)
    assert "alpha.npy" not in zipfile.ZipFile(tmp_path / "b.npz").namelist()
    old, _ = load_npz(tmp_path / "b.npz")
    assert old.alpha.dtype == np.float32 and (old.alpha == 1).all()
    assert np.array_equal(old.color, ldi.color)


def test_npz_without_soft_silhouettes_is_version_2(tmp_path):
    """A 3D photo cut hard is saved as version 2, which photo3d before format 3 reads."""
    image, depth = _pole(spread=1)
    ldi = photo3d.make(image, depth=depth, config=Config(size=None, depth_kind="depth",
                                                          edges="align")).ldi
    assert not ldi.soft
    save_npz(ldi, tmp_path / "a.npz")
    with np.load(tmp_path / "a.npz") as f:
        header = json.loads(f["header"].tobytes().decode())
        assert header["version"] == 2 and "alpha" not in f.files
    back, _ = load_npz(tmp_path / "a.npz")
    assert (back.alpha == 1).all() and np.array_equal(back.color, ldi.color)


def test_npz_refuses_alpha_out_of_range(tmp_path):
    ldi = _small_soft_ldi()
    save_npz(ldi, tmp_path / "a.npz")
    with np.load(tmp_path / "a.npz") as f:
        arrays = {k: f[k] for k in f.files}
    arrays["alpha"] = np.full_like(arrays["alpha"], 2.0)
    np.savez(tmp_path / "a.npz", **arrays)
    with pytest.raises(photo3d.errors.InputError, match="alpha"):
        load_npz(tmp_path / "a.npz")


@pytest.mark.parametrize("backend", ["numba", "gl"])
def test_renderer_blends_the_fringe_over_what_is_behind(backend):
    from photo3d.mesh.full import build_mesh
    from photo3d.render.renderer import Renderer, RenderSettings
    from photo3d.stages.ldi import from_image

    if backend == "gl":
        pytest.importorskip("moderngl")
        from photo3d.render.gl import gl_available

        if not gl_available():
            pytest.skip("no OpenGL context")
    h = w = 16
    blue = np.zeros((h, w, 3), np.float32)
    blue[..., 2] = 1.0
    back = build_mesh(from_image(blue, np.full((h, w), 0.2, np.float32)))
    front = np.zeros((h, w, 3), np.float32)
    front[..., 0] = 1.0
    alpha = np.full(h * w, 0.5, np.float32)
    near = build_mesh(from_image(front, np.full((h, w), 0.8, np.float32)))
    n = len(back.vertices)
    both = photo3d.structures.mesh.Mesh(
        np.concatenate([back.vertices, near.vertices]),
        np.concatenate([back.colors, near.colors]), np.concatenate([back.labels, near.labels]),
        np.concatenate([back.faces, near.faces + n]), w, h, back.hfov, back.vfov,
        alpha=np.concatenate([np.ones(n, np.float32), alpha]))
    camera = Camera(Intrinsics.default(w, h), np.eye(4))
    settings = RenderSettings(backend=backend, ssaa=2)
    with Renderer(both, settings) as renderer:
        color = renderer.render(camera).color
    inner = color[4:12, 4:12].reshape(-1, 3)
    assert np.allclose(inner, [0.5, 0.0, 0.5], atol=0.02)
    opaque = photo3d.structures.mesh.Mesh(*[getattr(both, f) for f in (
        "vertices", "colors", "labels", "faces", "width", "height", "hfov", "vfov")])
    with Renderer(opaque, settings) as renderer:  # without alpha: the red layer hides
        assert np.allclose(renderer.render(camera).color[4:12, 4:12], [1, 0, 0], atol=0.02)


def test_splats_take_the_alpha_as_opacity():
    from photo3d.export.splats import OPACITY, build_splats

    ldi = _small_soft_ldi()
    for density in ("dense", "adaptive"):
        splats = build_splats(ldi, density=density)
        assert splats.opacity.min() < 0.5 * OPACITY
    assert np.allclose(build_splats(ldi, density="dense").opacity, OPACITY * ldi.alpha)


def test_glb_files_keep_the_fringe_and_its_alpha(tmp_path):
    from photo3d.io.gltf import read_glb, write_glb
    from photo3d.io.gltf_textured import read_textured_glb, write_textured_glb
    from photo3d.io.light_glb import read_light_glb

    image, depth = _pole(spread=2)
    config = Config(size=None, depth_kind="depth", spatial_scale=1.0, edges="soft")
    photo = photo3d.make(image, depth=depth, config=config)
    light = photo.light_mesh()
    write_textured_glb(tmp_path / "light.glb", light)
    back = read_textured_glb(tmp_path / "light.glb")
    assert back.overlay is not None
    assert np.allclose(back.overlay.alpha, light.overlay.alpha, atol=1e-6)
    assert np.array_equal(back.overlay.colors, light.overlay.colors)
    assert np.array_equal(back.overlay.faces, light.overlay.faces)
    again = read_light_glb(tmp_path / "light.glb", intrinsics=photo.ldi.intrinsics,
                           lattice=photo.ldi.lattice_shape)
    assert again.overlay is not None  # videos drawn from a saved folder keep it
    full = photo.mesh()
    write_glb(tmp_path / "full.glb", full)
    read = read_glb(tmp_path / "full.glb")
    opaque, fringe = full.split_fringe()
    assert len(read.faces) == len(full.faces)
    assert np.isclose(read.alpha.min(), full.alpha.min())
    assert np.array_equal(read.split_fringe()[1].alpha, fringe.alpha)


def test_usdz_holds_the_fringe_with_its_opacity(tmp_path):
    pxr = pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom, UsdUtils

    from photo3d.export.usdz import write_usdz

    del pxr
    image, depth = _pole(spread=2)
    config = Config(size=None, depth_kind="depth", spatial_scale=1.0, edges="soft")
    ldi = photo3d.make(image, depth=depth, config=config).ldi
    path = tmp_path / "mesh.usdz"
    write_usdz(ldi, path)
    stage = Usd.Stage.Open(str(path))
    fringe = UsdGeom.Mesh(stage.GetPrimAtPath("/photo3d/fringe"))
    opacity = np.asarray(UsdGeom.PrimvarsAPI(fringe).GetPrimvar("displayOpacity").Get())
    assert opacity.size and opacity.min() < 0.5 and opacity.max() <= 1.0
    checker_class = getattr(UsdUtils, "ComplianceChecker", None)
    if checker_class is None:
        return  # usd-core >= 26.8 has no ARKit checker
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # deprecated since 25.x
        checker = checker_class(arkit=True, skipARKitRootLayerCheck=False,
                                rootPackageOnly=False, skipVariants=False, verbose=False)
        checker.CheckCompliance(str(path))
    assert (list(checker.GetErrors()), list(checker.GetFailedChecks())) == ([], [])


def test_soft_silhouettes_give_the_photo_back_at_its_camera():
    """Drawn with supersampling, each pixel's footprint keeps its own alpha (the
    nearest corner's, tests/render/test_fringe.py): at the input camera the soft photo
    is no farther from the photo near the pole's edges than the hard-cut one (with
    alpha interpolated between pixel centres the pole's outermost pixels faded: twice
    the error)."""
    from photo3d.render.renderer import RenderSettings

    rng = np.random.default_rng(3)
    image, depth = _pole(spread=2)
    image[:, 31:33] = np.clip(RED + 0.1 * rng.random((image.shape[0], 2, 3)), 0, 1)
    config = Config(size=None, depth_kind="depth", spatial_scale=1.0)
    near = np.zeros(image.shape[:2], bool)
    near[:, 27:37] = True
    errors = {}
    for edges in ("align", "soft"):
        photo = photo3d.make(image, depth=depth, config=config.with_(edges=edges))
        assert photo.ldi.soft == (edges == "soft")
        view = photo.render(Camera(photo.ldi.intrinsics, np.eye(4)),
                            settings=RenderSettings(ssaa=2, backend="numba")).color
        errors[edges] = float(np.abs(view - image)[near].mean())
    assert errors["soft"] <= 1.05 * errors["align"], errors


def test_mostly_opaque_fringe_keeps_the_inpainted_colour_behind_it():
    """Behind a fringe pixel of alpha 0.8 the photo shows the background by 0.2 only:
    the layer behind moves from its inpainted colour toward the matting's estimate
    (one background sample of the window) by that share, not all the way (the sample
    taken whole was a speckle in novel views), and the fringe's colour is solved
    against it: composited, the photo comes back."""
    from photo3d.stages.ldi import from_image
    from photo3d.stages.silhouettes import Behind, paint_behind

    ldi = from_image(np.full((1, 2, 3), 0.5, np.float32), np.ones((1, 2), np.float32))
    inpainted = np.array([0.2, 0.6, 0.4], np.float32)
    two = replace(ldi, y=np.r_[ldi.y, 0].astype(np.int32), x=np.r_[ldi.x, 1].astype(np.int32),
                  color=np.r_[ldi.color, inpainted[None]].astype(np.float32),
                  disparity=np.r_[ldi.disparity, 0.0].astype(np.float32),
                  links=np.r_[ldi.links, [[-1] * 4]].astype(np.int32),
                  label=np.r_[ldi.label, 2].astype(np.uint8),
                  alpha=np.array([1.0, 0.8, 1.0], np.float32))
    sample = np.array([[0.9, 0.1, 0.9]], np.float32)
    photo = np.array([[0.6, 0.5, 0.5]], np.float32)
    out = paint_behind(two, Behind(np.array([1]), photo, sample, photo), threshold=0.04)
    assert np.allclose(out.color[2], 0.2 * sample[0] + 0.8 * inpainted, atol=1e-6)
    assert np.allclose(0.8 * out.color[1] + 0.2 * out.color[2], photo[0], atol=1e-6)

