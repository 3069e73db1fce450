import numpy as np
import pytest
from PIL import Image

from photo3d.cli import main
from photo3d.errors import InputError
from photo3d.eval.evaluate import evaluate
from photo3d.eval.stereo_pair import load_pair, motorcycle_pair, read_calib
from photo3d.eval.synthetic import synthetic_pair
from photo3d.eval.warp import forward_warp
from photo3d.io.depth import write_pfm


def test_forward_warp_leaves_a_hole_as_wide_as_the_disparity_jump():
    img = np.random.default_rng(0).random((4, 40, 3)).astype(np.float32)
    d = np.full((4, 40), 2.0, np.float32)
    d[:, 20:] = 9.0  # near object on the right moves 9 px left, background 2 px
    w = forward_warp(img, d)
    assert w.disoccluded.sum(axis=1).tolist() == [0, 0, 0, 0]  # hole is at the border side
    d2 = np.full((4, 40), 9.0, np.float32)
    d2[:, 20:] = 2.0  # near object on the left: a 7 px hole opens on its right
    w2 = forward_warp(img, d2)
    assert w2.disoccluded.sum(axis=1).tolist() == [7, 7, 7, 7]


def test_synthetic_ground_truth_is_consistent():
    pair = synthetic_pair(3, width=96, height=72)
    w = forward_warp(pair.left, pair.disparity)
    ok = w.reached & w.frame
    err = np.abs(w.color[ok] - pair.right[ok]).mean()
    assert err < 0.03  # the warp of the exact left view reproduces the exact right view
    assert 0.001 < w.disoccluded.mean() < 0.3


def test_calib_and_pair_loading_give_consistent_cameras(tmp_path):
    pair = synthetic_pair(1, width=64, height=48)
    for name, img in (("left.png", pair.left), ("right.png", pair.right)):
        Image.fromarray(np.round(img * 255).astype(np.uint8)).save(tmp_path / name)
    disp = pair.disparity.copy()
    disp[0, 0] = np.inf
    write_pfm(tmp_path / "disp0.pfm", disp)
    k = pair.left_camera
    (tmp_path / "calib.txt").write_text(
        f"cam0=[{k.fx} 0 {k.cx}; 0 {k.fy} {k.cy}; 0 0 1]\n"
        f"cam1=[{k.fx} 0 {k.cx}; 0 {k.fy} {k.cy}; 0 0 1]\ndoffs=0\nbaseline={pair.baseline}\n"
        "width=64\nheight=48\nndisp=32\n")
    loaded = load_pair(tmp_path / "left.png", tmp_path / "right.png", tmp_path / "disp0.pfm",
                       tmp_path / "calib.txt")
    assert np.isnan(loaded.disparity[0, 0])
    z = loaded.depth()
    np.testing.assert_allclose(z[1:, 1:], (k.fx * pair.baseline / pair.disparity)[1:, 1:],
                               rtol=1e-5)
    # a left pixel at depth z lands d = f B / z to the left in the right camera
    x, y = 40, 20
    p = np.array([(x + 0.5 - k.cx) / k.fx * z[y, x], (y + 0.5 - k.cy) / k.fy * z[y, x], z[y, x]])
    cam = loaded.right_camera
    pc = cam.pose[:3, :3] @ p + cam.pose[:3, 3]
    xr = pc[0] / pc[2] * cam.intrinsics.fx + cam.intrinsics.cx - 0.5
    assert xr == pytest.approx(x - loaded.disparity[y, x], abs=1e-3)
    with pytest.raises(InputError, match="missing"):
        (tmp_path / "bad.txt").write_text("cam0=[1 0 0; 0 1 0; 0 0 1]\n")
        read_calib(tmp_path / "bad.txt")


def test_read_calib_refuses_a_file_too_large_before_reading_it(tmp_path):
    # hostile round: read_calib read a calib.txt of any size whole (this one parses)
    calib = tmp_path / "calib.txt"
    calib.write_text("cam0=[50 0 32; 0 50 24; 0 0 1]\ncam1=[50 0 34; 0 50 24; 0 0 1]\n"
                     "baseline=100\nwidth=64\nheight=48\n" + "#\n" * (1 << 20))
    with pytest.raises(InputError, match="calibration .*calib.txt: it has 2097[0-9]* bytes, "
                                         "more than the 1048576 expected"):
        read_calib(calib)


def test_motorcycle_pair_geometry():
    pair = motorcycle_pair()
    assert pair.left.shape == (500, 741, 3) and np.isnan(pair.disparity).any()
    assert pair.right_camera.intrinsics.cx - pair.left_camera.cx == pytest.approx(31.086)
    z = pair.depth()
    assert 1000 < np.nanmedian(z) < 10000  # millimetres: a motorcycle a few metres away


def test_inpainting_beats_the_baselines_where_it_matters():
    pair = synthetic_pair(0, width=128, height=96)
    r = evaluate(pair, ["forward-warp", "stretch", "diffusion"], lpips=False)
    dis = {m: r.scores[m]["disoccluded"]["psnr"] for m in r.scores}
    assert dis["diffusion"] > dis["forward-warp"] + 3
    assert dis["diffusion"] > dis["stretch"]
    assert r.scores["diffusion"]["all"]["ssim"] > r.scores["forward-warp"]["all"]["ssim"]


def test_eval_command_writes_tables_and_grids(tmp_path, capsys):
    out = tmp_path / "ev"
    assert main(["eval", "--synthetic", "1", "--methods", "forward-warp,diffusion",
                 "--no-lpips", "-o", str(out), "-q"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["grid_synthetic0.png", "results.json",
                                                     "results.md"]
    assert "| diffusion |" in (out / "results.md").read_text()
    assert main(["eval", "--methods", "magic", "-o", str(out)]) == 2
    assert "unknown method" in capsys.readouterr().err
