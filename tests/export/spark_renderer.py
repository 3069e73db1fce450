"""A real Gaussian splat renderer for the tests: Spark (``@sparkjsdev/spark``, npm) on
three.js in headless Chromium (SwiftShader WebGL2) via Playwright.

Needs Debian's ``chromium``, the ``playwright`` package and the npm packages
``@sparkjsdev/spark`` and ``three`` in ``PHOTO3D_NODE_MODULES/node_modules`` (``make
test`` installs them into ``.node/``); :func:`missing` says what is absent. The page
and the splat file are served from a local HTTP server (module scripts do not load
from ``file://``); nothing is fetched from the network: three.js and Spark come from
``node_modules`` through an import map.

:func:`render_views` opens one splat file and renders it from photo3d cameras
(OpenCV poses): the splats are turned 180 degrees about x into three.js's axes and
the three.js camera gets the same pose and vertical field of view. Spark's defaults
are kept (``blurAmount`` 0.3 with its opacity compensation, radial sorting).

Run as a script to write the pictures of docs/outputs.md (Spark's view beside
photo3d's render of the mesh)::

    PHOTO3D_NODE_MODULES=.node python tests/export/spark_renderer.py out/demo docs/img
"""

from __future__ import annotations

import base64
import functools
import http.server
import os
import sys
import tempfile
import threading
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from photo3d.camera import Camera

CHROMIUM = os.environ.get("PHOTO3D_CHROMIUM", "/usr/bin/chromium")
NODE_DIR = os.environ.get("PHOTO3D_NODE_MODULES", "")
PACKAGES = ("@sparkjsdev/spark", "three")
_FLIP = np.diag([1.0, -1.0, -1.0, 1.0])  # OpenCV <-> three.js axes (180 degrees about x)

PAGE = """<!doctype html>
<html><head><meta charset="utf-8"><style>body{margin:0;background:#000}</style>
<script type="importmap">{"imports": {
  "three": "/node_modules/three/build/three.module.js",
  "three/addons/": "/node_modules/three/examples/jsm/",
  "@sparkjsdev/spark": "/node_modules/@sparkjsdev/spark/dist/spark.module.js"}}</script>
</head><body><script type="module">
import * as THREE from "three";
import { SparkRenderer, SplatMesh } from "@sparkjsdev/spark";
window.splatError = null;
try {
  const q = new URLSearchParams(location.search);
  const width = +q.get("w"), height = +q.get("h");
  const renderer = new THREE.WebGLRenderer({antialias: false, alpha: true,
                                            preserveDrawingBuffer: true});
  renderer.setPixelRatio(1);
  renderer.setSize(width, height);
  renderer.setClearColor(0x000000, 0);
  document.body.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  const spark = new SparkRenderer({renderer, autoUpdate: false});
  scene.add(spark);
  const camera = new THREE.PerspectiveCamera(+q.get("vfov"), width / height, 0.01, 1000);
  const splats = new SplatMesh({url: q.get("file")});
  splats.quaternion.set(1, 0, 0, 0);  // OpenCV (x right, y down, z forward) -> three.js
  scene.add(splats);
  await splats.initialized;
  const gl = renderer.getContext();
  window.splatCount = splats.packedSplats ? splats.packedSplats.numSplats : -1;
  window.renderView = async (matrix) => {  // camera-to-world, three.js axes, column-major
    camera.matrix.fromArray(matrix);
    camera.matrix.decompose(camera.position, camera.quaternion, camera.scale);
    camera.updateMatrixWorld(true);
    await spark.update({scene, camera});  // generate and sort for this view
    renderer.render(scene, camera);
    const rgba = new Uint8Array(width * height * 4);
    gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, rgba);
    let text = "";
    for (let i = 0; i < rgba.length; i += 32768) {
      text += String.fromCharCode.apply(null, rgba.subarray(i, i + 32768));
    }
    return btoa(text);
  };
  window.readSplats = () => {  // every splat as Spark decoded it: 14 floats each
    const out = [];
    splats.forEachSplat((i, center, scales, quaternion, opacity, color) => {
      out.push(center.x, center.y, center.z, scales.x, scales.y, scales.z,
               quaternion.w, quaternion.x, quaternion.y, quaternion.z, opacity,
               color.r, color.g, color.b);
    });
    const bytes = new Uint8Array(new Float32Array(out).buffer);
    let text = "";
    for (let i = 0; i < bytes.length; i += 32768) {
      text += String.fromCharCode.apply(null, bytes.subarray(i, i + 32768));
    }
    return btoa(text);
  };
  window.splatReady = true;
} catch (error) {
  window.splatError = String(error && error.stack || error);
}
</script></body></html>
"""


def missing() -> str | None:
    """Why the renderer cannot run here, or None."""
    if not Path(CHROMIUM).is_file():
        return f"no Chromium at {CHROMIUM} (apt-get install chromium, or PHOTO3D_CHROMIUM)"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "needs pip install playwright"
    modules = Path(NODE_DIR) / "node_modules"
    if not NODE_DIR or not all((modules / p / "package.json").is_file() for p in PACKAGES):
        return ("needs PHOTO3D_NODE_MODULES with npm packages @sparkjsdev/spark and three "
                "(make test installs them into .node/)")
    return None


@contextmanager
def served(splat_file: Path, page: str = PAGE):
    """A local HTTP server for ``page`` (as ``index.html``), the splat file and
    node_modules (also for spz_readers' page)."""
    with tempfile.TemporaryDirectory() as root:
        root = Path(root)
        (root / "index.html").write_text(page)
        os.symlink(Path(NODE_DIR).resolve() / "node_modules", root / "node_modules")
        os.symlink(Path(splat_file).resolve(), root / splat_file.name)
        handler = functools.partial(_Quiet, directory=str(root))
        server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
        thread = threading.Thread(target=server.serve_forever, daemon=True)
        thread.start()
        try:
            yield f"http://127.0.0.1:{server.server_address[1]}"
        finally:
            server.shutdown()
            server.server_close()


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:
        pass


@contextmanager
def chromium():
    """A headless Chromium with SwiftShader WebGL2 (Playwright)."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=[
            "--use-angle=swiftshader", "--enable-unsafe-swiftshader"])
        try:
            yield browser
        finally:
            browser.close()


@contextmanager
def spark_page(splat_file: Path, width: int, height: int, vfov: float, *, browser=None,
               timeout: float = 600.0):
    """A Playwright page with ``splat_file`` loaded in Spark (``window.renderView``,
    ``window.readSplats``); ``vfov`` in radians; ``browser`` from :func:`chromium`
    (None: a new one)."""
    if browser is None:
        with chromium() as browser:
            with spark_page(splat_file, width, height, vfov, browser=browser,
                            timeout=timeout) as page:
                yield page
        return
    with served(Path(splat_file)) as url:
        page = browser.new_page(viewport={"width": width, "height": height},
                                device_scale_factor=1)
        try:
            page.set_default_timeout(timeout * 1000)
            errors = []
            page.on("pageerror", lambda error: errors.append(error))
            page.goto(f"{url}/index.html?file=/{Path(splat_file).name}&w={width}&h={height}"
                      f"&vfov={np.degrees(vfov)}")
            page.wait_for_function("window.splatReady || window.splatError !== null")
            error = page.evaluate("window.splatError")
            if error or errors:
                raise AssertionError(f"Spark failed: {error or errors}")
            yield page
        finally:
            page.close()


def three_matrix(camera: Camera) -> list[float]:
    """The three.js camera-to-world matrix (column-major) of a photo3d camera."""
    world_from_camera = np.linalg.inv(camera.pose)
    return (_FLIP @ world_from_camera @ _FLIP).T.ravel().tolist()


def render_views(splat_file: Path, cameras: list[Camera], *, browser=None
                 ) -> list[np.ndarray]:
    """Spark's renders of ``splat_file`` from ``cameras`` (same intrinsics, principal
    point at the centre): ``(H, W, 4) float`` RGBA in [0, 1], row 0 at the top,
    straight alpha over nothing (premultiplied by Spark: colour = rgb * alpha)."""
    k = cameras[0].intrinsics
    images = []
    with spark_page(splat_file, k.width, k.height, k.fov[1], browser=browser) as page:
        for camera in cameras:
            data = base64.b64decode(page.evaluate("m => window.renderView(m)",
                                                  three_matrix(camera)))
            rgba = np.frombuffer(data, np.uint8).reshape(k.height, k.width, 4)[::-1]
            images.append(rgba / 255.0)
    return images


def read_splats(splat_file: Path, *, browser=None) -> np.ndarray:
    """Every splat as Spark decoded it: ``(N, 14) float32`` centre (file axes), scales,
    quaternion w x y z, opacity, colour r g b."""
    with spark_page(splat_file, 16, 16, 1.0, browser=browser) as page:
        data = base64.b64decode(page.evaluate("window.readSplats()"))
    return np.frombuffer(data, np.float32).reshape(-1, 14)


def _screenshots(folder: Path, out: Path) -> None:
    """docs/outputs.md's pictures: the sample's ``splats.ply`` (adaptive, as ``photo3d
    export`` writes it) in Spark from the input camera and from the circle path's
    widest camera, each beside photo3d's own render of the mesh from that camera."""
    from PIL import Image

    from photo3d.config import Config
    from photo3d.export import export_folder
    from photo3d.io.npz import load_npz
    from photo3d.photo import Photo3D
    from photo3d.render.renderer import Renderer, RenderSettings

    ldi, _ = load_npz(folder / "photo3d.npz")
    cameras = [Camera(ldi.intrinsics, np.eye(4)), widest_circle_camera(ldi.intrinsics)]
    with tempfile.TemporaryDirectory() as tmp:
        ply = export_folder(folder, ["splats.ply"], output=Path(tmp) / "splats.ply")[0]
        views = render_views(ply, cameras)
    with Renderer(Photo3D(ldi, Config()).mesh(), RenderSettings(backend="numba")) as r:
        meshes = [r.render(c).color for c in cameras]
    for name, view, mesh in zip(("splats_input.jpg", "splats_circle.jpg"), views, meshes,
                                strict=True):
        pair = np.concatenate([view[..., :3], np.ones((len(mesh), 8, 3)), mesh], axis=1)
        image = np.rint(np.clip(pair, 0, 1) * 255).astype(np.uint8)  # splats over black
        Image.fromarray(image).resize((image.shape[1] // 2, image.shape[0] // 2),
                                      Image.LANCZOS).save(out / name, quality=85)
        print(out / name)  # noqa: T201 - a script


def widest_circle_camera(k) -> Camera:
    """The frame of the circle path farthest from the input view."""
    from photo3d.render.paths import preset_path

    path = preset_path("circle", k)
    return max(path, key=lambda c: float(np.linalg.norm(c.pose[:3, 3])))


if __name__ == "__main__":
    reason = missing()
    if reason:
        sys.exit(reason)
    _screenshots(Path(sys.argv[1]), Path(sys.argv[2]))
