"""Splat readers that others wrote, run in headless Chromium for the tests: three.js's
``SPZLoader`` (SPZ 1-4) and ``GLTFGaussianSplatLoaderExtension``
(``KHR_gaussian_splatting``; ``three`` 0.187, npm) and PlayCanvas's
``@playcanvas/splat-transform`` (SPZ 2-4: its ``readFile`` and
``materializeToDataTable``, on the ``playcanvas`` engine package), all from
``PHOTO3D_NODE_MODULES/node_modules`` (``make test`` installs them into ``.node/``).

:func:`read_with` loads one ``.spz`` file in a page and returns what the reader
decoded, as numpy arrays. Nothing is fetched from the network: the modules come from
``node_modules`` through an import map, the file from a local HTTP server.
"""

from __future__ import annotations

import base64
import json
from pathlib import Path

import numpy as np
from spark_renderer import CHROMIUM, NODE_DIR, served

PACKAGES = ("three", "playcanvas", "@playcanvas/splat-transform")

PAGE = """<!doctype html>
<html><head><meta charset="utf-8">
<script type="importmap">{"imports": {
  "three": "/node_modules/three/build/three.module.js",
  "three/addons/": "/node_modules/three/examples/jsm/",
  "three/webgpu": "/node_modules/three/build/three.webgpu.js",
  "three/tsl": "/node_modules/three/build/three.tsl.js",
  "playcanvas": "/node_modules/playcanvas/build/playcanvas.mjs",
  "@playcanvas/splat-transform": "/node_modules/@playcanvas/splat-transform/dist/index.mjs"}}
</script></head><body><script type="module">
import { SPZLoader } from "three/addons/loaders/SPZLoader.js";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
import { GLTFGaussianSplatLoaderExtension }
  from "three/addons/loaders/GLTFGaussianSplatLoaderExtension.js";
import { MemoryReadFileSystem, readFile, materializeToDataTable, createChunkDataPool }
  from "@playcanvas/splat-transform";
const pack = (array) => {  // a typed array as base64 of its bytes
  const bytes = new Uint8Array(array.buffer, array.byteOffset, array.byteLength);
  let text = "";
  for (let i = 0; i < bytes.length; i += 32768) {
    text += String.fromCharCode.apply(null, bytes.subarray(i, i + 32768));
  }
  return btoa(text);
};
const attributes = (geometry) => {
  const out = {};
  for (const name of ["position", "covariance", "color"]) {
    const attribute = geometry.getAttribute(name);
    out[name] = {data: pack(attribute.array), width: attribute.itemSize,
                 type: attribute.array.constructor.name};
  }
  return JSON.stringify(out);
};
window.readers = {
  async three_glb(url) {
    const loader = new GLTFLoader();
    loader.register((parser) => new GLTFGaussianSplatLoaderExtension(parser));
    const gltf = await loader.loadAsync(url);
    let splat = null;
    gltf.scene.traverse((o) => { if (o.isGaussianSplat) splat = o; });
    if (splat === null) throw new Error("no GaussianSplat in the scene");
    return attributes(splat.splatGeometry);
  },
  async three(url) {
    const buffer = await (await fetch(url)).arrayBuffer();
    return attributes(await new SPZLoader().parse(buffer));
  },
  async playcanvas(url) {
    const bytes = new Uint8Array(await (await fetch(url)).arrayBuffer());
    const fileSystem = new MemoryReadFileSystem();
    fileSystem.set("splats.spz", bytes);
    const [source] = await readFile({filename: "splats.spz", inputFormat: "spz",
                                     fileSystem});
    const table = await materializeToDataTable(source, createChunkDataPool());
    const out = {};
    for (const column of table.columns) {
      out[column.name] = {data: pack(column.data), width: 1,
                          type: column.data.constructor.name};
    }
    return JSON.stringify(out);
  },
};
window.ready = true;
</script></body></html>
"""
_TYPES = {"Float32Array": np.float32, "Uint8Array": np.uint8, "Uint8ClampedArray": np.uint8,
          "Uint16Array": np.uint16, "Uint32Array": np.uint32, "Int32Array": np.int32}


def missing() -> str | None:
    """Why the readers cannot run here, or None."""
    if not Path(CHROMIUM).is_file():
        return f"no Chromium at {CHROMIUM}"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "needs pip install playwright"
    modules = Path(NODE_DIR) / "node_modules"
    if not NODE_DIR or not all((modules / p / "package.json").is_file() for p in PACKAGES):
        return ("needs PHOTO3D_NODE_MODULES with npm packages " + ", ".join(PACKAGES)
                + " (make test installs them into .node/)")
    if not (modules / "three/examples/jsm/loaders/SPZLoader.js").is_file():
        return "the installed three.js has no SPZLoader"
    return None


def read_with(reader: str, splat_file: Path, browser) -> dict[str, np.ndarray]:
    """What ``reader`` decodes from ``splat_file``: ``"three"`` (an ``.spz``) and
    ``"three_glb"`` (a ``.glb``, through ``GLTFLoader`` with
    ``GLTFGaussianSplatLoaderExtension``): ``position (N, 3)``, ``covariance (N, 6)``
    (xx, xy, xz, yy, yz, zz) and ``color (N, 4) uint8``; ``"playcanvas"`` (an
    ``.spz``), splat-transform: one ``(N,)`` array per column (``x``,
    ``f_dc_0``, ``opacity``, ``scale_0``, ``rot_0``, ...: the 3DGS PLY's). The
    reader's errors raise AssertionError."""
    with served(Path(splat_file), PAGE) as url:
        page = browser.new_page()
        try:
            errors = []
            page.on("pageerror", lambda error: errors.append(error))
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.goto(f"{url}/index.html")
            try:
                page.wait_for_function("window.ready === true", timeout=60_000)
            except Exception as err:  # playwright's TimeoutError: a module did not load
                raise AssertionError(f"the readers' page did not load: {errors}") from err
            try:
                text = page.evaluate(f"u => window.readers.{reader}(u)",
                                     f"{url}/{Path(splat_file).name}")
            except Exception as err:  # playwright's Error: the reader threw
                raise AssertionError(f"{reader} failed: {err} {errors}") from None
        finally:
            page.close()
    out = {}
    for name, item in json.loads(text).items():
        data = np.frombuffer(base64.b64decode(item["data"]), _TYPES[item["type"]])
        out[name] = data.reshape(-1, item["width"]) if item["width"] > 1 else data
    return out
