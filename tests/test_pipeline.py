import json
import warnings

import numpy as np
import pytest
import trimesh
from conftest import exact_config, texture, two_planes
from PIL import Image

import photo3d
from photo3d.errors import InputError, OutputError
from photo3d.io.ply import read_ply


def test_make_save_load_round_trip(tmp_path):
    img, d = two_planes()
    photo = photo3d.make(img, depth=d, config=exact_config(border=4))
    out = photo.save(tmp_path / "out")
    assert sorted(p.name for p in out.iterdir()) == [
        "config.json", "mesh.glb", "mesh.ply", "photo3d.npz", "viewer.html"]
    back = photo3d.load(out)
    np.testing.assert_array_equal(back.ldi.links, photo.ldi.links)
    np.testing.assert_array_equal(back.ldi.color, photo.ldi.color)
    assert back.config == photo.config
    meta = json.loads((out / "config.json").read_text())
    assert meta["config"]["regions"]["border"] == 4
    # independent reader sees the same mesh
    ply = trimesh.load(out / "mesh.ply", process=False)
    mesh = photo.mesh()
    assert len(ply.vertices) == len(mesh.vertices) and len(ply.faces) == len(mesh.faces)
    assert read_ply(out / "mesh.ply").width == 96


def test_existing_output_is_refused_and_overwrite_replaces_it(tmp_path):
    img, d = two_planes(16, 16, 8)
    photo = photo3d.make(img, depth=d, config=exact_config())
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    with pytest.raises(OutputError, match="exists and is not empty"):
        photo.save(out)
    assert (out / "keep.txt").read_text() == "mine"
    with pytest.raises(OutputError, match="only replaces a folder photo3d wrote"):
        photo.save(out, overwrite=True)  # never an arbitrary folder
    assert sorted(p.name for p in out.iterdir()) == ["keep.txt"]
    (out / "keep.txt").unlink()
    photo.save(out)
    photo.save(out, overwrite=True, glb=False, ply="ascii", viewer=False)
    assert sorted(p.name for p in out.iterdir()) == ["config.json", "mesh.ply", "photo3d.npz"]
    assert (out / "mesh.ply").read_bytes().startswith(b"ply\nformat ascii 1.0\n")


def test_failed_save_leaves_no_folder(tmp_path, monkeypatch):
    img, d = two_planes(16, 16, 8)
    photo = photo3d.make(img, depth=d, config=exact_config())

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr("photo3d.output.write_textured_glb", boom)
    with pytest.raises(OutputError, match="cannot write .*out: disk full"):
        photo.save(tmp_path / "out")
    assert list(tmp_path.iterdir()) == []


def test_constant_depth_gives_a_flat_valid_photo():
    img = texture(32, 48)
    photo = photo3d.make(img, depth=np.full((32, 48), 5.0), config=exact_config(border=3))
    assert photo.stats["edges"] == [] and photo.stats["passes"] == 0
    m = photo.mesh()
    assert m.faces.shape[0] == 2 * (32 + 6 - 1) * (48 + 6 - 1)
    assert np.ptp(m.vertices[:, 2]) == 0


def test_a_map_below_the_flat_threshold_is_flat_everywhere():
    """A map holding only 1.0 and 1.0000001 (one float step): check_depth says it is
    flat, and make now agrees instead of stretching that step to the full range (at
    1024 px: 3.5M LDI pixels, 7.7 GB, 75 s); a map of 4 % range is flat too."""
    from photo3d.depth.checks import check_depth

    img = texture(48, 64)
    rng = np.random.default_rng(0)
    for low, high in ((1.0, 1.0000001), (1.0, 1.04)):
        d = np.where(rng.random((48, 64)) < 0.5, low, high).astype(np.float32)
        assert check_depth(d) == ["depth has almost no range: the 3D photo will look flat"]
        photo = photo3d.make(img, depth=d, config=exact_config(border=3))
        assert photo.stats["edges"] == [] and photo.ldi.size == 54 * 70
        assert np.ptp(photo.ldi.disparity) == 0


def test_working_size_resizes_the_longer_side_and_scales_parameters():
    img, d = two_planes(64, 96, 48)
    photo = photo3d.make(img, depth=d, config=photo3d.Config(size=192))
    assert photo.ldi.intrinsics.width == 192 and photo.ldi.intrinsics.height == 128
    assert photo.ldi.border == round(60 * 192 / 1024)


def test_inputs_from_files_with_unknown_depth(tmp_path):
    img, d = two_planes(32, 48, 24)
    Image.fromarray((img * 255).astype(np.uint8)).save(tmp_path / "a.jpg")
    d = d.copy()
    d[0, :5] = np.inf
    np.save(tmp_path / "d.npy", d)
    photo = photo3d.make(tmp_path / "a.jpg", depth=tmp_path / "d.npy", config=exact_config())
    assert photo.stats["unknown_depth_filled"] == 5


def test_depth_kind_depth_puts_small_values_in_front():
    img, d = two_planes(32, 48, 24)  # disparity 1 on the left, 2 on the right
    as_depth = photo3d.make(img, depth=d, config=exact_config().with_(depth_kind="depth"))
    as_disp = photo3d.make(img, depth=d, config=exact_config())
    z_depth, z_disp = as_depth.ldi.depth(), as_disp.ldi.depth()
    left, right = 5, 40
    assert z_depth[left] < z_depth[right]  # depth 1 is nearer than depth 2
    assert z_disp[left] > z_disp[right]  # disparity 1 is farther than disparity 2


def test_bad_inputs_raise_one_line_errors(tmp_path):
    img, d = two_planes(32, 48, 24)
    with pytest.raises(InputError, match="aspect ratios differ"):
        photo3d.make(img, depth=np.ones((10, 10)))
    with pytest.raises(InputError, match="no valid value"):
        photo3d.make(img, depth=np.full((32, 48), np.nan))
    with pytest.raises(InputError, match="not found"):
        photo3d.make(tmp_path / "missing.jpg", depth=d)
    with pytest.raises(InputError, match="needs at least 8x8"):
        photo3d.make(np.zeros((4, 3, 3)), depth=np.ones((4, 3)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(UserWarning, match="resampling"):
            photo3d.make(img, depth=np.ones((16, 24)))


def test_tiny_image_still_works():
    img = texture(8, 8)
    d = np.ones((8, 8), np.float32)
    d[:, 4:] = 2
    photo = photo3d.make(img, depth=d, config=photo3d.Config(size=None))
    assert photo.mesh().faces.shape[0] > 0


def test_metric_depth_and_intrinsics_are_kept():
    from photo3d.camera import Intrinsics

    img = texture(40, 60)
    z = np.full((40, 60), 5.0, np.float32)
    z[10:30, 20:40] = 2.0  # metres
    k = Intrinsics(70.0, 70.0, 28.0, 21.0, 60, 40)
    photo = photo3d.make(img, depth=z, intrinsics=k,
                         config=exact_config().with_(depth_kind="depth", metric=True))
    np.testing.assert_allclose(photo.ldi.depth()[: 40 * 60].reshape(40, 60), z, rtol=1e-5)
    assert photo.ldi.intrinsics == k
    # a pixel centre back-projects through the given camera
    v = photo.mesh().vertices[20 * 60 + 30]
    assert v[0] == pytest.approx((30.5 - 28.0) / 70.0 * 2.0, rel=1e-5)
    half = photo3d.make(img, depth=z, intrinsics=k, config=photo3d.Config(
        size=30, depth_kind="depth", metric=True))
    assert half.ldi.intrinsics.fx == pytest.approx(35.0)
    with pytest.raises(photo3d.ConfigError, match="metric"):
        photo3d.Config(metric=True)
    with pytest.raises(InputError, match="intrinsics are for"):
        photo3d.make(img, depth=z, intrinsics=Intrinsics.default(10, 10))
    for bad in (Intrinsics(0.0, 0.0, 0.0, 0.0, 60, 40),  # ZeroDivisionError before
                Intrinsics(np.nan, 70.0, 28.0, 21.0, 60, 40),  # NaN vertices before
                Intrinsics(-70.0, -70.0, 28.0, 21.0, 60, 40),  # a mirrored mesh before
                Intrinsics(70.0, 70.0, np.inf, 21.0, 60, 40)):
        with pytest.raises(InputError, match="intrinsics need finite fx, fy > 0"):
            photo3d.make(img, depth=z, intrinsics=bad, config=exact_config())


def test_a_config_of_the_wrong_type_or_value_is_one_config_error():
    """Before, size="512" and spatial_scale=NaN raised TypeError and ValueError deep in
    the pipeline, size=100.5 and spatial_scale=-1 were taken, a dict for config raised
    AttributeError."""
    for changes in ({"size": "512"}, {"size": 100.5}, {"spatial_scale": np.nan},
                    {"spatial_scale": -1.0}, {"spatial_scale": 0.0}, {"spatial_scale": "2"}):
        with pytest.raises(photo3d.ConfigError, match=f"{next(iter(changes))} must be"):
            photo3d.Config(**changes)
    assert photo3d.Config(size=np.int64(512)).size == 512  # a NumPy integer is whole
    img, d = two_planes(32, 48, 24)
    with pytest.raises(photo3d.ConfigError, match="config must be a photo3d.Config, got a dict"):
        photo3d.make(img, depth=d, config={"size": None})


def test_config_json_records_the_inpainter_the_depth_source_and_the_save_options(tmp_path):
    img, d = two_planes(32, 48, 24)
    np.save(tmp_path / "d.npy", d)
    photo = photo3d.make(img, depth=tmp_path / "d.npy", config=exact_config())
    out = photo.save(tmp_path / "out", ply="ascii", full_glb=True, viewer=False)
    meta = json.loads((out / "config.json").read_text())
    assert list(meta) == ["config", "inpainter", "depth_source", "save", "stats", "timings",
                          "written"]
    assert meta["inpainter"] == {"name": "diffusion", "iterations": 300, "tolerance": 1e-3}
    assert meta["depth_source"] == f"depth file {tmp_path / 'd.npy'} (disparity)"
    assert meta["save"] == {"ply": "ascii", "glb": "full", "light_error": 0.5,
                            "viewer": False, "videos": [], "render_settings": None,
                            "exports": []}
    from photo3d.io.npz import load_npz

    assert load_npz(out / "photo3d.npz")[1] == meta  # the LDI file carries the same
    back = photo3d.load(out)
    assert (back.inpainter, back.depth_source) == (photo.inpainter, photo.depth_source)


def test_folders_saved_before_the_new_records_still_load(tmp_path):
    from photo3d.io.npz import save_npz

    img, d = two_planes(16, 16, 8)
    photo = photo3d.make(img, depth=d, config=exact_config(border=2))
    old = tmp_path / "old"
    old.mkdir()
    meta = {"config": photo.config.to_dict(), "stats": photo.stats, "timings": photo.timings}
    save_npz(photo.ldi, old / "photo3d.npz", meta=meta)
    (old / "config.json").write_text(json.dumps(meta))
    back = photo3d.load(old)
    assert back.config == photo.config and back.stats == photo.stats
    assert back.inpainter == {} and back.depth_source is None
    back.save(tmp_path / "again", glb=False, viewer=False)  # and can be saved again
    assert json.loads((tmp_path / "again" / "config.json").read_text())["inpainter"] == {}


def test_make_reads_heic_photos_like_the_command_line(tmp_path):
    pillow_heif = pytest.importorskip("pillow_heif")
    from photo3d.depth.sources import read_photo

    img, d = two_planes(32, 48, 24)
    rgb = (img * 255).round().astype(np.uint8)
    pillow_heif.from_pillow(Image.fromarray(rgb)).save(tmp_path / "a.heic", quality=-1)
    photo = photo3d.make(tmp_path / "a.heic", depth=d, config=exact_config())
    from_array = photo3d.make(read_photo(tmp_path / "a.heic"), depth=d, config=exact_config())
    np.testing.assert_array_equal(photo.ldi.color, from_array.ldi.color)
    assert np.abs(photo.ldi.color[: 32 * 48].reshape(32, 48, 3) - img).mean() < 0.04  # lossy


def test_the_border_continues_the_photos_texture_without_streaks():
    """Replication copies the outermost row outward (every border row alike: streaks);
    the default border fill carries the photo's texture into the frame: its rows differ
    like the photo's do, with the photo's own colours (a binary texture stays binary,
    not diffused to grey). Depth, links and labels are the replicated ones either way."""
    rng = np.random.default_rng(0)
    img = np.repeat((rng.random((48, 64, 1)) > 0.5).astype(np.float32), 3, axis=2)
    depth = np.full((48, 64), 5.0)
    made = {fill: photo3d.make(img, depth=depth,
                               config=exact_config(border=8, border_context=16,
                                                   border_fill=fill))
            for fill in ("replicate", "structured", "texture")}
    rows = {}
    for fill, photo in made.items():
        ldi = photo.ldi
        top = ldi.y < 0
        grid = np.zeros((8, 64 + 16))
        grid[ldi.y[top] + 8, ldi.x[top] + 8] = ldi.color[top, 0]
        rows[fill] = np.abs(np.diff(grid[:, 8:-8], axis=0)).mean()
        if fill != "replicate":
            binary = np.minimum(ldi.color[top, 0], 1 - ldi.color[top, 0]) < 0.2
            assert binary.mean() > 0.8
    assert rows["replicate"] == 0.0
    for fill in ("structured", "texture"):
        assert rows[fill] > 0.3 * np.abs(np.diff(img[..., 0], axis=0)).mean(), fill
        a, b = made["replicate"].ldi, made[fill].ldi
        for name in ("y", "x", "disparity", "links", "label"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert np.array_equal(a.color[: 48 * 64], b.color[: 48 * 64])
