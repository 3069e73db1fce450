"""Side-by-side videos are named so headset players recognise them (issue 37 item 7):
``_LRF_Full_SBS`` for full-width left-right, ``_RLF_cross`` for cross-eyed; the names
are recorded in ``config.json``, and folders whose stereo videos have the old names
(``circle_sbs.mp4``) still render and stay photo3d's."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from renderkit import small_photo

from photo3d.cli import main
from photo3d.owned import owned_photo, recorded_files
from photo3d.render.animate import VideoSpec

TINY = ["--frames", "2", "--fps", "10", "--video-size", "32x24", "--backend", "numba",
        "--ssaa", "1", "-q"]


@pytest.mark.parametrize("stereo, order, name", [
    (None, "lr", "circle"), ("sbs", "lr", "circle_LRF_Full_SBS"),
    ("sbs", "rl", "circle_RLF_cross"), ("sbs-half", "lr", "circle_sbs-half"),
    ("anaglyph", "rl", "circle_anaglyph")])
def test_video_names(stereo, order, name):
    assert VideoSpec(stereo=stereo, eye_order=order).name == name


@pytest.fixture(scope="module")
def made(tmp_path_factory) -> Path:
    """A small 3D photo folder without videos (made once)."""
    return small_photo(tmp_path_factory.mktemp("made"))


@pytest.fixture
def photo(tmp_path, made) -> Path:
    shutil.copytree(made, tmp_path / "photo")
    return tmp_path / "photo"


def test_render_sbs_writes_and_records_the_player_name(photo):
    assert main(["render", str(photo), "--path", "circle", "--stereo", "sbs", *TINY]) == 0
    assert sorted(p.name for p in (photo / "video").iterdir()) == ["circle_LRF_Full_SBS.mp4"]
    assert recorded_files(photo) == {"video/circle_LRF_Full_SBS.mp4"}
    assert owned_photo(photo) == []  # so make --overwrite may replace the folder


def test_make_records_the_player_name(tmp_path, made):
    src = made.parent
    out = tmp_path / "out"
    assert main(["make", str(src / "a.png"), "--depth", str(src / "a.npy"), "-o", str(out),
                 "--size", "48", "--no-glb", "--no-viewer", "--path", "swing", "--stereo",
                 "sbs", *TINY]) == 0
    written = json.loads((out / "config.json").read_text())["written"]
    assert written == ["video/swing_LRF_Full_SBS.mp4"]
    assert (out / "video" / "swing_LRF_Full_SBS.mp4").is_file()


@pytest.mark.parametrize("record", ["written", "save.videos"])
def test_a_folder_with_old_stereo_names_still_works(photo, record):
    """An old ``circle_sbs.mp4`` (listed under ``written``, or only in ``save.videos``
    by folders older than that list) stays photo3d's, is left alone by a new render,
    and the folder may still be replaced."""
    meta = json.loads((photo / "config.json").read_text())
    if record == "written":
        meta["written"] = ["video/circle_sbs.mp4"]
    else:
        del meta["written"]
        meta["save"]["videos"] = [{"path": "circle", "format": "mp4", "stereo": "sbs"}]
    (photo / "config.json").write_text(json.dumps(meta))
    (photo / "video").mkdir()
    (photo / "video" / "circle_sbs.mp4").write_bytes(b"an old photo3d video")
    assert owned_photo(photo) == []

    assert main(["render", str(photo), "--path", "circle", "--stereo", "sbs", *TINY]) == 0
    assert (photo / "video" / "circle_sbs.mp4").read_bytes() == b"an old photo3d video"
    assert recorded_files(photo) == {"video/circle_sbs.mp4", "video/circle_LRF_Full_SBS.mp4"}
    assert owned_photo(photo) == []


def test_a_users_file_with_the_new_name_is_not_replaced(photo, capsys):
    (photo / "video").mkdir()
    (photo / "video" / "circle_LRF_Full_SBS.mp4").write_bytes(b"the user's own video")
    assert main(["render", str(photo), "--path", "circle", "--stereo", "sbs", *TINY]) == 2
    assert "photo3d did not write it" in capsys.readouterr().err
    assert (photo / "video" / "circle_LRF_Full_SBS.mp4").read_bytes() == b"the user's own video"
