"""Stereo disparity: known answers on a synthetic two-layer pair, the real
Middlebury pair against its ground truth, and refusal of unusable pairs."""

from __future__ import annotations

import numpy as np
import pytest

cv2 = pytest.importorskip("cv2")
if not hasattr(cv2, "ximgproc"):
    pytest.skip("stereo needs opencv-contrib-python-headless", allow_module_level=True)

from photo3d.depth import stereo  # noqa: E402
from photo3d.depth.stereo import check_pair, stereo_disparity  # noqa: E402
from photo3d.errors import InputError  # noqa: E402
from photo3d.sample import motorcycle  # noqa: E402

BG, FG = 4, 14  # disparities in pixels
BOX = (40, 100, 70, 150)  # y0, y1, x0, x1 of the foreground square (left view)


def noise_texture(h: int, w: int, seed: int) -> np.ndarray:
    """``(h, w, 3)`` float32 random blocks of 2x2 px: every patch is distinctive."""
    rng = np.random.default_rng(seed)
    small = rng.random((h // 2 + 1, w // 2 + 1, 3))
    return small.repeat(2, 0).repeat(2, 1)[:h, :w].astype(np.float32)


def layered_pair(h: int = 140, w: int = 220):
    """Left/right views of a textured square (disparity FG) before a wall (BG)."""
    bg, fg = noise_texture(h, w + BG, 1), noise_texture(h, w, 2)
    y0, y1, x0, x1 = BOX
    left, right = bg[:, :w].copy(), bg[:, BG:BG + w].copy()
    left[y0:y1, x0:x1] = fg[y0:y1, x0:x1]
    right[y0:y1, x0 - FG:x1 - FG] = fg[y0:y1, x0:x1]
    truth = np.full((h, w), BG, np.float32)
    truth[y0:y1, x0:x1] = FG
    return left, right, truth


def bad2(disparity: np.ndarray, truth: np.ndarray, mask: np.ndarray) -> float:
    return float((np.abs(disparity - truth) > 2)[mask].mean())


def test_synthetic_pair_recovers_both_layers():
    left, right, truth = layered_pair()
    res = stereo_disparity(left, right)
    assert res.disparity.shape == truth.shape and res.disparity.dtype == np.float32
    assert res.valid.dtype == bool and 0.5 < res.valid.mean() < 1.0
    y0, y1, x0, x1 = BOX
    assert np.median(res.disparity[y0 + 5:y1 - 5, x0 + 5:x1 - 5]) == pytest.approx(FG, abs=0.5)
    assert np.median(res.disparity[:, 30:60]) == pytest.approx(BG, abs=0.5)
    judged = np.ones_like(truth, bool)
    judged[:, :res.max_disparity] = False  # no match possible left of the search range
    assert bad2(res.disparity, truth, judged) < 0.03


def test_occlusions_fail_the_left_right_check_and_are_filled_from_the_background():
    left, right, truth = layered_pair()
    res = stereo_disparity(left, right)
    y0, y1, x0, x1 = BOX
    # Left of the square, a band FG - BG wide is visible in the left view only.
    band = (slice(y0 + 5, y1 - 5), slice(x0 - (FG - BG) + 2, x0 - 2))
    assert res.valid[band].mean() < 0.2
    assert np.abs(res.disparity[band] - BG).max() <= 2


def test_reduced_working_size_keeps_disparities_in_input_pixels(monkeypatch):
    monkeypatch.setattr(stereo, "WORK_SIZE", 110)  # matched at half size
    left, right, truth = layered_pair()
    res = stereo_disparity(left, right)
    assert res.disparity.shape == truth.shape
    y0, y1, x0, x1 = BOX
    assert np.median(res.disparity[y0 + 8:y1 - 8, x0 + 8:x1 - 8]) == pytest.approx(FG, abs=1)


def test_motorcycle_bad2_against_ground_truth():
    s = motorcycle()
    res = stereo_disparity(s.left, s.right)
    known = np.isfinite(s.disparity)
    assert bad2(res.disparity, s.disparity, known) < 0.12  # measured 0.103
    assert res.check.reliable and res.check.same_row > 0.8 and res.warnings == ()
    assert 60 <= res.max_disparity <= 96  # from the matches: ground truth goes to 60
    assert res.valid.mean() > 3 * stereo.MIN_MATCHED  # a real pair: far above the refusal


def test_swapped_pair_is_refused():
    s = motorcycle()
    with pytest.raises(InputError, match="left and right seem swapped: try swapping them"):
        stereo_disparity(s.right, s.left)


@pytest.mark.parametrize("shift", [3, 5])
def test_vertically_shifted_pair_is_refused(shift):
    s = motorcycle()
    right = np.roll(s.right, shift, axis=0)
    with pytest.raises(InputError, match="not rectified: the right image is shifted vertically"):
        stereo_disparity(s.left, right)


def test_rotated_pair_is_refused():
    s = motorcycle()
    h, w = s.right.shape[:2]
    turn = cv2.getRotationMatrix2D((w / 2, h / 2), 2.0, 1.0)
    right = cv2.warpAffine(s.right, turn, (w, h))
    with pytest.raises(InputError, match="not rectified"):
        stereo_disparity(s.left, right)
    assert check_pair(s.left, right).same_row < 0.6


def test_check_can_be_disabled():
    s = motorcycle()
    right = np.roll(s.right, 3, axis=0)
    res = stereo_disparity(s.left[::2, ::2], right[::2, ::2], check=False)
    assert res.disparity.shape == s.left[::2, ::2].shape[:2]


def test_shape_mismatch_names_both_shapes():
    left, right, _ = layered_pair()
    with pytest.raises(InputError, match=r"right image has shape \(140, 200, 3\)"):
        stereo_disparity(left, right[:, :200])


def test_featureless_pair_warns_instead_of_refusing():
    flat = np.full((64, 96, 3), 0.5, np.float32)
    flat[:, 40:] = 0.7
    res = stereo_disparity(flat, flat)
    assert res.check.matches < 20
    assert "could not verify" in res.warnings[0]
    assert np.isfinite(res.disparity).all() and (res.disparity >= 0).all()


def test_a_right_view_that_matches_almost_nothing_is_refused():
    s = motorcycle()
    disparity = np.nan_to_num(np.asarray(s.disparity), posinf=0.0)
    as_image = np.repeat((disparity / disparity.max())[..., None], 3, axis=2)
    with pytest.raises(InputError) as err:
        stereo_disparity(s.left, as_image.astype(np.float32))  # a depth map as the right view
    message = str(err.value)
    assert message.startswith("the right view matches only ") and "\n" not in message
    assert message.endswith("(a depth map goes with --depth, not --right)")


def test_make_with_a_depth_map_as_the_right_view_is_one_line(tmp_path, capsys):
    from PIL import Image

    from photo3d.cli import main
    from photo3d.io.images import write_image

    s = motorcycle()
    disparity = np.nan_to_num(np.asarray(s.disparity), posinf=0.0)
    write_image(tmp_path / "photo.png", s.left)
    Image.fromarray((disparity / disparity.max() * 65535).astype(np.uint16)).save(
        tmp_path / "depth.png")
    code = main(["make", str(tmp_path / "photo.png"), "--right", str(tmp_path / "depth.png"),
                 "-o", str(tmp_path / "out"), "--no-video", "-q"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith("photo3d: error: the right view matches only ")
    assert not (tmp_path / "out").exists()
