"""The Khronos glTF validator on photo3d's GLB files (both kinds).

Needs Node.js and the npm package ``gltf-validator`` (``npm install gltf-validator``
in a folder named by ``PHOTO3D_NODE_MODULES``, its ``node_modules``' parent; ``make
test`` installs it into ``.node/`` when npm is there and sets the variable);
skipped otherwise.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import exact_config, texture

import photo3d
from photo3d.io.gltf import write_glb
from photo3d.io.gltf_textured import write_textured_glb

NODE_DIR = os.environ.get("PHOTO3D_NODE_MODULES", "")
if not (shutil.which("node") and NODE_DIR and
        (Path(NODE_DIR) / "node_modules" / "gltf-validator").is_dir()):
    pytest.skip("needs node and PHOTO3D_NODE_MODULES with gltf-validator",
                allow_module_level=True)

SCRIPT = """
const v = require('gltf-validator'); const fs = require('fs');
v.validateBytes(new Uint8Array(fs.readFileSync(process.argv[1]))).then(r => {
  console.log(JSON.stringify(r.issues)); });
"""


def validate(path: Path) -> dict:
    out = subprocess.run(["node", "-e", SCRIPT, str(path)], cwd=NODE_DIR, check=True,
                         capture_output=True, text=True, timeout=120)
    return json.loads(out.stdout)


def test_light_and_full_glb_have_no_errors_or_warnings(tmp_path):
    disp = np.ones((40, 48), np.float32)
    disp[10:30, 12:36] = 2.0
    photo = photo3d.make(texture(40, 48, seed=7), depth=disp, config=exact_config(border=4))
    write_textured_glb(tmp_path / "light.glb", photo.light_mesh())
    write_glb(tmp_path / "full.glb", photo.mesh())
    for name in ("light.glb", "full.glb"):
        issues = validate(tmp_path / name)
        assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"]
    # the validator does find problems: a file with a broken index is refused
    data = bytearray((tmp_path / "full.glb").read_bytes())
    data[-4:] = b"\xff\xff\xff\xff"
    (tmp_path / "bad.glb").write_bytes(bytes(data))
    assert validate(tmp_path / "bad.glb")["numErrors"] > 0


def test_soft_silhouettes_are_a_valid_blended_primitive(tmp_path):
    from photo3d.config import Config
    from photo3d.io.glb import read_chunks

    image = texture(48, 64, seed=3)
    image[:, 30:34] = (0.9, 0.1, 0.1)  # a red pole, its depth 2 px too wide
    depth = np.full((48, 64), 6.0, np.float32)
    depth[:, 28:36] = 2.0
    config = Config(size=None, depth_kind="depth", spatial_scale=1.0, edges="soft")
    photo = photo3d.make(image, depth=depth, config=config)
    light = photo.light_mesh()
    assert light.overlay is not None and photo.ldi.soft
    write_textured_glb(tmp_path / "light.glb", light)
    write_glb(tmp_path / "full.glb", photo.mesh())
    for name in ("light.glb", "full.glb"):
        document = read_chunks(tmp_path / name)[0]
        assert [m.get("alphaMode", "OPAQUE") for m in document["materials"]] == [
            "OPAQUE", "BLEND"]
        issues = validate(tmp_path / name)
        assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"]
