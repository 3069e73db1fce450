"""Each backend's settings(): what changes its output, recorded in config.json."""

from __future__ import annotations

import hashlib
import json

import pytest

from photo3d.inpaint import get_inpainter
from photo3d.pipeline import inpainter_settings


def test_classical_backends_report_their_options():
    diffusion = get_inpainter("diffusion", iterations=50, tolerance=1e-2)
    assert diffusion.settings() == {"name": "diffusion", "iterations": 50, "tolerance": 1e-2}
    structured = get_inpainter("structured", texture=0.25, pm_iterations=5, coherence=0.5,
                               lines=False)
    s = structured.settings()
    assert (s["name"], s["texture"], s["pm_iterations"], s["coherence"], s["lines"]) == (
        "structured", 0.25, 5, 0.5, False)
    assert s["iterations"] == 300 and "workers" not in s
    assert get_inpainter("structured").settings() != s
    json.dumps(s)


def test_a_backend_without_settings_is_recorded_by_name():
    class Mine:
        name = "mine"
        margin = 1

    assert inpainter_settings(Mine()) == {"name": "mine"}


def test_learned_settings_name_the_weights_and_their_hashes(tmp_path):
    torch = pytest.importorskip("torch")
    from photo3d.inpaint.learned import LearnedInpainter, bundled_weights
    from photo3d.nets import InpaintingNets, build_net, save_safetensors

    def sha(path):
        return hashlib.sha256(path.read_bytes()).hexdigest()

    bundled = LearnedInpainter(weights=bundled_weights()).settings()
    assert bundled["weights"] == "bundled compact" and bundled["precision"] == "fp32"
    assert bundled["sha256"] == {p.name: sha(p)
                                 for p in sorted(bundled_weights().glob("*.safetensors"))}
    small = {"edge": dict(width=0.125, blocks=1), "depth": dict(levels=3, width=0.125),
             "color": dict(levels=3, width=0.125)}
    for kind, cfg in small.items():
        save_safetensors(build_net(kind, **cfg), tmp_path / f"{kind}.safetensors")
    (tmp_path / "notes.txt").write_text("not weights")
    fast = LearnedInpainter(weights=tmp_path, edge_unit=8, precision="bf16",
                            edge_threshold=0.01).settings()
    assert fast["weights"] == str(tmp_path.resolve())
    assert sorted(fast["sha256"]) == ["color.safetensors", "depth.safetensors",
                                      "edge.safetensors"]
    assert (fast["precision"], fast["units"]["edge"], fast["edge_threshold"]) == (
        "bf16", 8, 0.01)
    assert fast["nets"] == {"edge": "safetensors", "depth": "safetensors",
                            "color": "safetensors"}
    built = {k: build_net(k, **cfg).eval() for k, cfg in small.items()}
    given = LearnedInpainter(nets=InpaintingNets(**built, device=torch.device("cpu"),
                                                 sources={})).settings()
    assert given["weights"] == "nets given in memory" and given["sha256"] == {}
    json.dumps([bundled, fast, given])
