"""Splats of a 3D photo (photo3d.export.splats) and ``export`` into its folder."""

from __future__ import annotations

import fnmatch
import json

import numpy as np
import pytest
from conftest import exact_config, texture

import photo3d
from photo3d.cli import main
from photo3d.errors import ConfigError, InputError, OutputError
from photo3d.export import FORMATS, check_formats, export_folder
from photo3d.export.splats import (
    FOOTPRINT,
    OPACITY,
    build_splats,
    splat_count,
    splat_opacity,
)
from photo3d.io.splat_glb import read_splat_glb
from photo3d.io.splat_ply import read_splat_ply
from photo3d.io.spz import read_spz
from photo3d.owned import EXPORT_FILES, owned_photo, recorded_files

SPLATS = ["splats.ply", "splats.spz", "splats.glb"]


@pytest.fixture(scope="module")
def photo():
    """A textured background with a box in front: inpainted layers behind the box
    and a 6 px border."""
    disp = np.ones((40, 56), np.float32)
    disp[10:30, 16:40] = 2.5
    return photo3d.make(texture(40, 56, seed=5), depth=disp, config=exact_config(border=6))


@pytest.fixture
def folder(photo, tmp_path):
    return photo.save(tmp_path / "out", viewer=False, glb=False)


def test_one_splat_per_ldi_pixel_at_its_vertex_with_its_footprint(photo):
    ldi = photo.ldi
    splats = build_splats(ldi, density="dense")
    assert len(splats) == ldi.size and set(np.unique(ldi.label)) >= {1, 2, 5}
    np.testing.assert_array_equal(splats.positions, photo.mesh().vertices)
    np.testing.assert_array_equal(splats.colors, ldi.color)
    z = ldi.depth()
    np.testing.assert_allclose(splats.scales[:, 0], FOOTPRINT * z / ldi.intrinsics.fx, rtol=1e-6)
    np.testing.assert_allclose(splats.scales[:, 1], FOOTPRINT * z / ldi.intrinsics.fy, rtol=1e-6)
    assert (splats.scales[:, 2] < splats.scales[:, 0] / 5).all()  # discs facing the camera
    np.testing.assert_array_equal(splats.rotations, np.tile([1, 0, 0, 0], (ldi.size, 1)))
    assert ((splats.opacity > 0.9) & (splats.opacity < 1)).all()


def test_adaptive_joins_flat_planar_blocks_only():
    image = np.full((48, 64, 3), 0.4, np.float32)
    image[:, 32:] = texture(48, 32, seed=1)  # right half textured
    photo = photo3d.make(image, depth=np.ones((48, 64)), config=exact_config())
    ldi = photo.ldi
    full, merged = build_splats(ldi, density="dense"), build_splats(ldi)
    assert len(merged) < 0.6 * len(full)
    left = merged.positions[:, 0] < 0
    assert left.sum() == (32 // 16) * (48 // 16)  # the flat half: blocks of 16 x 16 pixels
    assert (~left).sum() > 0.8 * (full.positions[:, 0] > 0).sum()  # texture kept
    assert merged.scales[left, :2].max() == pytest.approx(16 * full.scales[0, 0], rel=1e-4)
    # a joined splat sits at the centre of its block, with its mean colour
    big = np.argmax(merged.scales[:, 0])
    assert merged.colors[big] == pytest.approx([0.4, 0.4, 0.4], abs=1e-6)
    # the photo stays covered: every pixel of the flat half lies within 1.5 sigma
    # (in pixels) of a joined splat's centre
    k = ldi.intrinsics
    u = merged.positions[left, 0] / merged.positions[left, 2] * k.fx + k.cx
    v = merged.positions[left, 1] / merged.positions[left, 2] * k.fy + k.cy
    sigma = merged.scales[left, :2].min(axis=1) / merged.positions[left, 2] * k.fx
    yy, xx = np.mgrid[0:48, 0:30] + 0.5
    d = np.hypot(xx.ravel()[:, None] - u, yy.ravel()[:, None] - v) / sigma
    assert d.min(axis=1).max() < 1.5


def test_adaptive_splats_follow_a_slanted_plane():
    """A floor seen at an angle (inverse depth linear in the row): the joined
    splats lie on the plane, long along its slope, and project onto their block."""
    h, w = 64, 64
    rows = np.linspace(0.3, 1.0, h, dtype=np.float32)[:, None] * np.ones((1, w), np.float32)
    photo = photo3d.make(np.full((h, w, 3), 0.5, np.float32), depth=rows,
                         config=exact_config())
    splats = build_splats(photo.ldi)
    big = splats.scales[:, :2].max(axis=1) > 3 * splats.scales[:, :2].min(axis=1).min()
    assert big.sum() > 4
    # the Gaussian's thin axis is the floor's normal: the plane through the splats
    q = splats.rotations[big]
    w_, x, y, z = q.T
    normal = np.stack([2 * (x * z + w_ * y), 2 * (y * z - w_ * x), 1 - 2 * (x * x + y * y)], 1)
    points = splats.positions[big]
    centred = points - points.mean(axis=0)
    plane = np.linalg.svd(centred)[2][2]  # the least-squares plane's normal
    assert np.abs(normal @ plane).min() > 0.95
    assert abs(plane[2]) < 0.99  # and it is slanted, not facing the camera
    # anisotropic: the long axis is along the slope (the rows), longer than across it
    assert (splats.scales[big, :2].max(axis=1) > 1.2 * splats.scales[big, :2].min(axis=1)).all()


def test_opacity_comes_from_one_function_that_takes_a_coverage(photo):
    ldi = photo.ldi
    alpha = np.ones(ldi.size, np.float32)
    alpha[::2] = 0.5
    splats = build_splats(ldi, density="dense", alpha=alpha)
    np.testing.assert_allclose(splats.opacity, splat_opacity(ldi.size, alpha))
    assert splats.opacity.min() == pytest.approx(OPACITY / 2)
    with pytest.raises(ConfigError, match="alpha has shape"):
        build_splats(ldi, alpha=alpha[:3])
    with pytest.raises(ConfigError, match="density must be one of adaptive, dense"):
        build_splats(ldi, density="sparse")


def test_export_writes_into_the_folder_and_records_the_files(folder, photo):
    written = export_folder(folder, SPLATS, density="dense")
    assert [p.name for p in written] == SPLATS
    assert recorded_files(folder) >= set(SPLATS)
    assert owned_photo(folder) == []  # make --overwrite may replace the folder
    ply, spz, glb = (read_splat_ply(written[0]), read_spz(written[1]),
                     read_splat_glb(written[2]))
    assert len(ply) == len(spz) == len(glb) == photo.ldi.size
    np.testing.assert_allclose(spz.positions, ply.positions, atol=1e-3)
    np.testing.assert_allclose(glb.positions, ply.positions, atol=1e-6)
    assert [splat_count(p) for p in written] == [photo.ldi.size] * 3
    # again: photo3d's own files are replaced
    before = written[0].stat().st_mtime_ns
    export_folder(folder, ["splats.ply"])  # adaptive, the default
    assert splat_count(written[0]) < photo.ldi.size and written[0].stat().st_mtime_ns >= before


def test_export_never_replaces_a_file_photo3d_did_not_write(folder):
    (folder / "splats.spz").write_bytes(b"mine")
    with pytest.raises(OutputError, match="splats.spz exists and photo3d did not write it"):
        export_folder(folder, ["splats.ply", "splats.spz"])
    assert (folder / "splats.spz").read_bytes() == b"mine"
    assert not (folder / "splats.ply").exists()  # refused before writing anything
    assert "splats.spz" in owned_photo(folder)[0]  # nor does make --overwrite
    (folder / "splats.spz").unlink()
    (folder / "splats.ply").symlink_to(folder / "elsewhere.ply")
    with pytest.raises(OutputError, match="symbolic link"):
        export_folder(folder, ["splats.ply"])
    assert not (folder / "elsewhere.ply").exists()


def test_export_refusals_are_one_line(folder, tmp_path):
    with pytest.raises(ConfigError, match="unknown export format 'splats.obj'; choose from"):
        export_folder(folder, ["splats.obj"])
    with pytest.raises(ConfigError, match="no export format"):
        export_folder(folder, [])
    with pytest.raises(InputError, match="no 3D photo folder at"):
        export_folder(tmp_path / "missing", ["splats.ply"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no photo3d.npz"):
        export_folder(tmp_path / "empty", ["splats.ply"])
    with pytest.raises(ConfigError, match="one format"):
        export_folder(folder, ["splats.ply", "splats.spz"], output=tmp_path / "a.ply")


def test_output_writes_one_format_elsewhere(folder, tmp_path):
    target = tmp_path / "elsewhere.spz"
    assert export_folder(folder, ["splats.spz"], output=target) == [target]
    assert splat_count(target) > 0 and not (folder / "splats.spz").exists()
    assert "elsewhere.spz" not in recorded_files(folder)
    with pytest.raises(OutputError, match="exists; pass overwrite"):
        export_folder(folder, ["splats.spz"], output=target)
    export_folder(folder, ["splats.spz"], output=target, overwrite=True, spz_version=4)
    assert target.read_bytes()[:4] == b"NGSP"
    assert splat_count(target) < len(read_splat_ply(export_folder(
        folder, ["splats.ply"], output=tmp_path / "full.ply", density="dense")[0]))
    with pytest.raises(ConfigError, match="spz_version must be 3 or 4"):
        export_folder(folder, ["splats.spz"], output=tmp_path / "v2.spz", spz_version=2)


def test_registry_names_files_that_owned_knows(photo):
    assert list(FORMATS) == ["splats.ply", "splats.spz", "splats.glb", "mesh.usdz", "quilt"]
    assert [f.name for f in check_formats(["quilt", "splats.ply", "quilt"])] == [
        "quilt", "splats.ply"]
    for fmt in FORMATS.values():
        try:
            name = fmt.filename(photo.ldi)
        except ImportError:  # a format whose module is not written yet
            continue
        assert any(fnmatch.fnmatchcase(name, p) for p in EXPORT_FILES), name


def test_cli_export(folder, photo, capsys, tmp_path):
    from photo3d.save_options import EXPORT_FORMATS

    assert EXPORT_FORMATS == tuple(FORMATS)  # the names the CLI and SaveOptions take
    assert main(["export", str(folder), "splats.spz", "splats.ply", "--splats", "dense",
                 "--spz-version", "4"]) == 0
    out = capsys.readouterr().out
    assert "exported 2 file(s)" in out and "splats.spz" in out and " splats" in out
    # the memory it may take, said before the work
    assert out.startswith(f"export: {photo.ldi.size:,} LDI pixels, dense splats, colours "
                          "fitted, at most about ")  # fitted by default
    written = json.loads((folder / "config.json").read_text())["written"]
    assert {"splats.spz", "splats.ply"} <= set(written)
    assert (folder / "splats.spz").read_bytes()[:4] == b"NGSP"
    assert splat_count(folder / "splats.ply") == len(read_splat_ply(folder / "splats.ply"))
    (folder / "splats.glb").write_bytes(b"mine")
    assert main(["export", str(folder), "splats.glb"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "photo3d did not write it" in err
    assert main(["export", str(tmp_path / "none"), "splats.ply", "-q"]) == 2
    assert "no 3D photo folder" in capsys.readouterr().err
    assert main(["export", str(folder), "splats.ply", "-o", str(tmp_path / "x.ply"), "-q"]) == 0
    assert splat_count(tmp_path / "x.ply") > 0


def test_a_failing_writer_leaves_the_others_recorded(folder, monkeypatch):
    from photo3d.export import Format

    def fail(ldi, path, **options):
        raise OutputError("disk full")

    monkeypatch.setitem(FORMATS, "splats.glb", Format(
        "splats.glb", __name__, "fail", lambda ldi: "splats.glb", ()))
    monkeypatch.setitem(globals(), "fail", fail)
    with pytest.raises(OutputError, match="disk full"):
        export_folder(folder, ["splats.glb", "splats.ply"])
    assert "splats.ply" in recorded_files(folder) and not (folder / "splats.glb").exists()


def test_spz_version_4_without_zstd_is_refused_before_the_work(folder, monkeypatch):
    import sys

    from photo3d.errors import MissingExtra

    for name in ("compression", "compression.zstd", "backports", "backports.zstd"):
        monkeypatch.setitem(sys.modules, name, None)  # as if neither were installed
    with pytest.raises(MissingExtra, match=r"photo3d\[spz4\]"):
        export_folder(folder, ["splats.ply", "splats.spz"], spz_version=4)
    assert not (folder / "splats.ply").exists()  # nothing written
    export_folder(folder, ["splats.spz"])  # version 3 needs no zstd
    assert (folder / "splats.spz").read_bytes()[:2] == b"\x1f\x8b"
