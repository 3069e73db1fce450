import re

import numpy as np
import pytest

from photo3d.depth.normalize import fill_unknown, normalize, prepare_depth
from photo3d.errors import InputError


def test_unknown_pixels_take_the_farther_row_neighbour():
    d = np.array([[1.0, np.inf, np.nan, 5.0], [3.0, -1.0, 3.0, 3.0]], np.float32)
    out = prepare_depth(d, (2, 4), kind="disparity")
    assert out.disparity.tolist() == [[1.0, 1.0, 1.0, 5.0], [3.0, 3.0, 3.0, 3.0]]
    assert out.unknown.sum() == 3


def test_rows_without_known_values_take_the_farthest_value():
    d = np.array([[2.0, 4.0], [np.nan, np.nan]], np.float32)
    assert fill_unknown(d, np.isnan(d)).tolist() == [[2.0, 4.0], [2.0, 2.0]]


def test_depth_kind_inverts():
    d = np.array([[2.0, 4.0]], np.float32)
    out = prepare_depth(d, (1, 2), kind="depth").disparity
    np.testing.assert_allclose(out, [[0.5, 0.25]])


def test_resamples_same_aspect_with_warning_and_refuses_other_shapes():
    d = np.ones((10, 20), np.float32)
    with pytest.warns(UserWarning, match="resampling"):
        assert prepare_depth(d, (20, 40), kind="disparity").disparity.shape == (20, 40)
    with pytest.raises(InputError, match=r"shape \(10, 20\) but image is \(20, 20\)"):
        prepare_depth(d, (20, 20), kind="disparity")


def test_all_invalid_is_an_error():
    with pytest.raises(InputError, match="no valid value"):
        prepare_depth(np.full((4, 4), np.nan), (4, 4), kind="disparity")
    with pytest.raises(InputError, match="no valid value"):
        prepare_depth(-np.ones((4, 4)), (4, 4), kind="depth")


def test_normalize_range_and_constant_map():
    n, lo, hi = normalize(np.array([[3.0, 5.0, 4.0]], np.float32))
    assert n.tolist() == [[0.0, 1.0, 0.5]] and (lo, hi) == (3.0, 5.0)
    n, _, _ = normalize(np.full((2, 2), 7.0, np.float32))
    assert not n.any()


def test_normalize_and_check_depth_agree_on_flat():
    """One threshold (photo3d.depth.checks.FLAT_RANGE) for both: a map that check_depth
    calls flat is normalised flat, one it does not is stretched to [0, 1]. Before,
    normalize flattened only a range of 1e-12 and stretched the rest."""
    from photo3d.depth.checks import FLAT_RANGE, check_depth

    for relative in (0.0, 1e-7, 0.5 * FLAT_RANGE, 0.99 * FLAT_RANGE, 1.01 * FLAT_RANGE, 0.5):
        d = np.array([[10.0 * (1.0 - relative), 10.0]], np.float32)
        n, lo, hi = normalize(d)
        flat = bool(check_depth(np.repeat(d, 3, axis=0)))
        assert flat == (relative < FLAT_RANGE) and (lo, hi) == (float(d.min()), 10.0)
        assert n.tolist() == ([[0.0, 0.0]] if flat else [[0.0, 1.0]])


def test_values_float32_cannot_hold_are_unknown_not_nan():
    """A depth so small that its inverse overflows float32, and a float64 value beyond
    float32, are unknown pixels (filled), with no NumPy warning. Before, a depth of
    1e-40 became an infinite disparity, and normalising it wrote NaN into the LDI."""
    tiny = np.array([[1e-40, 2.0, 4.0]], np.float32)
    out = prepare_depth(tiny, (1, 3), kind="depth")
    assert out.unknown.tolist() == [[True, False, False]]
    np.testing.assert_allclose(out.disparity, [[0.5, 0.5, 0.25]])
    assert np.isfinite(normalize(out.disparity)[0]).all()
    huge = np.array([[1e300, 2.0, 4.0]])
    out = prepare_depth(huge, (1, 3), kind="disparity")
    assert out.unknown.tolist() == [[True, False, False]]
    assert out.disparity.tolist() == [[2.0, 2.0, 4.0]]


@pytest.mark.parametrize("dtype", [bool, np.complex64, "m8[s]", object])
def test_depth_of_no_real_number_dtype_is_refused(dtype):
    """Before, a complex map lost its imaginary part with only NumPy's ComplexWarning,
    and a timedelta map was taken as numbers (read_depth refuses both)."""
    message = re.escape(f"depth has dtype {np.dtype(dtype)}; expected real numbers")
    with pytest.raises(InputError, match=message):
        prepare_depth(np.ones((4, 4)).astype(dtype), (4, 4), kind="disparity")
