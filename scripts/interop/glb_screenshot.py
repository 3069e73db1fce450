"""Screenshot a GLB in three.js (headless Chromium), seen from its own camera node.

Serves a small page, three.js (``npm install three`` in NODE_DIR) and the GLB over
a local HTTP server, opens it in Debian's ``chromium`` through Playwright (the
``playwright`` package; no browser download), loads the file with three.js's
``GLTFLoader``, looks through the file's first camera moved by ``--shift`` (depth
units, input camera axes: x right, y down, z forward) and saves a PNG.

Usage: python scripts/interop/glb_screenshot.py out/demo/mesh.glb shot.png \
           --node-dir DIR [--shift 0.015,0,0] [--size 1024x691]
"""

from __future__ import annotations

import argparse
import functools
import http.server
import shutil
import tempfile
import threading
import time
from pathlib import Path

PAGE = """<!doctype html><html><body style="margin:0;background:#111">
<script type="importmap">{"imports": {"three": "./three/build/three.module.js",
  "three/addons/": "./three/examples/jsm/"}}</script>
<script type="module">
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
const [w, h, sx, sy, sz] = [%(w)d, %(h)d, %(sx)f, %(sy)f, %(sz)f];
const renderer = new THREE.WebGLRenderer({antialias: true, preserveDrawingBuffer: true});
renderer.setSize(w, h);
document.body.appendChild(renderer.domElement);
new GLTFLoader().load('model.glb', (gltf) => {
  const camera = gltf.cameras[0];
  camera.aspect = w / h; camera.updateProjectionMatrix();
  // glTF axes: x right, y up, the camera looks down -z; photo3d's y and z flip
  camera.position.set(sx, -sy, -sz);
  const scene = gltf.scene;
  renderer.render(scene, camera);
  window.done = {triangles: renderer.info.render.triangles,
                 textured: !!gltf.scene.getObjectByName('photo3d').material.map};
}, undefined, (err) => { window.done = {error: String(err)}; });
</script></body></html>"""


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:
        pass


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("glb", type=Path)
    parser.add_argument("png", type=Path)
    parser.add_argument("--node-dir", type=Path, required=True,
                        help="folder holding node_modules/three")
    parser.add_argument("--shift", default="0.015,0,0")
    parser.add_argument("--size", default="1024x691")
    parser.add_argument("--chromium", default="/usr/bin/chromium")
    args = parser.parse_args()
    from playwright.sync_api import sync_playwright

    w, h = (int(v) for v in args.size.split("x"))
    sx, sy, sz = (float(v) for v in args.shift.split(","))
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        (root / "three").symlink_to((args.node_dir / "node_modules" / "three").resolve())
        shutil.copy(args.glb, root / "model.glb")
        (root / "index.html").write_text(PAGE % dict(w=w, h=h, sx=sx, sy=sy, sz=sz))
        handler = functools.partial(_QuietHandler, directory=tmp)
        server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
        threading.Thread(target=server.serve_forever, daemon=True).start()
        try:
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=args.chromium, args=[
                    "--use-angle=swiftshader", "--enable-unsafe-swiftshader"])
                page = browser.new_page(viewport={"width": w, "height": h})
                page.goto(f"http://127.0.0.1:{server.server_port}/index.html")
                end = time.monotonic() + 120
                while not page.evaluate("() => window.done") and time.monotonic() < end:
                    time.sleep(0.2)
                print(page.evaluate("() => JSON.stringify(window.done)"))
                page.screenshot(path=str(args.png))
                browser.close()
        finally:
            server.shutdown()


if __name__ == "__main__":
    main()
