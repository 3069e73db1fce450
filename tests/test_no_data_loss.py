"""No command deletes or rewrites a file it did not write: it refuses in one line (exit 2)
before any work, and every file that was there is unchanged (``photo3d train``: see
tests/train/test_train_no_data_loss.py)."""

from __future__ import annotations

import os

import numpy as np
import pytest
import test_robustness
from PIL import Image
from test_robustness import make, run, snapshot

from photo3d.cli import main
from photo3d.files.staging import owned_by_names
from photo3d.io.video import video_formats
from photo3d.owned import VIDEO_FILES, owned_photo

photos = test_robustness.photos  # the fixture: tmp/photos/{a.png, a.npy, notes.txt}

# --- make --overwrite: video/ is checked too ---------------------------------------------


def test_video_patterns_cover_every_format_photo3d_writes():
    assert sorted(p.removeprefix("*") for p in VIDEO_FILES) == sorted(video_formats())


@pytest.mark.parametrize(("entry", "named"), [
    ("video/holiday.mov", "video/holiday.mov"), ("video/notes.txt", "video/notes.txt"),
    ("video/mine/a.mp4", "video/mine"), ("mesh.ply/a.txt", "mesh.ply")])
def test_make_overwrite_never_deletes_a_users_file_in_the_folder(photos, capsys, entry, named):
    out = photos.parent / "out"
    run(capsys, *make(photos, "out"), status=0)
    if entry.startswith("mesh.ply/"):  # a folder with the name of a file photo3d writes
        (out / "mesh.ply").unlink()
    (out / entry).parent.mkdir(parents=True, exist_ok=True)
    (out / entry).write_text("the user's")
    run(capsys, *make(photos, "out", "--overwrite"), status=2, message=f"holds {named}")


def test_make_overwrite_replaces_the_videos_photo3d_wrote(photos, capsys):
    """Videos made by `make` and added by `render` are listed in config.json and replaced;
    a video the user put beside them is not photo3d's, whatever its name."""
    out = photos.parent / "out"
    video = ["--frames", "2", "--video-size", "32x24", "--ssaa", "1", "--format", "gif"]
    argv = [a for a in make(photos, "out", "--path", "circle", *video) if a != "--no-video"]
    run(capsys, *argv, status=0)
    run(capsys, "render", out, "--path", "swing", *video, "-q", status=0)
    assert sorted(p.name for p in (out / "video").iterdir()) == ["circle.gif", "swing.gif"]
    run(capsys, *make(photos, "out", "--overwrite"), status=0)
    assert not (out / "video").exists()  # this run wrote no video (--no-video)
    run(capsys, *argv, "--overwrite", status=0)
    (out / "video" / "holiday.mp4").write_bytes(b"the user's own video")
    (out / "still.png").write_bytes(b"the user's own still")
    run(capsys, *make(photos, "out", "--overwrite"), status=2,
        message="holds still.png, video/holiday.mp4, which photo3d did not write")


def test_render_never_replaces_a_video_or_still_photo3d_did_not_write(photos, capsys):
    out = photos.parent / "out"
    run(capsys, *make(photos, "out"), status=0)
    (out / "video").mkdir()
    (out / "video" / "circle.gif").write_bytes(b"the user's own video")
    (out / "still.png").write_bytes(b"the user's own still")
    video = ["--frames", "2", "--video-size", "32x24", "--ssaa", "1", "--format", "gif", "-q"]
    run(capsys, "render", out, "--path", "circle", *video, status=2,
        message="circle.gif exists and photo3d did not write it")
    run(capsys, "render", out, "--still", "-q", status=2,
        message="still.png exists and photo3d did not write it")
    (out / "still.png").unlink()
    run(capsys, "render", out, "--still", "-q", status=0)
    run(capsys, "render", out, "--still", "-q", status=0)  # its own still: replaced


def test_owned_by_names_looks_inside_subfolders(tmp_path):
    owned = owned_by_names("a.npz", ["a.npz", "video"], inside={"video": ["*.mp4"]})
    (tmp_path / "a.npz").write_bytes(b"")
    (tmp_path / "video").mkdir()
    assert owned(tmp_path) == []
    (tmp_path / "video" / "x.mp4").write_bytes(b"")
    assert owned(tmp_path) == []
    os.symlink(tmp_path / "a.npz", tmp_path / "video" / "y.mp4")
    (tmp_path / "video" / "z.txt").write_bytes(b"")
    assert owned(tmp_path) == ["holds video/y.mp4, video/z.txt"]
    assert owned_photo(tmp_path) == ["holds a.npz, video/y.mp4, video/z.txt",
                                     "has no photo3d.npz"]
    for name in ("a.npz", "video/y.mp4", "video/z.txt"):
        (tmp_path / name).unlink()
    (tmp_path / "photo3d.npz").write_bytes(b"")
    assert owned_photo(tmp_path) == ["holds video/x.mp4, which photo3d did not write"]
    (tmp_path / "config.json").write_text('{"save": {"videos": [{"path": "x", "format": "mp4"}]}}')
    assert owned_photo(tmp_path) == []  # saved before config.json listed what it wrote


# --- depth: the output is never one of the inputs ----------------------------------------


@pytest.fixture
def no_depth(monkeypatch):
    """Fail the test if the depth is resolved (the output is checked first)."""
    def refuse(*args, **kwargs):
        raise AssertionError("the depth was resolved before the output was checked")

    monkeypatch.setattr("photo3d.cli.depth.depth_from_args", refuse)


def test_depth_never_replaces_an_input(photos, capsys, no_depth):
    disp = np.load(photos / "a.npy")
    Image.fromarray((disp * 1000).astype(np.uint16)).save(photos / "d.png")
    Image.open(photos / "a.png").save(photos / "b_preview.png")
    os.symlink("a.png", photos / "link.png")
    os.link(photos / "d.png", photos / "hard.png")
    cases = [("a.png", "a.npy", "a.png"),  # onto the photo
             ("a.png", "d.png", "d.png"),  # onto the depth map
             ("b_preview.png", "a.npy", "b.png"),  # the preview onto the photo
             ("a.png", "d.png", "link.png"),  # through a symbolic link
             ("a.png", "d.png", "hard.png"),  # through a hard link
             ("link.png", "a.npy", "a.png")]
    for image, depth, out in cases:
        run(capsys, "depth", photos / image, "--depth", photos / depth, "-o", photos / out,
            status=2, message="is the input", root=photos)


def test_depth_writes_a_new_file_beside_the_inputs(photos, capsys):
    run(capsys, "depth", photos / "a.png", "--depth", photos / "a.npy", "-o",
        photos / "a_depth.png", status=0, root=photos)
    assert (photos / "a_depth.png").is_file() and (photos / "a_depth_preview.png").is_file()


def test_depth_replaces_an_existing_output_only_with_overwrite(photos, capsys, tmp_path):
    """An existing OUT.png or OUT_preview.png is refused before the work without
    --overwrite; never written through a symbolic link, even with it."""
    (photos / "mine.png").write_bytes(b"my picture")
    (photos / "other_preview.png").write_bytes(b"my preview")
    outside = tmp_path / "outside.png"
    outside.write_bytes(b"outside")
    os.symlink(outside, photos / "linked.png")
    os.symlink(tmp_path / "nowhere.png", photos / "dangling.png")
    for out in ("mine.png", "other.png", "linked.png", "dangling.png"):
        run(capsys, "depth", photos / "a.png", "--depth", photos / "a.npy", "-o",
            photos / out, status=2, message="exists; pass --overwrite", root=tmp_path)
    for out in ("linked.png", "dangling.png"):
        run(capsys, "depth", photos / "a.png", "--depth", photos / "a.npy", "-o",
            photos / out, "--overwrite", status=2, message="symbolic link", root=tmp_path)
    run(capsys, "depth", photos / "a.png", "--depth", photos / "a.npy", "-o",
        photos / "mine.png", "--overwrite", status=0, root=photos)
    assert (photos / "mine.png").read_bytes()[:4] == b"\x89PNG"
    assert outside.read_bytes() == b"outside" and not (tmp_path / "nowhere.png").exists()


# --- eval -o: an existing folder needs --overwrite; only eval's files are replaced -------

EVAL = ["eval", "--synthetic", "1", "--methods", "forward-warp", "--no-lpips", "-q"]


@pytest.fixture
def no_eval(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("evaluated before the output was checked")

    monkeypatch.setattr("photo3d.eval.report.evaluate", refuse)


def test_eval_refuses_an_existing_folder(tmp_path, capsys, monkeypatch, no_eval):
    monkeypatch.chdir(tmp_path)
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "results.md").write_text("my results")
    (mine / "results.json").write_text('{"mine": true}')
    run(capsys, *EVAL, "-o", "mine", status=2, message="not empty (use --overwrite")
    run(capsys, *EVAL, "-o", "mine", "--overwrite", status=2,
        message="only replaces results photo3d eval wrote")
    (mine / "results.json").unlink()
    run(capsys, *EVAL, "-o", "mine", "--overwrite", status=2,
        message="only replaces results photo3d eval wrote")


def test_eval_overwrite_replaces_only_its_files(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    run(capsys, *EVAL, "-o", "ev", status=0)
    ev = tmp_path / "ev"
    assert sorted(os.listdir(ev)) == ["grid_synthetic0.png", "results.json", "results.md"]
    (ev / "notes.txt").write_text("my notes")
    (ev / "grid_old.png").write_bytes(b"an older grid")
    run(capsys, *EVAL, "-o", "ev", status=2, message="use --overwrite")
    old = {n: (ev / n).stat().st_ino for n in ("results.json", "results.md")}
    run(capsys, *EVAL, "-o", "ev", "--overwrite", status=0)
    assert (ev / "notes.txt").read_text() == "my notes"
    assert (ev / "grid_old.png").read_bytes() == b"an older grid"
    assert all((ev / n).stat().st_ino != i for n, i in old.items())  # replaced
    loud = [a for a in EVAL if a != "-q"]
    assert main([*loud, "-o", "ev", "--overwrite"]) == 0
    assert "left as they were: grid_old.png, notes.txt" in capsys.readouterr().out


def test_eval_into_an_empty_folder(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "empty").mkdir()
    before = snapshot(tmp_path)
    assert main([*EVAL, "-o", "empty"]) == 0, capsys.readouterr().err
    assert snapshot(tmp_path).keys() - before.keys() == {
        "empty/grid_synthetic0.png", "empty/results.json", "empty/results.md"}
