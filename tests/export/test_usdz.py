"""``mesh.usdz`` for AR Quick Look (issue 37 item 5): usd-core's ARKit compliance
checker reports no errors, and the package reads back as the light mesh in AR Quick
Look's conventions (Y-up, metres, the photo's frame 1 m wide, a preview surface
showing the texture, a default prim)."""

from __future__ import annotations

import io
import sys
import warnings
import zipfile

import numpy as np
import pytest
from conftest import texture
from PIL import Image

import photo3d
from photo3d.errors import MissingExtra
from photo3d.export.usdz import USDZ_NAME, write_usdz
from photo3d.mesh.light import build_light_mesh
from photo3d.stages.ldi import from_image

pxr = pytest.importorskip("pxr", reason="needs pip install 'photo3d[usdz]'")
from pxr import Usd, UsdGeom, UsdShade, UsdUtils  # noqa: E402


@pytest.fixture(scope="module")
def photo():
    """A far wall with a nearer box in front of it, inpainted."""
    image = texture(40, 56, seed=5)
    disparity = np.full((40, 56), 0.3, np.float32)
    disparity[12:30, 18:38] = 1.0
    return photo3d.make(image, depth=disparity,
                        config=photo3d.Config(size=None, inpainter="diffusion"))


@pytest.fixture(scope="module")
def written(photo, tmp_path_factory):
    path = tmp_path_factory.mktemp("usdz") / USDZ_NAME
    light = build_light_mesh(photo.ldi)
    write_usdz(photo.ldi, path, mesh=light)
    return path, light


def arkit_check(path) -> tuple[list[str], list[str]]:
    """``(errors, failed checks)`` of usd-core's ARKit compliance checker (a broken
    rule is a failed check; errors are what stopped a check from running)."""
    checker_class = getattr(UsdUtils, "ComplianceChecker", None)
    if checker_class is None:
        pytest.skip("usd-core >= 26.8 has no ARKit checker; pip install 'usd-core<26.8'")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # deprecated since 25.x
        checker = checker_class(arkit=True, skipARKitRootLayerCheck=False,
                                rootPackageOnly=False, skipVariants=False, verbose=False)
        checker.CheckCompliance(str(path))
    return list(checker.GetErrors()), list(checker.GetFailedChecks())


def test_arkit_compliance_checker_reports_no_errors(written):
    assert arkit_check(written[0]) == ([], [])


def test_the_checker_can_fail(tmp_path, written):
    """The same package with a shader AR Quick Look does not know is reported."""
    with zipfile.ZipFile(written[0]) as z:
        z.extractall(tmp_path)
    stage = Usd.Stage.Open(str(tmp_path / "photo3d.usdc"))
    UsdShade.Shader(stage.GetPrimAtPath("/photo3d/material/surface")).SetShaderId("PxrSurface")
    stage.GetRootLayer().Export(str(tmp_path / "bad.usdc"))
    assert UsdUtils.CreateNewUsdzPackage(str(tmp_path / "bad.usdc"), str(tmp_path / "bad.usdz"))
    errors, failed = arkit_check(tmp_path / "bad.usdz")
    assert errors == [] and any("ARKitShaderChecker" in f for f in failed)


def test_the_validation_framework_reports_no_errors(written):
    validation = pytest.importorskip("pxr.UsdValidation")
    registry = validation.ValidationRegistry()
    context = validation.ValidationContext(registry.GetOrLoadAllValidators())
    errors = context.Validate(Usd.Stage.Open(str(written[0])))
    assert [e.GetErrorAsString() for e in errors] == []


def test_it_reads_back_as_the_light_mesh_with_its_texture(written):
    path, light = written
    with zipfile.ZipFile(path) as z:
        assert z.namelist() == ["photo3d.usdc", "texture.jpg"]  # the usdc first
        image = np.asarray(Image.open(io.BytesIO(z.read("texture.jpg"))).convert("RGB"))
    assert image.shape == light.texture.shape
    assert np.abs(image.astype(int) - light.texture).mean() < 3  # JPEG
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetDefaultPrim().GetPath() == "/photo3d"
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/photo3d/photo"))
    assert len(mesh.GetPointsAttr().Get()) == len(light.vertices)
    indices = np.array(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)
    np.testing.assert_array_equal(indices, light.faces)
    st = np.array(UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st").Get())
    np.testing.assert_allclose(st[:, 0], light.uv[:, 0], atol=1e-6)
    np.testing.assert_allclose(st[:, 1], 1 - light.uv[:, 1], atol=1e-6)  # USD's v is up
    material, _ = UsdShade.MaterialBindingAPI(mesh.GetPrim()).ComputeBoundMaterial()
    shader = material.ComputeSurfaceSource()[0]
    assert shader.GetIdAttr().Get() == "UsdPreviewSurface"
    source = shader.GetInput("emissiveColor").GetConnectedSources()[0][0].source
    file = UsdShade.Shader(source.GetPrim()).GetInput("file").Get()
    assert file.path == "./texture.jpg" and file.resolvedPath.endswith("[texture.jpg]")


def test_metres_y_up_and_the_photo_standing_on_the_origin(tmp_path):
    """A flat photo: its frame is 1 m wide, stands on y = 0, faces +z at z = 0."""
    ldi = from_image(np.full((30, 40, 3), 0.5, np.float32), np.full((30, 40), 0.5, np.float32))
    write_usdz(ldi, tmp_path / "flat.usdz")
    stage = Usd.Stage.Open(str(tmp_path / "flat.usdz"))
    points = np.array(UsdGeom.Mesh(stage.GetPrimAtPath("/photo3d/photo")).GetPointsAttr().Get())
    lo, hi = points.min(axis=0), points.max(axis=0)
    pixel = 1 / 40  # vertices sit on pixel centres, half a pixel inside the frame
    np.testing.assert_allclose(lo, [-0.5 + pixel / 2, pixel / 2, 0], atol=1e-5)
    np.testing.assert_allclose(hi, [0.5 - pixel / 2, 0.75 - pixel / 2, 0], atol=1e-5)
    top = points[np.argmax(points[:, 1])]  # the photo's top row is up (+y)
    assert top[1] > 0.7


def test_nearer_is_towards_the_viewer(written, photo):
    path, light = written
    stage = Usd.Stage.Open(str(path))
    points = np.array(UsdGeom.Mesh(stage.GetPrimAtPath("/photo3d/photo")).GetPointsAttr().Get())
    z_cv = light.vertices[:, 2]
    near, far = z_cv <= np.percentile(z_cv, 10), z_cv >= np.percentile(z_cv, 90)
    assert points[near, 2].mean() > points[far, 2].mean()


def test_no_diagnostics_on_stderr(tmp_path, capfd):
    ldi = from_image(np.full((8, 12, 3), 0.5, np.float32), np.ones((8, 12), np.float32))
    write_usdz(ldi, tmp_path / USDZ_NAME)
    assert capfd.readouterr() == ("", "")
    assert [p.name for p in tmp_path.iterdir()] == [USDZ_NAME]


def test_missing_usd_core_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pxr", None)
    monkeypatch.setitem(sys.modules, "pxr.UsdUtils", None)
    ldi = from_image(np.full((8, 12, 3), 0.5, np.float32), np.ones((8, 12), np.float32))
    with pytest.raises(MissingExtra, match=r"photo3d\[usdz\]") as caught:
        write_usdz(ldi, tmp_path / USDZ_NAME)
    assert isinstance(caught.value, ImportError)
    assert list(tmp_path.iterdir()) == []
