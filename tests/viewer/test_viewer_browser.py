"""viewer.html in a real browser: headless Chromium (SwiftShader WebGL2) via Playwright.

Skipped when Debian's ``chromium`` or the ``playwright`` package is missing (CI installs
both: apt ``chromium``, pip ``playwright``; no browser download is needed).
"""

from __future__ import annotations

import base64
import io
import os
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from viewer_scenes import HEIGHT, WIDTH, box_photo, shuffled

from photo3d.camera import Camera, Intrinsics
from photo3d.render.renderer import Renderer, RenderSettings
from photo3d.viewer import ViewerServer, write_viewer

CHROMIUM = os.environ.get("PHOTO3D_CHROMIUM", "/usr/bin/chromium")
if not Path(CHROMIUM).is_file():
    pytest.skip(f"no Chromium at {CHROMIUM} (apt-get install chromium, or set PHOTO3D_CHROMIUM)",
                allow_module_level=True)
sync_api = pytest.importorskip("playwright.sync_api", reason="needs pip install playwright")

RANGE = np.array([0.015, 0.015, 0.05])  # viewer.js: the authors' circle shifts
READY = "window.photo3dViewer && (photo3dViewer.ready || photo3dViewer.error !== null)"


@pytest.fixture(scope="module")
def browser():
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=CHROMIUM,
            args=["--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
        )
        yield browser
        browser.close()


@pytest.fixture(scope="module")
def page_file(tmp_path_factory):
    return write_viewer(box_photo().mesh(), tmp_path_factory.mktemp("viewer") / "viewer.html")


def open_page(browser, url, *, size=(WIDTH, HEIGHT), init_script=None):
    page = browser.new_page(viewport={"width": size[0], "height": size[1]},
                            device_scale_factor=1)
    errors = []
    page.on("pageerror", lambda error: errors.append(error))
    if init_script:
        page.add_init_script(init_script)
    page.goto(url)
    wait_until(page, READY, timeout=20)
    return page, errors


def wait_until(page, expression: str, timeout: float = 10.0) -> None:
    """Poll ``expression`` from Python (the page's CSP forbids Playwright's in-page eval)."""
    end = time.monotonic() + timeout
    while not page.evaluate(expression):
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {expression}")
        time.sleep(0.05)


def pixels(page) -> np.ndarray:
    """The drawing buffer as ``(H, W, 3) float`` in [0, 1], row 0 at the top."""
    out = page.evaluate("photo3dViewer.pixels()")
    rgba = np.frombuffer(base64.b64decode(out["rgba"]), np.uint8)
    return rgba.reshape(out["height"], out["width"], 4)[..., :3] / 255.0


def reference(position, camera=None) -> tuple[np.ndarray, np.ndarray]:
    """photo3d's own renderer at the same camera: colour and covered pixels."""
    photo = box_photo()
    camera = camera or Camera.translated(Intrinsics.default(WIDTH, HEIGHT), position)
    settings = RenderSettings(ssaa=1, fill_holes=False, backend="numba")
    with Renderer(photo.mesh(), settings) as renderer:
        view = renderer.render(camera)
    return view.color, view.mask


def psnr(a, b) -> float:
    return float(10 * np.log10(1.0 / np.mean((a - b) ** 2)))


def test_renders_a_non_blank_image(browser, page_file):
    page, errors = open_page(browser, page_file.as_uri())  # default: animated
    try:
        assert page.evaluate("photo3dViewer.error") is None and not errors
        shot = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB"), float)
        assert shot.shape == (HEIGHT, WIDTH, 3)
        assert shot.std() > 10 and len(np.unique(shot.reshape(-1, 3), axis=0)) > 500
        assert page.evaluate("photo3dViewer.firstFrameMs") > 0
    finally:
        page.close()


@pytest.mark.parametrize("position", [(0.0, 0.0, 0.0), (0.03, -0.02, 0.05)])
def test_fixed_camera_matches_photo3d_renderer(browser, page_file, position):
    url = page_file.as_uri() + "#static=1&camera=" + ",".join(map(str, position))
    page, errors = open_page(browser, url)
    try:
        assert page.evaluate("photo3dViewer.position()") == pytest.approx(list(position))
        got = pixels(page)
        assert not errors
    finally:
        page.close()
    want, covered = reference(position)
    assert got.shape == want.shape and covered.mean() > 0.95
    assert psnr(got[covered], want[covered]) > 25
    # and far from the reference at another camera (the test can fail)
    other, _ = reference((-0.05, 0.0, 0.0))
    assert psnr(got[covered], other[covered]) < psnr(got[covered], want[covered]) - 3


def test_pose_hook_with_a_rotation_matches_photo3d_renderer(browser, page_file):
    camera = Camera.look_at(Intrinsics.default(WIDTH, HEIGHT), (0.04, 0.02, 0.0), (0.5, 0, 4))
    page, errors = open_page(browser, page_file.as_uri() + "#static=1")
    try:
        page.evaluate("pose => photo3dViewer.setCamera(pose)", camera.pose.ravel().tolist())
        assert page.evaluate("photo3dViewer.position()") == pytest.approx(
            camera.position.tolist(), abs=1e-9)
        got = pixels(page)
        assert not errors
    finally:
        page.close()
    want, covered = reference(None, camera)
    assert covered.mean() > 0.9 and psnr(got[covered], want[covered]) > 25
    unrotated, _ = reference(camera.position)
    assert psnr(got[covered], unrotated[covered]) < psnr(got[covered], want[covered]) - 3


def test_any_face_order_decodes_to_the_same_picture(browser, page_file, tmp_path):
    other = write_viewer(shuffled(box_photo().mesh(), seed=2), tmp_path / "shuffled.html")
    images = []
    for path in (page_file, other):
        page, _ = open_page(browser, path.as_uri() + "#static=1&camera=0.02,0.01,0")
        try:
            images.append(pixels(page))
        finally:
            page.close()
    assert np.mean(np.abs(images[0] - images[1]) > 2 / 255) < 0.01


def test_base64_fallback_for_browsers_without_frombase64(browser, page_file):
    images = []
    for init in (None, "delete Uint8Array.fromBase64;"):
        page, errors = open_page(browser, page_file.as_uri() + "#static=1", init_script=init)
        try:
            assert not errors and page.evaluate("photo3dViewer.ready")
            images.append(pixels(page))
        finally:
            page.close()
    np.testing.assert_array_equal(images[0], images[1])


def test_pointer_moves_the_camera_within_range(browser, page_file):
    page, _ = open_page(browser, page_file.as_uri() + "#static=1", size=(2 * WIDTH, 2 * HEIGHT))
    try:
        before = pixels(page)
        assert page.evaluate("photo3dViewer.position()") == [0, 0, 0]
        page.mouse.move(2 * WIDTH - 1, 2 * HEIGHT - 1)  # bottom-right corner
        wait_until(page, "photo3dViewer.position()[0] > 0.014")
        after = pixels(page)
        positions = [page.evaluate("photo3dViewer.position()") for _ in range(5)]
    finally:
        page.close()
    assert np.mean(np.abs(after - before)) > 0.01
    for p in positions:  # right and down (OpenCV y down), never beyond the range
        assert 0 < p[0] <= RANGE[0] + 1e-9 and 0 < p[1] <= RANGE[1] + 1e-9


TOUCH_DRAG = """() => {
    const canvas = document.querySelector('canvas');
    const r = canvas.getBoundingClientRect();
    const at = (type, dx) => canvas.dispatchEvent(new PointerEvent(type, {
        pointerType: 'touch', pointerId: 7, bubbles: true, isPrimary: true,
        clientX: r.left + r.width / 2 + dx, clientY: r.top + r.height / 2}));
    at('pointerdown', 0);
    at('pointermove', -r.height);  // far to the left: clamped to the range
}"""
TILT = """(gamma) => window.dispatchEvent(
    new DeviceOrientationEvent('deviceorientation', {alpha: 0, beta: 30, gamma}))"""


def test_touch_drag_and_device_tilt_move_the_camera(browser, page_file):
    page, errors = open_page(browser, page_file.as_uri() + "#static=1")
    try:
        page.evaluate(TOUCH_DRAG)
        wait_until(page, "photo3dViewer.position()[0] < -0.0149")
        assert page.evaluate("photo3dViewer.position()[0]") >= -RANGE[0] - 1e-9
        page.evaluate("""() => document.querySelector('canvas').dispatchEvent(
            new PointerEvent('pointerup', {pointerType: 'touch', pointerId: 7}))""")
        wait_until(page, "Math.abs(photo3dViewer.position()[0]) < 1e-4")  # springs back
        page.evaluate(TILT, 0)  # the first reading is the reference
        page.evaluate(TILT, 10)  # tilted right: camera moves right
        wait_until(page, "photo3dViewer.position()[0] > 0.009")
        assert not errors
    finally:
        page.close()


def test_animation_follows_the_circle_path(browser, page_file):
    page, _ = open_page(browser, page_file.as_uri())
    try:
        # past the 1.5 s fade-in (headless Chromium draws about 1 frame per second)
        wait_until(page, "Math.hypot(...photo3dViewer.position().slice(0, 2)) > 0.01499")
        samples = []
        for _ in range(3):
            samples.append(page.evaluate("photo3dViewer.position()"))
            time.sleep(1.1)
        x, y, z = np.array(samples).T
    finally:
        page.close()
    # photo3d.render.paths "circle": position (0.015 cos(pi u), 0.015 sin(pi u),
    # 0.05 cos(pi u / 2)), so x^2 + y^2 = 0.015^2 and (z / 0.05)^2 = (1 + x / 0.015) / 2
    np.testing.assert_allclose(np.hypot(x, y), RANGE[0], atol=1e-7)
    np.testing.assert_allclose((z / RANGE[2]) ** 2, (1 + x / RANGE[0]) / 2, atol=1e-6)
    assert np.ptp(x) > 0 or np.ptp(y) > 0  # it moves


def test_no_network_request(browser, page_file):
    with ViewerServer(page_file.parent) as server:
        thread = threading.Thread(target=server.serve_forever)
        thread.start()
        try:
            page = browser.new_page(viewport={"width": WIDTH, "height": HEIGHT})
            requests = []
            page.on("request", lambda r: requests.append(r.url))
            page.goto(server.url)
            wait_until(page, READY, timeout=20)
            page.mouse.move(10, 10)
            page.wait_for_timeout(300)
            ready = page.evaluate("photo3dViewer.ready")
            page.close()
        finally:
            server.shutdown()
            thread.join()
    assert ready
    assert requests == [server.url]


def test_fallback_message_without_webgl2(browser, page_file):
    no_webgl2 = """
        const original = HTMLCanvasElement.prototype.getContext;
        HTMLCanvasElement.prototype.getContext = function (kind, ...rest) {
            return kind === 'webgl2' ? null : original.call(this, kind, ...rest);
        };"""
    page, _ = open_page(browser, page_file.as_uri(), init_script=no_webgl2)
    try:
        assert page.evaluate("photo3dViewer.ready") is False
        assert "WebGL 2" in page.inner_text("#photo3d-message")
        assert page.is_visible("#photo3d-message") and not page.is_visible("canvas")
    finally:
        page.close()


def test_textured_page_matches_photo3d_renderer(browser, tmp_path):
    """The light textured mesh in the page looks like photo3d's own render of it."""
    from photo3d.mesh.light import build_light_mesh

    light = build_light_mesh(box_photo().ldi)
    path = write_viewer(light, tmp_path / "viewer.html")
    position = (0.03, -0.02, 0.05)
    page, errors = open_page(browser, path.as_uri() + "#static=1&camera=" +
                             ",".join(map(str, position)))
    try:
        assert page.evaluate("photo3dViewer.error") is None and not errors
        got = pixels(page)
    finally:
        page.close()
    camera = Camera.translated(Intrinsics.default(WIDTH, HEIGHT), position)
    settings = RenderSettings(ssaa=1, fill_holes=False, backend="numba")
    with Renderer(light, settings) as renderer:
        view = renderer.render(camera)
    covered = view.mask
    assert covered.mean() > 0.95
    assert psnr(got[covered], view.color[covered]) > 25
    other, _ = reference((-0.05, 0.0, 0.0))
    assert psnr(got[covered], other[covered]) < psnr(got[covered], view.color[covered]) - 3


def test_soft_silhouettes_are_blended_in_the_page(browser, tmp_path):
    """A photo with soft silhouettes: the page blends the fringe as photo3d's renderer
    does, and differs from the same page without the fringe's alpha."""
    from dataclasses import replace

    import photo3d
    from photo3d.config import Config
    from photo3d.mesh.light import build_light_mesh

    image = np.zeros((HEIGHT, WIDTH, 3), np.float32)
    image[:] = np.linspace(0.2, 0.6, WIDTH)[None, :, None] * np.array([0.6, 1.0, 0.8])
    image[:, 44:50] = (0.9, 0.1, 0.1)  # a red pole, its depth 2 px too wide
    depth = np.full((HEIGHT, WIDTH), 6.0, np.float32)
    depth[:, 42:52] = 2.0
    photo = photo3d.make(image, depth=depth, config=Config(size=None, depth_kind="depth",
                                                           spatial_scale=1.0, edges="soft"))
    light = build_light_mesh(photo.ldi)
    assert light.overlay is not None
    hard = replace(light, overlay=replace(light.overlay,
                                          alpha=np.ones_like(light.overlay.alpha)))
    camera = Camera.translated(Intrinsics.default(WIDTH, HEIGHT), (0.1, 0.0, 0.0))
    settings = RenderSettings(ssaa=1, fill_holes=False, backend="numba")
    got = {}
    for name, mesh in (("soft", light), ("hard", hard)):
        path = write_viewer(mesh, tmp_path / f"{name}.html")
        page, errors = open_page(browser, path.as_uri() + "#static=1&camera=0.1,0,0")
        try:
            assert page.evaluate("photo3dViewer.error") is None and not errors
            got[name] = pixels(page)
        finally:
            page.close()
    with Renderer(light, settings) as renderer:
        view = renderer.render(camera)
    covered = view.mask
    assert covered.mean() > 0.9
    assert psnr(got["soft"][covered], view.color[covered]) > 25
    fringe = np.abs(got["soft"] - got["hard"]).max(axis=2) > 0.1
    assert fringe.sum() > HEIGHT  # the fringe is drawn translucent, along the pole
