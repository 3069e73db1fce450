import pickle

import numpy as np
import pytest
from scipy import ndimage

from photo3d.errors import InputError
from photo3d.eval.metrics import psnr, ssim


def photo():
    from skimage import data

    return (data.astronaut()[::2, ::2].astype(np.float32) / 255)[:160, :160]


def test_psnr_and_ssim_known_values_and_masks():
    a = photo()
    b = a.copy()
    b[:80] = np.clip(b[:80] + 0.1, 0, 1)
    mask = np.zeros(a.shape[:2], bool)
    mask[100:] = True
    assert psnr(a, b, mask) == float("inf") and ssim(a, a) == pytest.approx(1.0)
    assert psnr(a, b, ~mask) < 25
    assert ssim(a, ndimage.gaussian_filter(a, (2, 2, 0))) < ssim(a, ndimage.gaussian_filter(
        a, (1, 1, 0))) < 1
    with pytest.raises(InputError, match="differ in shape"):
        psnr(a, a[:10])


def test_lpips_behaves_like_lpips():
    from photo3d.eval.lpips import lpips

    pytest.importorskip("torch")
    a = photo()
    rng = np.random.default_rng(0)
    assert lpips(a, a) == 0.0
    blur = [lpips(a, ndimage.gaussian_filter(a, (s, s, 0))) for s in (0.5, 1, 2, 4)]
    noise = [lpips(a, np.clip(a + rng.normal(0, n, a.shape), 0, 1).astype(np.float32))
             for n in (0.02, 0.05, 0.1, 0.2)]
    assert blur == sorted(blur) and noise == sorted(noise)  # more distortion, more distance
    # the published LPIPS-Alex range for these distortions on natural photos
    assert 0.15 < blur[2] < 0.6 and 0.15 < noise[2] < 0.7 and noise[-1] < 1.0
    b = ndimage.gaussian_filter(a, (2, 2, 0))
    assert lpips(a, b) == pytest.approx(lpips(b, a), rel=1e-5)
    mask = np.zeros(a.shape[:2], bool)
    mask[:, :80] = True
    c = a.copy()
    c[:, 100:] = b[:, 100:]  # distorted only on the right
    assert lpips(a, c, mask) < 0.5 * lpips(a, c, ~mask)


def test_lpips_checkpoint_reader_refuses_code():
    pytest.importorskip("torch")
    from photo3d.nets.pretrained import convert_checkpoint

    class Evil:
        def __reduce__(self):
            return (print, ("pwned",))

    with pytest.raises(pickle.UnpicklingError, match="refusing"):
        convert_checkpoint(pickle.dumps({"AlexNet_0": Evil()}))
    tree = {"AlexNet_0": {f"Conv_{i}": {"kernel": np.ones((1, 1, 1, 1), np.float32),
                                        "bias": np.zeros(1, np.float32)} for i in range(5)}}
    tree.update({f"NetLinLayer_{i}": {"Conv_0": {"kernel": np.ones((1, 1, 1, 1))}}
                 for i in range(5)})
    flat = convert_checkpoint(pickle.dumps(tree))
    assert set(flat) == {f"{k}{i}.{p}" for i in range(5) for k, p in
                         (("conv", "kernel"), ("conv", "bias"), ("lin", "kernel"))}
