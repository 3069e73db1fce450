"""``--depth-model`` in make and batch: the model's depth reaches config.json alike."""

from __future__ import annotations

import json

import numpy as np
from test_models import tiny_depth_anything

from photo3d.cli import main
from photo3d.io.images import write_image


def test_make_and_batch_record_the_depth_model_they_used(tmp_path, capsys):
    model = tiny_depth_anything(tmp_path / "tiny")
    (tmp_path / "photos").mkdir()
    write_image(tmp_path / "photos" / "p.png",
                np.random.default_rng(0).random((40, 56, 3)).astype(np.float32))
    fast = ["--size", "64", "--no-video", "--no-glb", "--no-viewer", "--depth-model",
            str(model), "-q"]
    assert main(["make", str(tmp_path / "photos" / "p.png"), "-o", str(tmp_path / "made"),
                 *fast]) == 0
    assert main(["batch", str(tmp_path / "photos"), "-o", str(tmp_path / "many"),
                 "--workers", "1", *fast]) == 0
    made, batched = (json.loads((f / "config.json").read_text())
                     for f in (tmp_path / "made", tmp_path / "many" / "p"))
    assert made["depth_source"] == batched["depth_source"]
    assert made["depth_source"].startswith(f"monocular depth model {model} (disparity")
    assert made["config"] == batched["config"]
