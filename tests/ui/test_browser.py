"""``photo3d ui`` in a real browser: headless Chromium (SwiftShader WebGL2) via
Playwright uploads the bundled sample and its depth, waits for the 3D photo, checks
that the viewer drew it and that the downloads (GLB, splats, zip) are valid files; a hostile upload
shows one line and the next upload works; two pages at once queue and each get
their own result; nothing is loaded from another host.

Skipped when Debian's ``chromium`` or the ``playwright`` package is missing (CI
installs both: apt ``chromium``, pip ``playwright``; no browser download is needed).
"""

from __future__ import annotations

import base64
import os
import time
import zipfile
from pathlib import Path
from urllib.parse import urlsplit

import numpy as np
import pytest
from PIL import Image
from uikit import (
    GRADIO_WARNINGS,
    check_glb,
    check_zip,
    first_request_held,
    png_bomb,
    running,
    write_sample,
)

from photo3d.export.splats import build_splats
from photo3d.io.npz import load_npz
from photo3d.io.spz import read_spz

CHROMIUM = os.environ.get("PHOTO3D_CHROMIUM", "/usr/bin/chromium")
if not Path(CHROMIUM).is_file():
    pytest.skip(f"no Chromium at {CHROMIUM} (apt-get install chromium, or set PHOTO3D_CHROMIUM)",
                allow_module_level=True)
sync_api = pytest.importorskip("playwright.sync_api", reason="needs pip install playwright")
pytest.importorskip("gradio", reason="needs pip install 'photo3d[ui]'")

pytestmark = GRADIO_WARNINGS
READY = "window.photo3dViewer && (photo3dViewer.ready || photo3dViewer.error !== null)"


@pytest.fixture(scope="module")
def server():
    with running() as server:
        yield server


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    return write_sample(tmp_path_factory.mktemp("sample"))


@pytest.fixture(scope="module")
def browser():
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=CHROMIUM,
            args=["--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
        )
        yield browser
        browser.close()


@pytest.fixture
def page(browser, server):
    page = browser.new_page(viewport={"width": 1280, "height": 900}, device_scale_factor=1)
    page.requests = []
    page.on("request", lambda r: page.requests.append(r.url))
    page.goto(server.url)
    page.wait_for_selector("#photo3d-make")
    yield page
    page.close()


def wait_until(check, timeout: float, what: str):
    """Poll ``check()`` from Python until it returns something true; returns it."""
    end = time.monotonic() + timeout
    while not (value := check()):
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.2)
    return value


def status(page) -> str:
    return page.locator("#photo3d-status textarea").input_value()


def prepare(page, photo: Path, depth: Path | None, *, size: int, videos: bool) -> None:
    """Upload the files and set the options."""
    page.locator("#photo3d-photo input[type=file]").set_input_files(photo)
    if depth is not None:
        page.locator("#photo3d-depth input[type=file]").set_input_files(depth)
    slider = page.locator("#photo3d-size input[type=range]")
    if not slider.is_visible():
        page.click("#photo3d-options")
        slider.wait_for()
        page.wait_for_timeout(500)  # the options are built when first shown
    slider.fill(str(size))
    checkbox = page.locator("#photo3d-videos-on input[type=checkbox]")
    if checkbox.is_checked() != videos:
        checkbox.click()
    page.wait_for_timeout(300)
    assert slider.input_value() == str(size)


def make(page, photo: Path, depth: Path | None, *, size: int, videos: bool) -> str:
    """Upload, set the options, press the button; returns the final status line."""
    prepare(page, photo, depth, size=size, videos=videos)
    before = status(page)
    page.click("#photo3d-make")
    return wait_until(lambda: (s := status(page)) != before and (
        s.startswith("Error") or ("made in" in s and "rendering" not in s)) and s,
        300, "the result")


def download(page, selector: str, target: Path) -> Path:
    href = page.locator(f"{selector} a[download]").first.get_attribute("href")
    reply = page.request.get(href)
    assert reply.ok
    target.write_bytes(reply.body())
    return target


def viewer_pixels(page) -> np.ndarray:
    """What the 3D photo's viewer drew, ``(H, W, 3) uint8``."""
    frame = page.locator("#photo3d-viewer iframe").element_handle().content_frame()
    wait_until(lambda: frame.evaluate(READY), 120, "the viewer's first frame")
    assert frame.evaluate("photo3dViewer.error") is None
    out = frame.evaluate("photo3dViewer.pixels()")
    rgba = np.frombuffer(base64.b64decode(out["rgba"]), np.uint8)
    return rgba.reshape(out["height"], out["width"], 4)[..., :3]


def test_the_sample_and_its_depth_become_a_3d_photo_in_the_page(page, server, sample,
                                                                 tmp_path):
    wait_until(lambda: "Ready" in page.inner_text("#photo3d-warmup"), 300, "the warm-up")
    line = make(page, *sample, size=512, videos=False)
    assert line.startswith("3D photo made in") and "512x345" in line
    drawn = viewer_pixels(page)
    assert drawn.shape[0] > 100 and drawn.std() > 10
    assert len(np.unique(drawn.reshape(-1, 3), axis=0)) > 500  # a photo, not a fill
    check_glb(download(page, "#photo3d-glb", tmp_path / "mesh.glb"), min_faces=1000)
    splats = read_spz(download(page, "#photo3d-splats", tmp_path / "splats.spz"))
    check_zip(download(page, "#photo3d-zip", tmp_path / "photo.zip"))
    with zipfile.ZipFile(tmp_path / "photo.zip") as z:  # the adaptive splats of its photo
        (tmp_path / "photo3d.npz").write_bytes(z.read("photo3d.npz"))
    assert len(splats) == len(build_splats(load_npz(tmp_path / "photo3d.npz")[0]))
    host = urlsplit(server.url).netloc
    assert {urlsplit(u).netloc for u in page.requests if u.startswith("http")} == {host}


def test_a_hostile_upload_is_one_line_and_the_next_upload_works(page, sample, tmp_path):
    line = make(page, png_bomb(tmp_path / "bomb.png"), None, size=256, videos=False)
    assert line.startswith("Error: ") and "decompression bomb" in line and "\n" not in line
    assert "/tmp" not in line
    page.click("#photo3d-photo button[aria-label=Clear]")
    line = make(page, *sample, size=256, videos=True)
    assert line.startswith("3D photo and 1 video(s) made in") and "256x173" in line
    assert viewer_pixels(page).std() > 10
    video = page.locator("#photo3d-videos video").first.get_attribute("src")
    body = page.request.get(video).body()
    assert body[4:8] == b"ftyp" and len(body) > 10_000


def test_two_pages_at_once_queue_and_each_get_their_own_result(browser, server, sample,
                                                               tmp_path, monkeypatch):
    flat = tmp_path / "flat.png"  # the second page's depth: make warns it has no range
    Image.new("I;16", (741, 500), 1000).save(flat)
    pages = []
    for _ in range(2):
        page = browser.new_page(viewport={"width": 1280, "height": 900})
        page.goto(server.url)
        page.wait_for_selector("#photo3d-make")
        pages.append(page)
    # the first request is held until the second page shows its place in the queue: a
    # make of 256 px may otherwise end before the second click arrives
    try:
        with first_request_held(monkeypatch) as (gate, calls):
            for page, depth in zip(pages, (sample[1], flat), strict=True):
                prepare(page, sample[0], depth, size=256, videos=False)
            for page in pages:
                page.click("#photo3d-make")
            queued = wait_until(lambda: "queue: 1/1" in pages[1].inner_text("#photo3d-viewer"),
                                60, "the second page's place in the queue")
            gate.set()
            lines = [wait_until(lambda p=p: "made in" in status(p) and status(p), 300,
                                "a result") for p in pages]
            zips = {p.locator("#photo3d-zip a[download]").get_attribute("href") for p in pages}
    finally:
        for page in pages:
            page.close()
    assert queued and len(calls) == 2 and all("256x173" in line for line in lines)
    assert "warning" not in lines[0]
    assert "\nwarning: depth has almost no range: the 3D photo will look flat" in lines[1]
    assert len(zips) == 2  # each its own folder
