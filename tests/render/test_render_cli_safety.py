"""``photo3d render`` never writes through a symbolic link placed in the photo folder.

Each case makes a link (to a file or folder outside the folder, to nothing, or to a
file inside), runs ``photo3d render`` and checks exit status 2, one line on stderr,
that nothing was rendered and that nothing under the temporary root changed.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import two_planes
from filetree import tree
from PIL import Image

from photo3d.cli import main

LINK_MESSAGE = "is a symbolic link; photo3d does not write through links"


@pytest.fixture(scope="module")
def made(tmp_path_factory) -> Path:
    """A small 3D photo folder without videos (made once)."""
    root = tmp_path_factory.mktemp("made")
    img, disparity = two_planes(48, 64, 32)
    Image.fromarray((img * 255).astype(np.uint8)).save(root / "a.png")
    np.save(root / "a.npy", disparity)
    out = root / "out"
    assert main(["make", str(root / "a.png"), "--depth", str(root / "a.npy"), "-o", str(out),
                 "--size", "48", "--no-video", "--no-glb", "--no-viewer", "-q"]) == 0
    return out


@pytest.fixture
def root(tmp_path, made, monkeypatch) -> Path:
    """``tmp/photo`` (a copy of ``made``) beside ``tmp/outside/`` (``theirs.png``,
    ``circle.mp4``); rendering raises, so a case that gets that far fails."""
    shutil.copytree(made, tmp_path / "photo")
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside" / "theirs.png").write_bytes(b"their image")
    (tmp_path / "outside" / "circle.mp4").write_bytes(b"their video")

    def refuse(*args, **kwargs):
        raise AssertionError("rendered before the output was checked")

    monkeypatch.setattr("photo3d.render.animate.render_still", refuse)
    monkeypatch.setattr("photo3d.render.animate.render_video", refuse)
    monkeypatch.setattr("photo3d.render.renderer.Renderer", refuse)
    return tmp_path


def refused(root: Path, argv: list[str], capsys, link: Path) -> None:
    before = tree(root)
    assert main(["render", str(root / "photo"), "-q", *argv]) == 2
    err = capsys.readouterr().err
    assert err == f"photo3d: error: {link} {LINK_MESSAGE}\n"
    assert tree(root) == before


@pytest.mark.parametrize("name, argv", [("still.png", ["--still"]),
                                        ("still_sbs.png", ["--still", "--stereo", "sbs"])])
@pytest.mark.parametrize("points_to", ["outside/theirs.png", "outside/missing.png",
                                       "photo/config.json"])
def test_a_linked_still_is_refused_before_rendering(root, capsys, name, argv, points_to):
    link = root / "photo" / name
    link.symlink_to(root / points_to)
    refused(root, argv, capsys, link)


@pytest.mark.parametrize("points_to", ["outside", "missing", "photo"])
def test_a_linked_video_folder_is_refused_before_rendering(root, capsys, points_to):
    link = root / "photo" / "video"
    link.symlink_to(root / points_to, target_is_directory=True)
    refused(root, ["--path", "circle", "--format", "mp4"], capsys, link)


@pytest.mark.parametrize("points_to", ["outside/circle.mp4", "outside/missing.mp4"])
def test_a_linked_video_file_is_refused_before_rendering(root, capsys, points_to):
    (root / "photo" / "video").mkdir()
    (root / "photo" / "video" / "swing.mp4").write_bytes(b"old swing")
    link = root / "photo" / "video" / "circle.mp4"
    link.symlink_to(root / points_to)
    refused(root, ["--path", "swing", "--path", "circle", "--format", "mp4"], capsys, link)
