"""The exception family: MissingExtra and require name the extra to install, at every
site that imports an optional package, and the CLI turns it into one line (exit 2)."""

from __future__ import annotations

import pickle
import sys

import numpy as np
import pytest

from photo3d.errors import InputError, MissingExtra, Photo3DError, install_hint, require


def test_missing_extra_is_a_photo3d_error_and_an_import_error():
    err = MissingExtra("reading HEIF/HEIC photos", "pillow-heif", "heif", module="pillow_heif")
    assert isinstance(err, InputError) and isinstance(err, Photo3DError)
    assert isinstance(err, ValueError) and isinstance(err, ImportError)
    assert str(err) == "reading HEIF/HEIC photos needs pillow-heif: pip install 'photo3d[heif]'"
    assert (err.extra, err.name, err.package, err.hint) == (
        "heif", "pillow_heif", "pillow-heif", "pip install 'photo3d[heif]'")
    back = pickle.loads(pickle.dumps(err))  # crosses process boundaries (batch workers)
    assert type(back) is MissingExtra and str(back) == str(err)
    assert (back.extra, back.name, back.hint) == (err.extra, err.name, err.hint)
    core = MissingExtra("writing video", "PyAV", None, module="av.video")
    assert str(core) == "writing video needs PyAV: pip install av"
    own = MissingExtra("x", "OpenCV's contrib modules", "stereo", hint="pip do this")
    assert str(own) == "x needs OpenCV's contrib modules: pip do this" and own.extra == "stereo"
    assert install_hint("gl") == "pip install 'photo3d[gl]'"


def test_require_imports_or_names_the_extra(monkeypatch):
    import json.decoder  # noqa: F401

    assert require("json", None, purpose="x") is sys.modules["json"]
    monkeypatch.setitem(sys.modules, "json", None)
    with pytest.raises(MissingExtra, match=r"^reading JSON needs json: pip install "
                                           r"'photo3d\[web\]'$") as err:
        require("json", "web", purpose="reading JSON")
    assert err.value.extra == "web" and isinstance(err.value.__cause__, ImportError)
    # a submodule already imported still counts as missing when its package is
    with pytest.raises(ImportError, match="needs the json package"):
        require("json.decoder", "web", purpose="x", package="the json package")


def _tiff(tmp_path):
    tifffile = pytest.importorskip("tifffile")
    path = tmp_path / "d.tif"
    tifffile.imwrite(path, np.ones((8, 8), np.float64))
    from photo3d.io.decoding import read_tiff_page

    return lambda: read_tiff_page(path)


def _heif(tmp_path):
    from photo3d.depth.heif import read_heif_image

    (tmp_path / "a.heic").write_bytes(b"not read")
    return lambda: read_heif_image(tmp_path / "a.heic")


def _yaml(tmp_path):
    from photo3d.camera import Intrinsics
    from photo3d.render.paths import load_path

    (tmp_path / "path.yaml").write_text("[]")
    k = Intrinsics(fx=10.0, fy=10.0, cx=4.0, cy=4.0, width=8, height=8)
    return lambda: load_path(tmp_path / "path.yaml", k, frames=2)


def _onnx(tmp_path):
    from photo3d.depth.models import run_model

    return lambda: run_model(np.zeros((8, 8, 3)), tmp_path / "m.onnx")


def _transformers(tmp_path):
    from photo3d.depth.models import run_model

    return lambda: run_model(np.zeros((8, 8, 3)), "some/model")


def _stereo(tmp_path):
    from photo3d.depth.stereo import check_pair

    image = np.zeros((32, 32, 3), np.float32)
    return lambda: check_pair(image, image)


def _sample(tmp_path):
    from photo3d.sample import motorcycle

    return motorcycle


def _gl(tmp_path):
    from photo3d.render.renderer import select_backend

    return lambda: select_backend("gl")


def _lpips(tmp_path):
    from photo3d.eval.lpips import lpips

    image = np.zeros((32, 32, 3), np.float32)
    return lambda: lpips(image, image)


SITES = [  # (what, module made missing, the call, extra named)
    ("TIFF", "tifffile", _tiff, "tiff"),
    ("HEIF", "pillow_heif", _heif, "heif"),
    ("YAML path", "yaml", _yaml, "yaml"),
    ("ONNX depth", "onnxruntime", _onnx, "depth"),
    ("hub depth", "transformers", _transformers, "depth"),
    ("stereo", "cv2", _stereo, "stereo"),
    ("sample", "skimage", _sample, "sample"),
    ("OpenGL", "moderngl", _gl, "gl"),
    ("LPIPS", "torch", _lpips, "eval"),
]


@pytest.mark.parametrize(("what", "module", "make_call", "extra"), SITES,
                         ids=[s[0] for s in SITES])
def test_each_site_names_its_extra(what, module, make_call, extra, tmp_path, monkeypatch):
    call = make_call(tmp_path)
    monkeypatch.setitem(sys.modules, module, None)
    with pytest.raises(MissingExtra) as err:
        call()
    assert err.value.extra == extra and err.value.name.split(".")[0] == module
    assert str(err.value).endswith(f"pip install 'photo3d[{extra}]'")
    assert "\n" not in str(err.value)


def test_stereo_without_the_contrib_modules_says_which_package(monkeypatch):
    from photo3d.depth.stereo import check_pair

    class PlainOpenCV:
        pass

    image = np.zeros((32, 32, 3), np.float32)
    monkeypatch.setitem(sys.modules, "cv2", PlainOpenCV())
    with pytest.raises(MissingExtra, match="stereo matching needs OpenCV's contrib modules: "
                                           "pip uninstall opencv-python-headless and pip "
                                           r"install 'photo3d\[stereo\]'") as err:
        check_pair(image, image)
    assert err.value.extra == "stereo"


def test_the_cli_prints_one_line_and_exits_2(monkeypatch, capsys):
    from photo3d.cli import main, view

    def needs_gl(args):
        require("no_such_module_xyz", "gl", purpose="the viewer test", package="moderngl")

    monkeypatch.setattr(view, "run", needs_gl)
    assert main(["view", "out"]) == 2
    assert capsys.readouterr().err == (
        "photo3d: error: the viewer test needs moderngl: pip install 'photo3d[gl]'\n")

    def bug(args):
        raise ImportError("cannot import name 'x' (pip install would not help)")

    monkeypatch.setattr(view, "run", bug)
    with pytest.raises(ImportError, match="cannot import name"):  # a bug is not hidden
        main(["view", "out"])
