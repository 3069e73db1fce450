"""Export formats whose packages are missing are told before any work."""

import numpy as np

from photo3d import pipeline
from photo3d.cli import main
from photo3d.errors import require
from photo3d.export import usdz
from photo3d.io.images import write_image


def test_a_missing_package_of_an_export_is_told_before_the_work(tmp_path, capsys,
                                                                monkeypatch):
    # issue 45: `--export mesh.usdz` without usd-core was found only after the photo
    # was made, and `batch` made and threw away every photo
    def missing() -> None:  # as without usd-core
        require("photo3d_no_such_package", "usdz", purpose="writing USDZ", package="usd-core")

    def never(*args, **kwargs):
        raise AssertionError("the photo was made")

    monkeypatch.setattr(usdz, "require_usd", missing)
    monkeypatch.setattr(pipeline, "make", never)
    (tmp_path / "in").mkdir()
    write_image(tmp_path / "in" / "p.png", np.full((32, 32, 3), 0.5, np.float32))
    np.save(tmp_path / "d.npy", np.ones((32, 32), np.float32))
    (tmp_path / "depth").mkdir()
    np.save(tmp_path / "depth" / "p.npy", np.ones((32, 32), np.float32))
    line = "photo3d: error: writing USDZ needs usd-core: pip install 'photo3d[usdz]'\n"
    assert main(["make", str(tmp_path / "in" / "p.png"), "--depth", str(tmp_path / "d.npy"),
                 "-o", str(tmp_path / "o"), "--export", "mesh.usdz", "-q"]) == 2
    assert capsys.readouterr().err == line and not (tmp_path / "o").exists()
    assert main(["batch", str(tmp_path / "in"), "--depth", str(tmp_path / "depth"), "-o",
                 str(tmp_path / "b"), "--export", "mesh.usdz", "-q"]) == 2
    assert capsys.readouterr().err == line and not (tmp_path / "b").exists()
