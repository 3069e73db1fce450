import subprocess
import sys

import numpy as np
import pytest
from conftest import two_planes
from PIL import Image

from photo3d.cli import main


@pytest.fixture
def files(tmp_path):
    img, d = two_planes(48, 64, 32)
    Image.fromarray((img * 255).astype(np.uint8)).save(tmp_path / "photo.png")
    Image.fromarray((d * 100).astype(np.uint16)).save(tmp_path / "depth.png")
    return tmp_path


def test_make_writes_a_3d_photo_the_four_videos_and_a_timing_summary(files, capsys):
    from videoprobe import frame_count, probe

    out = files / "out"
    code = main(["make", str(files / "photo.png"), "--depth", str(files / "depth.png"),
                 "-o", str(out), "--size", "128", "--frames", "6", "--video-size", "64x48"])
    assert code == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "config.json", "mesh.glb", "mesh.ply", "photo3d.npz", "video", "viewer.html"]
    videos = sorted(p.name for p in (out / "video").iterdir())
    assert videos == ["circle.mp4", "dolly-zoom-in.mp4", "swing.mp4", "zoom-in.mp4"]
    info = probe(out / "video" / "circle.mp4")
    assert info["codec"] == "h264" and info["size"] == (64, 48) and info["fps"] == 40
    assert info["pix_fmt"].startswith("yuv420p")
    assert frame_count(out / "video" / "circle.mp4") == 6
    text = capsys.readouterr().out
    assert "3D photo written to" in text and "time:" in text and "inpaint" in text


def test_render_reuses_a_saved_photo(files, capsys):
    from videoprobe import frame_count, probe

    out = files / "out"
    assert main(["make", str(files / "photo.png"), "--depth", str(files / "depth.png"),
                 "-o", str(out), "--size", "96", "--no-video", "-q"]) == 0
    assert not (out / "video").exists()
    args = ["render", str(out), "--path", "swing", "--video-size", "32x24", "--frames", "5",
            "--fps", "10"]
    assert main(args) == 0
    assert probe(out / "video" / "swing.mp4")["size"] == (32, 24)
    assert frame_count(out / "video" / "swing.mp4") == 5
    assert main(args + ["--stereo", "sbs", "--format", "webm"]) == 0
    info = probe(out / "video" / "swing_LRF_Full_SBS.webm")
    assert info["codec"] == "vp9" and info["size"] == (64, 24)
    assert main(args + ["--stereo", "anaglyph", "--format", "gif"]) == 0
    assert frame_count(out / "video" / "swing_anaglyph.gif") == 5
    keys = files / "path.json"
    keys.write_text('[{"position": [0, 0, 0]}, {"position": [0.01, 0, 0]}]')
    assert main(["render", str(out), "--path", str(keys), "--frames", "3", "-q"]) == 0
    assert frame_count(out / "video" / "path.mp4") == 3
    assert "rendered 1 video(s)" in capsys.readouterr().out
    assert main(["render", str(out), "--still", "--stereo", "anaglyph", "--size", "40x30"]) == 0
    from PIL import Image

    with Image.open(out / "still_anaglyph.png") as still:
        assert still.size == (40, 30)


def test_render_errors_are_one_line(files, capsys):
    assert main(["render", str(files / "nothing"), "--path", "circle"]) == 2
    assert capsys.readouterr().err.startswith("photo3d: error: no 3D photo at")
    assert main(["render", str(files), "--path", "spiral"]) == 2
    assert "photo3d: error:" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["make", "{d}/nope.jpg", "--depth", "{d}/depth.png", "-o", "{d}/o"], "not found"),
        (["make", "{d}/photo.png", "--depth", "{d}/nope.png", "-o", "{d}/o"], "not found"),
        (["make", "{d}/photo.png", "--depth", "{d}/photo.png", "-o", "{d}/o"], "depth"),
        (["make", "{d}/photo.png", "--depth", "{d}/depth.png", "-o", "{d}"], "holds the input"),
        (["make", "{d}/photo.png", "--depth", "{d}/depth.png", "-o", "{d}/o",
          "--inpainter", "magic"], "unknown inpainter"),
        (["make", "{d}/photo.png", "--depth", "{d}/depth.png", "-o", "{d}/o",
          "--video-size", "65x48"], "even"),
    ],
)
def test_user_mistakes_give_one_line_and_status_2(files, capsys, args, message):
    argv = [a.format(d=files) for a in args]
    before = sorted(p.name for p in files.iterdir())
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("photo3d: error:") and message in err[0]
    assert sorted(p.name for p in files.iterdir()) == before  # nothing half-written


def test_console_script_runs_without_traceback(files):
    proc = subprocess.run(
        [sys.executable, "-m", "photo3d", "make", str(files / "missing.png"), "--depth",
         str(files / "depth.png"), "-o", str(files / "o")],
        capture_output=True, text=True, check=False,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and "image file not found" in proc.stderr


def test_depth_command_and_make_from_a_stereo_pair(tmp_path, capsys, monkeypatch):
    pytest.importorskip("cv2")
    from photo3d.eval.synthetic import synthetic_pair

    pair = synthetic_pair(2, width=320, height=240)
    for name, img in (("left.png", pair.left), ("right.png", pair.right)):
        Image.fromarray(np.round(img * 255).astype(np.uint8)).save(tmp_path / name)
    assert main(["depth", str(tmp_path / "left.png"), "--right", str(tmp_path / "right.png"),
                 "-o", str(tmp_path / "d.png")]) == 0
    with Image.open(tmp_path / "d.png") as d:
        assert d.size == (320, 240) and d.mode.startswith("I")
        disp = np.asarray(d, np.float64)
    assert (tmp_path / "d_preview.png").is_file()
    # near planes are brighter than the back plane
    truth = pair.disparity
    assert np.corrcoef(disp.ravel(), truth.ravel())[0, 1] > 0.8
    out = tmp_path / "o"
    assert main(["make", str(tmp_path / "left.png"), "--right", str(tmp_path / "right.png"),
                 "-o", str(out), "--no-video", "--size", "160", "-q"]) == 0
    assert (out / "photo3d.npz").is_file()
    capsys.readouterr()
    monkeypatch.setenv("PHOTO3D_DEPTH_MODEL", str(tmp_path / "no-such-model.onnx"))
    assert main(["make", str(tmp_path / "left.png"), "-o", str(tmp_path / "o2")]) == 2
    err = capsys.readouterr().err
    assert "no depth for left.png" in err and "--depth FILE, --right IMAGE" in err
    assert not (tmp_path / "o2").exists()


def test_view_serves_the_viewer_on_localhost(files):
    import signal
    import urllib.request

    out = files / "out"
    assert main(["make", str(files / "photo.png"), "--depth", str(files / "depth.png"),
                 "-o", str(out), "--size", "64", "--no-video", "--no-viewer", "-q"]) == 0
    assert not (out / "viewer.html").exists()
    # default SIGINT in the child even if we were started with it ignored (a background
    # job of a non-interactive shell): Python then turns it into KeyboardInterrupt
    proc = subprocess.Popen([sys.executable, "-m", "photo3d", "view", str(out), "--no-browser"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        line = proc.stdout.readline()
        url = line.split(" at ", 1)[1].split()[0]
        assert url.startswith("http://127.0.0.1:")
        with urllib.request.urlopen(url, timeout=10) as resp:
            assert b"<html" in resp.read(2000).lower()
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=10)
        proc.stdout.close()
        proc.stderr.close()
    assert proc.returncode == 130 and err == "photo3d: interrupted\n"  # as every command
    assert (out / "viewer.html").is_file()  # written on demand


def test_view_stops_on_sigterm_with_143_and_a_line(files):
    # issue 45: view exited 0, silently, on SIGTERM
    import signal

    out = files / "out"
    assert main(["make", str(files / "photo.png"), "--depth", str(files / "depth.png"),
                 "-o", str(out), "--size", "64", "--no-video", "-q"]) == 0
    proc = subprocess.Popen([sys.executable, "-m", "photo3d", "view", str(out), "--no-browser"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert " at http://127.0.0.1:" in proc.stdout.readline()
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=10)
        proc.stdout.close()
        proc.stderr.close()
    assert proc.returncode == 143 and err == "photo3d: interrupted (SIGTERM)\n"


def test_make_with_the_learned_inpainter_and_authors_format_weights(files, capsys):
    torch = pytest.importorskip("torch")
    from photo3d.eval.evaluate import random_nets

    weights = files / "weights"
    weights.mkdir()
    nets = random_nets(seed=1)
    for kind in ("edge", "depth", "color"):
        torch.save(getattr(nets, kind).state_dict(), weights / f"{kind}-model.pth")
    out = files / "learned"
    assert main(["make", str(files / "photo.png"), "--depth", str(files / "depth.png"),
                 "-o", str(out), "--size", "96", "--no-video", "--no-viewer",
                 "--inpainter", "learned", "--weights", str(weights), "-q"]) == 0
    import json

    meta = json.loads((out / "config.json").read_text())
    assert meta["config"]["inpainter"] == "learned"
    assert meta["stats"]["pixels_added"][0] > 0


def test_fast_nets_reach_the_learned_backend(files, monkeypatch):
    pytest.importorskip("torch")
    from photo3d.inpaint import learned
    from photo3d.nets import build_net, save_safetensors

    weights = files / "small"
    weights.mkdir()
    small = {"edge": dict(width=0.125, blocks=1), "depth": dict(levels=3, width=0.125),
             "color": dict(levels=3, width=0.125)}
    for kind, cfg in small.items():
        save_safetensors(build_net(kind, **cfg), weights / f"{kind}.safetensors")
    seen = {}
    original = learned.LearnedInpainter.__init__

    def spy(self, **kw):
        seen.update(kw)
        original(self, **kw)

    monkeypatch.setattr(learned.LearnedInpainter, "__init__", spy)
    assert main(["make", str(files / "photo.png"), "--depth", str(files / "depth.png"),
                 "-o", str(files / "fast"), "--size", "96", "--no-video", "--no-viewer",
                 "--inpainter", "learned", "--weights", str(weights), "--fast-nets",
                 "-q"]) == 0
    assert seen["edge_unit"] == 8 and seen["precision"] == "bf16"


def test_learned_only_flags_are_refused_for_diffusion(files, capsys):
    code = main(["make", str(files / "photo.png"), "--depth", str(files / "depth.png"),
                 "-o", str(files / "nope"), "--fast-nets", "-q"])
    err = capsys.readouterr().err
    assert code == 2 and "--fast-nets only apply to --inpainter learned" in err
    assert not (files / "nope").exists()


def test_mesh_glb_is_light_and_textured_unless_full_glb(files):
    from photo3d.io.gltf import read_glb
    from photo3d.io.gltf_textured import read_textured_glb
    from photo3d.io.npz import load_npz

    base = ["make", str(files / "photo.png"), "--depth", str(files / "depth.png"), "--size",
            "96", "--no-video", "-q"]
    assert main(base + ["-o", str(files / "light")]) == 0
    assert main(base + ["-o", str(files / "full"), "--full-glb"]) == 0
    light = read_textured_glb(files / "light" / "mesh.glb")
    full = read_glb(files / "full" / "mesh.glb")
    ldi, _ = load_npz(files / "full" / "photo3d.npz")
    assert len(full.vertices) == ldi.size  # one vertex per LDI pixel
    assert len(light.faces) < len(full.faces) / 4 and light.texture.ndim == 3
    with pytest.raises(Exception, match="TEXCOORD_0|textured"):
        read_textured_glb(files / "full" / "mesh.glb")


def test_make_says_where_the_depth_came_from_and_records_it(files, capsys):
    import json

    out = files / "out"
    assert main(["make", str(files / "photo.png"), "--depth", str(files / "depth.png"),
                 "--depth-kind", "depth", "-o", str(out), "--size", "64", "--no-video",
                 "--no-viewer"]) == 0
    source = f"depth file {files / 'depth.png'} (depth)"
    assert f"depth: {source}\n" in capsys.readouterr().err
    meta = json.loads((out / "config.json").read_text())
    assert meta["depth_source"] == source and meta["config"]["depth_kind"] == "depth"
    assert meta["save"]["viewer"] is False and meta["save"]["videos"] == []
    assert meta["inpainter"]["name"] == "structured"  # the default


@pytest.mark.parametrize("command", ["make", "batch"])
def test_edges_option_reaches_the_config_of_make_and_batch(files, command):
    """``--edges exact`` turns the alignment off and is recorded; the default aligns
    and gives the silhouettes a coverage."""
    import argparse
    import json

    from photo3d.cli.options import add_make_options, config_from

    p = argparse.ArgumentParser()
    add_make_options(p, out_required=False)
    assert config_from(p.parse_args([])).edges == "soft"
    assert config_from(p.parse_args(["--edges", "exact"])).edges == "exact"
    if command == "make":
        args = ["make", str(files / "photo.png"), "--depth", str(files / "depth.png"),
                "-o", str(files / "out")]
        written = files / "out"
    else:
        (files / "in").mkdir()
        (files / "maps").mkdir()
        (files / "photo.png").rename(files / "in" / "photo.png")
        (files / "depth.png").rename(files / "maps" / "photo.png")
        args = ["batch", str(files / "in"), "--depth", str(files / "maps"),
                "-o", str(files / "outs")]
        written = files / "outs" / "photo"
    assert main([*args, "--size", "64", "--no-video", "--no-viewer", "--no-glb",
                 "--edges", "exact", "-q"]) == 0
    assert json.loads((written / "config.json").read_text())["config"]["edges"] == "exact"
