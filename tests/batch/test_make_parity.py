"""Every option of ``photo3d make`` works in ``photo3d batch`` and reaches its output.

The options are enumerated from the parsers (argparse actions), so a new ``make``
option fails here until batch takes it too, or it is listed in ``NOT_BATCH`` with
the reason.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
from conftest import two_planes

from photo3d.cli import build_parser, main
from photo3d.cli.options import make_options
from photo3d.io.images import write_image
from photo3d.io.npz import load_npz

NOT_BATCH = {
    "image": "the photo: batch takes IN_DIR, a folder of photos",
    "depth": "the photo's depth map: batch's --depth is a folder of maps named like the "
             "photos (checked end to end below)",
    "right": "a stereo pair is one photo's; batch takes depth maps by name",
    "out": "the output folder: batch writes one folder per photo under it",
    "quiet": "what is printed, not what is made",
    "threads": "how many threads make it, not what is made (every command takes it; the "
               "LDI does not depend on it: tests/test_parallel.py)",
    "help": "argparse's help",
}
"""``make`` options that are not ``MakeOptions`` (``dest`` -> why)."""

VALUES = {
    "size": ["64"], "inpainter": ["diffusion"], "depth_model": ["some/model"],
    "paths": ["circle"], "video_size": ["32x24"], "fps": ["10"], "frames": ["3"],
    "ssaa": ["1"], "eye_separation": ["0.02"], "weights": ["{weights}"],
}
"""A non-default value for each option that is neither a flag nor a choice."""

COMPANIONS = {"weights": ["--inpainter", "learned"], "fast_nets": ["--inpainter", "learned"]}
"""Options an option needs beside it (compared with a run that has only these)."""


def subcommands() -> tuple[argparse.ArgumentParser, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices["make"], sub.choices["batch"]


def option_argv(action: argparse.Action, weights: Path) -> list[str]:
    """``[--option, value]`` giving ``action`` a value other than its default."""
    flag = action.option_strings[-1]
    if action.nargs == 0:  # store_true
        return [flag]
    if action.choices:
        return [flag, next(str(c) for c in action.choices if c != action.default)]
    assert action.dest in VALUES, f"give {flag} a test value in VALUES"
    return [flag, *(v.format(weights=weights) for v in VALUES[action.dest])]


def test_every_make_option_is_a_batch_option_and_reaches_make_options(tmp_path, monkeypatch):
    # learned without --weights means the authors' weights: a folder here, not a download
    monkeypatch.setattr("photo3d.nets.authors.authors_weights",
                        lambda **_: tmp_path / "authors")
    make, batch = subcommands()
    weights = tmp_path / "weights"
    weights.mkdir()
    dests = {a.dest for a in make._actions}
    assert set(NOT_BATCH) <= dests, "NOT_BATCH lists options make no longer has"
    checked = []
    for action in make._actions:
        for flag in action.option_strings:
            assert flag in batch._option_string_actions or action.dest in NOT_BATCH, (
                f"make {flag} is not a batch option")
        if action.dest in NOT_BATCH:
            continue
        extra = COMPANIONS.get(action.dest, [])
        argv = [*extra, *option_argv(action, weights)]
        made = make_options(make.parse_args(["photo.png", "-o", "o", *argv]))
        batched = make_options(batch.parse_args(["photos", "-o", "o", *argv]))
        plain = make_options(make.parse_args(["photo.png", "-o", "o", *extra]))
        assert made == batched, f"{argv}: make and batch read it differently"
        assert made != plain, f"{argv} does not change MakeOptions: batch would ignore it"
        checked.append(action.dest)
    assert {"full_glb", "ply", "weights", "fast_nets", "stereo", "depth_kind",
            "exports"} <= set(checked)


@pytest.fixture
def photos(tmp_path):
    """``photos/a.png``, ``depth/a.npy`` and ``plain/b.png`` (no depth)."""
    for name in ("photos", "depth", "plain"):
        (tmp_path / name).mkdir()
    img, d = two_planes(48, 64, 24)
    write_image(tmp_path / "photos" / "a.png", img)
    np.save(tmp_path / "depth" / "a.npy", d)
    return tmp_path


def make_and_batch(root: Path, options: list[str], name: str) -> tuple[Path, Path]:
    """Run make on ``a.png`` and batch on its folder with the same options."""
    made, batched = root / f"made-{name}", root / f"batched-{name}"
    assert main(["make", str(root / "photos" / "a.png"), "--depth",
                 str(root / "depth" / "a.npy"), "-o", str(made), *options, "-q"]) == 0
    assert main(["batch", str(root / "photos"), "--depth", str(root / "depth"), "-o",
                 str(batched), "--workers", "1", *options, "-q"]) == 0
    return made, batched / "a"


def same_output(made: Path, batched: Path) -> dict:
    """Both folders hold the same files, LDI and recorded options; returns the record."""
    assert sorted(p.relative_to(made).as_posix() for p in made.rglob("*")) == sorted(
        p.relative_to(batched).as_posix() for p in batched.rglob("*"))
    meta = [json.loads((f / "config.json").read_text()) for f in (made, batched)]
    for key in ("config", "inpainter", "depth_source", "save", "stats"):
        assert meta[0][key] == meta[1][key], key
    ldi = [load_npz(f / "photo3d.npz")[0] for f in (made, batched)]
    np.testing.assert_array_equal(ldi[0].color, ldi[1].color)
    np.testing.assert_array_equal(ldi[0].links, ldi[1].links)
    return meta[0]


def test_batch_makes_what_make_makes_with_every_output_option(photos):
    from photo3d.io.gltf import read_glb

    options = ["--size", "64", "--inpainter", "structured", "--ply", "ascii", "--full-glb",
               "--no-viewer", "--path", "circle", "--frames", "2", "--fps", "10",
               "--video-size", "32x24", "--format", "gif", "--ssaa", "1", "--no-crop",
               "--backend", "numba", "--stereo", "sbs", "--eye-separation", "0.02",
               "--eye-order", "rl", "--depth-kind", "depth", "--overwrite",
               "--export", "splats.spz", "--export", "splats.ply"]
    made, batched = make_and_batch(photos, options, "all")
    meta = same_output(made, batched)
    assert meta["save"]["exports"] == ["splats.spz", "splats.ply"]
    assert {"splats.spz", "splats.ply"} <= set(meta["written"])
    assert (batched / "splats.ply").read_bytes() == (made / "splats.ply").read_bytes()
    assert (batched / "video" / "circle_RLF_cross.gif").is_file()  # --eye-order rl
    assert (batched / "mesh.ply").read_bytes().startswith(b"ply\nformat ascii 1.0\n")
    full = read_glb(batched / "mesh.glb")  # --full-glb: every LDI pixel a vertex
    assert len(full.vertices) == load_npz(batched / "photo3d.npz")[0].size
    assert meta["config"]["size"] == 64 and meta["config"]["depth_kind"] == "depth"
    assert meta["inpainter"]["name"] == "structured"
    assert meta["depth_source"].endswith("a.npy (depth)")
    video = meta["save"]["videos"][0]
    assert (video["fps"], video["frames"], video["format"], video["stereo"]) == (
        10, 2, "gif", "sbs")
    assert (video["eye_separation"], video["eye_order"], video["size"]) == (0.02, "rl", [32, 24])
    settings = meta["save"]["render_settings"]
    assert (settings["ssaa"], settings["crop"], settings["backend"]) == (1, [0, 0, 0, 0],
                                                                         "numba")
    assert (meta["save"]["glb"], meta["save"]["ply"], meta["save"]["viewer"]) == (
        "full", "ascii", False)


def test_batch_passes_the_learned_inpainter_options_as_make_does(photos):
    torch = pytest.importorskip("torch")
    from photo3d.nets import build_net, save_safetensors

    weights = photos / "weights"
    weights.mkdir()
    torch.manual_seed(0)
    for kind, cfg in {"edge": dict(width=0.125, blocks=1), "depth": dict(levels=3, width=0.125),
                      "color": dict(levels=3, width=0.125)}.items():
        save_safetensors(build_net(kind, **cfg), weights / f"{kind}.safetensors")
    options = ["--size", "64", "--no-video", "--no-glb", "--inpainter", "learned",
               "--weights", str(weights), "--fast-nets"]
    meta = same_output(*make_and_batch(photos, options, "learned"))
    learned = meta["inpainter"]
    assert learned["weights"] == str(weights.resolve()) and len(learned["sha256"]) == 3
    assert learned["precision"] == "bf16" and learned["units"]["edge"] == 8
