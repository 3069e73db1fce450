"""``photo3d render`` never writes through a symbolic link placed in the photo folder.

Each case makes a link (to a file or folder outside the folder, to nothing, or to a
file inside), runs ``photo3d render`` and checks exit status 2, one line on stderr,
that nothing was rendered and that nothing under the temporary root changed.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from filetree import tree
from renderkit import small_photo

from photo3d.cli import main

LINK_MESSAGE = "is a symbolic link; photo3d does not write through links"


@pytest.fixture(scope="module")
def made(tmp_path_factory) -> Path:
    """A small 3D photo folder without videos (made once)."""
    return small_photo(tmp_path_factory.mktemp("made"))


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


# --- issue 36: the encoder's limits, one message per bad keyframe file, no empty video/ ---

@pytest.mark.parametrize(("argv", "message"), [
    (["--size", "16386x2"], "a 16386x2 mp4 video is too large: its encoder takes at most 16384"),
    (["--size", "8194x2", "--stereo", "sbs"], "--stereo sbs doubles the width: a 16388x2 mp4"),
    (["--size", "16256x16256", "--format", "gif"], "FFmpeg's encoders take at most about"),
])
def test_a_video_its_encoder_cannot_open_is_refused_before_rendering(root, capsys, argv,
                                                                      message):
    before = tree(root)
    # before: libx264's avcodec_open2 traceback, after rendering
    assert main(["render", str(root / "photo"), "-q", "--frames", "2", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("photo3d: error: ") and err.count("\n") == 1 and message in err, err
    assert tree(root) == before


def test_bad_yaml_keyframes_are_said_once(root, capsys):
    pytest.importorskip("yaml")
    path = root / "outside" / "bad.yaml"
    path.write_text("keyframes: [1\n")
    assert main(["render", str(root / "photo"), "-q", "--path", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.count("cannot parse camera path") == 1, err


def test_a_failed_render_leaves_no_empty_video_folder(root, capsys, monkeypatch):
    from photo3d.errors import OutputError

    def fails(*args, **kwargs):
        raise OutputError("the renderer failed")

    monkeypatch.setattr("photo3d.render.renderer.Renderer", fails)
    before = tree(root)
    assert main(["render", str(root / "photo"), "-q", "--frames", "2"]) == 2
    assert capsys.readouterr().err == "photo3d: error: the renderer failed\n"
    assert tree(root) == before  # before: an empty photo/video/
    (root / "photo" / "video").mkdir()  # a folder that was there stays
    assert main(["render", str(root / "photo"), "-q", "--frames", "2"]) == 2
    assert (root / "photo" / "video").is_dir()


def test_make_refuses_a_video_its_encoder_cannot_open_before_the_work(made, tmp_path, capsys,
                                                                       monkeypatch):
    def no_work(*args, **kwargs):
        raise AssertionError("the work started before the video size was checked")

    monkeypatch.setattr("photo3d.folder.make_folder", no_work)
    source = made.parent
    argv = ["make", str(source / "a.png"), "--depth", str(source / "a.npy"), "-o",
            str(tmp_path / "out"), "--video-size", "16386x2", "-q"]
    assert main(argv) == 2  # before: the pipeline ran, then libx264's traceback
    assert capsys.readouterr().err == ("photo3d: error: a 16386x2 mp4 video is too large: its "
                                       "encoder takes at most 16384 pixels a side\n")
    assert not (tmp_path / "out").exists()
