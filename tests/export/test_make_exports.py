"""The exports from ``make`` (``--export``, ``SaveOptions.exports``, ``photo.save(out,
exports=...)``): written inside the staged folder from the meshes ``save`` builds
anyway, recorded in ``config.json`` as ``photo3d export`` records them;
``export_folder`` builds the light mesh once for ``mesh.usdz`` and the quilt; and
both load usd-core before their writer threads start."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import texture
from PIL import Image

import photo3d
import photo3d.export.quilt
import photo3d.export.splats
import photo3d.export.usdz
import photo3d.mesh.light
import photo3d.output
from photo3d.cli import main
from photo3d.errors import ConfigError, OutputError
from photo3d.export import FORMATS, export_folder
from photo3d.export.splats import build_splats, splat_count
from photo3d.owned import owned_photo, recorded_files
from photo3d.render.animate import VideoSpec
from photo3d.save_options import EXPORT_FORMATS, SaveOptions

ALL = list(FORMATS)
QUILT = "quilt_qs8x6a0.75.png"


@pytest.fixture(scope="module")
def photo():
    """A textured wall with a nearer box: inpainted layers behind the box."""
    disparity = np.ones((40, 56), np.float32)
    disparity[10:30, 16:40] = 2.5
    return photo3d.make(texture(40, 56, seed=3), depth=disparity,
                        config=photo3d.Config(size=None, inpainter="diffusion"))


@pytest.fixture
def light_meshes(monkeypatch):
    """Every light mesh built (``(max_error, mesh)``), wherever it is built."""
    built = []
    real = photo3d.mesh.light.build_light_mesh

    def counted(ldi, **options):
        mesh = real(ldi, **options)
        built.append((options.get("max_error"), mesh))
        return mesh

    monkeypatch.setattr(photo3d.mesh.light, "build_light_mesh", counted)
    monkeypatch.setattr(photo3d.output, "build_light_mesh", counted)
    return built


@pytest.fixture
def given_meshes(monkeypatch):
    """The mesh each of ``mesh.usdz`` and the quilt was written from (by file name)."""
    given = {}

    def spying(real):
        def spy(ldi, path, *, mesh=None, **options):
            given[path.name] = mesh
            real(ldi, path, mesh=mesh, **options)

        return spy

    for module, name in ((photo3d.export.quilt, "write_quilt"),
                         (photo3d.export.usdz, "write_usdz")):
        monkeypatch.setattr(module, name, spying(getattr(module, name)))
    return given


def test_the_names_are_the_registrys():
    assert EXPORT_FORMATS == tuple(FORMATS)


def test_save_options_check_the_exports():
    assert SaveOptions(exports=None).exports == ()
    with pytest.raises(ConfigError, match="exports must be a list of format names, got 'quilt'"):
        SaveOptions(exports="quilt")
    with pytest.raises(ConfigError, match="unknown export format 3; choose from splats.ply"):
        SaveOptions(exports=[3])


def test_save_writes_every_export_from_the_light_mesh_it_built(photo, tmp_path, light_meshes,
                                                                given_meshes):
    pytest.importorskip("pxr", reason="needs pip install 'photo3d[usdz]'")
    video = VideoSpec(path="swing", size=(32, 24), frames=2)
    out = photo.save(tmp_path / "out", exports=ALL, videos=(video,))
    assert len(light_meshes) == 1  # mesh.glb, viewer.html, the exports and the video
    light = light_meshes[0][1]
    assert given_meshes == {"mesh.usdz": light, QUILT: light}
    names = ["splats.ply", "splats.spz", "splats.glb", "mesh.usdz", QUILT]
    assert {p.name for p in out.iterdir()} >= {*names, "mesh.glb", "viewer.html"}
    meta = json.loads((out / "config.json").read_text())
    assert meta["save"]["exports"] == ALL
    assert meta["written"] == sorted([*names, "video/swing.mp4"])
    assert recorded_files(out) == {*names, "video/swing.mp4"}
    assert owned_photo(out) == []  # make --overwrite may replace it
    assert [splat_count(out / n) for n in names[:3]] == [len(build_splats(photo.ldi))] * 3
    with Image.open(out / QUILT) as quilt:
        assert quilt.size == (3360, 3360)


def test_the_splats_equal_photo3d_exports(photo, tmp_path):
    made = photo.save(tmp_path / "made", exports=["splats.ply"], viewer=False, ply=None)
    exported = photo.save(tmp_path / "exported", viewer=False, ply=None)
    export_folder(exported, ["splats.ply"])
    assert (made / "splats.ply").read_bytes() == (exported / "splats.ply").read_bytes()


def test_the_light_mesh_is_built_once_for_the_exports_that_take_it(photo, tmp_path,
                                                                   light_meshes):
    out = photo.save(tmp_path / "out", glb=False, viewer=False, ply=None)
    assert light_meshes == []  # nothing asked for it
    photo.save(tmp_path / "only-exports", exports=["quilt"], glb=False, viewer=False)
    assert len(light_meshes) == 1
    del light_meshes[:]
    export_folder(out, ["quilt", "splats.spz"])
    assert len(light_meshes) == 1


def test_export_makes_the_light_mesh_of_the_folders_glb(photo, tmp_path, light_meshes):
    out = photo.save(tmp_path / "out", light_error=2.0, viewer=False, ply=None)
    del light_meshes[:]
    export_folder(out, ["quilt"])
    assert [error for error, _ in light_meshes] == [2.0]


def test_a_failed_export_leaves_no_folder(photo, tmp_path, monkeypatch):
    def fail(ldi, path, **options):
        raise OutputError("disk full")

    monkeypatch.setattr(photo3d.export.splats, "write_spz", fail)
    with pytest.raises(OutputError, match="disk full"):
        photo.save(tmp_path / "out", exports=["splats.ply", "splats.spz"])
    assert list(tmp_path.iterdir()) == []  # nothing staged is left either


def test_make_and_its_overwrite_with_exports(tmp_path, capsys):
    from photo3d.io.images import write_image

    disparity = np.ones((32, 48), np.float32)
    disparity[8:24, 12:36] = 2.0
    write_image(tmp_path / "photo.png", texture(32, 48, seed=1))
    np.save(tmp_path / "d.npy", disparity)
    out = tmp_path / "out"
    make = ["make", str(tmp_path / "photo.png"), "--depth", str(tmp_path / "d.npy"), "-o",
            str(out), "--size", "0", "--no-video", "--inpainter", "diffusion"]
    assert main([*make, "--export", "splats.spz", "--export", "quilt"]) == 0
    listed = capsys.readouterr().out
    assert "splats.spz" in listed and QUILT in listed  # make lists every file it wrote
    assert recorded_files(out) == {"splats.spz", QUILT}
    assert main([*make, "--export", "splats.ply", "--overwrite", "-q"]) == 0
    assert not (out / "splats.spz").exists() and recorded_files(out) == {"splats.ply"}
    (out / "splats.glb").write_bytes(b"mine")
    assert main([*make, "--overwrite", "-q"]) == 2  # a file photo3d did not write
    assert "splats.glb" in capsys.readouterr().err
    with pytest.raises(SystemExit, match="2"):
        main([*make, "--export", "splats.obj"])
    assert "invalid choice: 'splats.obj'" in capsys.readouterr().err


IMPORTS = """
import json, sys, threading
seen = []

def hook(event, args):
    if event == "import" and args[0].split(".")[0] == "pxr":
        seen.append([args[0], threading.current_thread() is threading.main_thread(),
                     threading.active_count()])

sys.addaudithook(hook)
import numpy as np, photo3d
from photo3d.export import export_folder
if sys.argv[1] == "save":
    disparity = np.ones((24, 32), np.float32)
    disparity[6:18, 8:24] = 2.0
    photo = photo3d.make(np.full((24, 32, 3), 0.5), depth=disparity,
                         config=photo3d.Config(size=None, inpainter="diffusion"))
    photo.save(sys.argv[2], exports=["splats.spz", "mesh.usdz", "quilt"], viewer=False)
else:
    export_folder(sys.argv[2], ["splats.spz", "quilt", "mesh.usdz"])
print(json.dumps(seen))
"""


@pytest.mark.parametrize("how", ["save", "export"])
def test_usd_core_is_loaded_before_the_writer_threads_start(photo, tmp_path, how):
    """usd-core's libraries, loaded while another thread runs numpy, can deadlock
    the process (photo3d.export.preload): they are imported by the thread that
    starts the writers, while it is the only thread."""
    import subprocess
    import sys

    pytest.importorskip("pxr", reason="needs pip install 'photo3d[usdz]'")
    out = tmp_path / "out"
    if how == "export":
        photo.save(out, viewer=False, ply=None)
    run = subprocess.run([sys.executable, "-c", IMPORTS, how, str(out)], check=True,
                         capture_output=True, text=True, timeout=300)
    seen = json.loads(run.stdout.splitlines()[-1])
    assert {"pxr.Tf._tf", "pxr.Usd._usd"} <= {name for name, _, _ in seen}
    assert all(main and threads == 1 for _, main, threads in seen), seen
    assert (out / "mesh.usdz").is_file()
