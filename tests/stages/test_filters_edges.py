import numpy as np
import pytest

from photo3d.stages.edges import find_discontinuities, link_edges
from photo3d.stages.filters import bilateral_median


def test_bilateral_median_removes_speckles_and_keeps_the_step():
    rng = np.random.default_rng(1)
    d = np.zeros((40, 40), np.float32)
    d[:, 20:] = 1.0
    clean_cuts = (find_discontinuities(d, 0.04) > 0).sum()
    noisy = d.copy()
    band = np.zeros_like(d, bool)
    band[:, 14:26] = True
    speckle = band & (rng.random(d.shape) < 0.1)
    noisy[speckle] = rng.random(speckle.sum())
    out = bilateral_median(noisy)
    assert (find_discontinuities(noisy, 0.04) > 0).sum() > 3 * clean_cuts
    assert (find_discontinuities(out, 0.04) > 0).sum() < 1.5 * clean_cuts
    assert np.all(out[:, :18] < 0.5) and np.all(out[:, 22:] > 0.5)


def test_bilateral_median_leaves_smooth_ramps_alone():
    ramp = np.tile(np.linspace(0, 1, 40, dtype=np.float32), (20, 1))
    # away from the image border (truncated windows) a linear ramp is its own median
    np.testing.assert_allclose(bilateral_median(ramp)[:, 3:-3], ramp[:, 3:-3], atol=1e-6)


def test_discontinuity_sits_on_the_background_pixel():
    d = np.zeros((3, 4), np.float32)
    d[:, 2:] = 1.0
    cuts = find_discontinuities(d, 0.04)
    assert np.all(cuts[:, 1] == 2)  # background pixel, cut towards the right
    assert np.all(cuts[:, [0, 2, 3]] == 0)


def test_two_planes_give_one_edge_along_the_boundary():
    d = np.ones((30, 40), np.float32) * 0.2
    d[:, 25:] = 0.8
    e = link_edges(d, threshold=0.04, min_length=10)
    assert e.count == 1
    assert np.array_equal(np.nonzero(e.labels.any(axis=0))[0], [24])


def test_short_segments_are_removed():
    d = np.zeros((30, 40), np.float32)
    d[5:8, 5:7] = 1.0  # speckle: 2x3 foreground, its silhouette has 10 pixels
    d[10:25, 20:] = 1.0  # long edge
    assert link_edges(d, threshold=0.04, min_length=11).labels[4:9, 4:8].max() == 0
    assert link_edges(d, threshold=0.04, min_length=10).labels[4:9, 4:8].max() > 0


def test_junction_of_three_layers_is_split_by_ldi_connectivity():
    # left: far (0), top-right: middle (0.5), bottom-right: near (1).
    d = np.zeros((40, 40), np.float32)
    d[:20, 20:] = 0.5
    d[20:, 20:] = 1.0
    e = link_edges(d, threshold=0.04, min_length=5)
    # the vertical boundary's background is one layer (x = 19, far) and the horizontal
    # boundary's background is another (y = 19, middle): connected by 8-adjacency at
    # the junction but not in the LDI, so they are two edges.
    vertical = set(e.labels[:, 19].tolist()) - {0}
    horizontal = set(e.labels[19, 21:].tolist()) - {0}
    assert len(vertical) == 1 and len(horizontal) == 1 and vertical != horizontal
    assert e.count == 2


def test_short_segment_touching_a_long_edge_is_attached_or_dropped():
    d = np.zeros((30, 30), np.float32)
    d[:, 20:] = 1.0
    d[10:13, 17:20] = 0.5  # small middle-depth blob against the foreground
    attached = link_edges(d, threshold=0.04, min_length=10)
    dropped = link_edges(d, threshold=0.04, min_length=10, attach_short=False)
    long_id = attached.labels[0, 19]
    assert long_id > 0
    assert np.all(attached.labels[10:13, 19] == long_id)
    assert np.all(attached.cuts[10:13, 19] & 2)
    assert np.all(dropped.labels[10:13, 19] == 0) and np.all(dropped.cuts[10:13, 19] == 0)


def test_spread_is_scipys_maximum_minus_minimum_filter():
    from scipy import ndimage

    from photo3d.stages.steps import spread_above

    rng = np.random.default_rng(3)
    d = np.where(rng.random((37, 53)) < 0.7, 0.25, rng.random((37, 53))).astype(np.float32)
    for size in (1, 3, 5, 7, 9):
        spread = ndimage.maximum_filter(d, size) - ndimage.minimum_filter(d, size)
        np.testing.assert_array_equal(spread_above(d, size, 0.04), spread > 0.04)


def _sorted_scan(d, y, x, radius, sigma_s, sigma_i):
    """The weighted median of one window as the filter defines it: weights computed in
    float64, kept as float32, values sorted (stably), the first to reach half."""
    h, w = d.shape
    vals, wts, total = [], [], 0.0
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            if 0 <= y + dy < h and 0 <= x + dx < w:
                v = d[y + dy, x + dx]
                diff = np.float32(v - d[y, x])
                wt = np.exp(-(dy * dy + dx * dx) / (2.0 * sigma_s ** 2)
                            - float(np.float32(diff * diff)) / (2.0 * sigma_i ** 2))
                vals.append(v)
                wts.append(np.float32(wt))
                total += wt
    order = np.argsort(np.array(vals), kind="stable")
    acc = 0.0
    for j in order:
        acc += float(wts[j])
        if acc >= 0.5 * total:
            return vals[j]
    return vals[order[-1]]


@pytest.mark.parametrize("sigmas", [(4.0, 0.5), (1e12, 1e12)])  # the defaults; weights 1
def test_each_filtered_pixel_is_the_weighted_median_of_its_window(sigmas):
    rng = np.random.default_rng(4)
    d = np.round(rng.random((23, 29)) * 6).astype(np.float32) / 6  # many equal values
    out = bilateral_median(d, windows=(5,), threshold=0.0, sigma_spatial=sigmas[0],
                           sigma_intensity=sigmas[1])
    for y in range(23):
        for x in range(29):  # equal weights: the border's even windows hit half exactly
            assert out[y, x] == _sorted_scan(d, y, x, 2, *sigmas)


def test_bilateral_median_uses_the_callers_budget(monkeypatch):
    from photo3d import parallel
    from photo3d.stages import filters

    pools = []
    real = parallel.thread_pool

    def recording(most=None, *, name="work"):
        pools.append(parallel.width(most))
        return real(most, name=name)

    monkeypatch.setattr(filters.parallel, "thread_pool", recording)
    rng = np.random.default_rng(3)
    disparity = rng.random((24, 24)).astype(np.float32)
    with parallel.share(1):  # as `batch` gives each worker on two cores
        one = filters.bilateral_median(disparity)
    assert pools == [1]
    with parallel.share(3):
        np.testing.assert_array_equal(filters.bilateral_median(disparity), one)
    assert pools[1] == 3
