import numpy as np
from scipy import ndimage

from photo3d.inpaint.edgepaths import edge_paths, thin


def disk_band(h=60, w=80, width=7):
    """A curved band ``width`` px thick (a quarter ring)."""
    yy, xx = np.mgrid[:h, :w]
    r = np.hypot(yy - h, xx)
    return np.abs(r - 45) < width / 2


def test_thinning_keeps_one_connected_pixel_wide_curve_inside_the_shape():
    band = disk_band()
    skel = thin(band)
    assert skel.any() and not (skel & ~band).any()
    assert ndimage.label(skel, structure=np.ones((3, 3)))[1] == 1
    # one pixel wide: no 2x2 block of skeleton pixels
    blocks = skel[:-1, :-1] & skel[1:, :-1] & skel[:-1, 1:] & skel[1:, 1:]
    assert not blocks.any()
    # it follows the band's middle: every skeleton pixel within 1.5 px of radius 45
    yy, xx = np.nonzero(skel)
    assert np.abs(np.hypot(yy - 60, xx) - 45).max() < 1.5
    assert skel.sum() > 0.6 * 45 * np.pi / 2  # and spans most of its length


def test_paths_keep_only_pieces_that_continue_a_context_edge():
    band = disk_band()
    ctx_edge = np.zeros_like(band)
    ctx_edge[59, 40:46] = True  # meets the band's lower end
    speck = np.zeros_like(band)
    speck[5:12, 70:77] = True  # a blob no context edge reaches
    paths = edge_paths(band | speck, ctx_edge)
    assert paths[band].any() and not paths[speck].any()
    np.testing.assert_array_equal(paths, thin(band))
    assert not edge_paths(band, np.zeros_like(band)).any()
