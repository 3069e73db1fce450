"""The ``/make`` API with Gradio's own client: the sample and its depth give a valid
GLB and zip; hostile requests get one line and never make the server read a file
of its choosing; two clients at once each get their own result, in queue order."""

from __future__ import annotations

import threading
import time
import zipfile

import numpy as np
import pytest
from PIL import Image
from uikit import GRADIO_WARNINGS, check_glb, check_zip, png_bomb, running, write_sample

gradio_client = pytest.importorskip("gradio_client", reason="needs pip install 'photo3d[ui]'")
httpx = pytest.importorskip("httpx")

pytestmark = GRADIO_WARNINGS
MAX_UPLOAD = 4 * 2**20


@pytest.fixture(scope="module")
def server():
    with running(max_upload_bytes=MAX_UPLOAD) as server:
        yield server


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    return write_sample(tmp_path_factory.mktemp("sample"))


def client(server, tmp_path):
    return gradio_client.Client(server.url, verbose=False, download_files=str(tmp_path))


def test_the_endpoint_takes_photo_and_depth_and_defaults_the_rest(server, tmp_path):
    api = client(server, tmp_path).view_api(print_info=False, return_format="dict")
    assert list(api["named_endpoints"]) == ["/make"]
    params = {p["parameter_name"]: p for p in api["named_endpoints"]["/make"]["parameters"]}
    assert list(params)[:2] == ["photo", "depth"]
    assert not params["photo"]["parameter_has_default"]
    assert all(p["parameter_has_default"] for name, p in params.items() if name != "photo")


def test_the_sample_and_its_depth_give_a_glb_a_zip_a_depth_map_and_a_video(
        server, sample, tmp_path):
    photo, depth = sample
    handle = gradio_client.handle_file
    glb, bundle, preview, videos = client(server, tmp_path).predict(
        photo=handle(photo), depth=handle(depth), size=256, paths=["swing"], api_name="/make")
    check_glb(glb, min_faces=1000)
    names = check_zip(bundle, videos=("swing",))
    assert "mesh.ply" not in names  # off unless asked for
    with zipfile.ZipFile(bundle) as z:
        assert b'"size": 256' in z.read("config.json")
    with Image.open(preview) as im:
        assert im.size == (741, 500)  # the depth map at the photo's size
    assert len(videos) == 1 and videos[0].endswith("swing.mp4")


@pytest.mark.parametrize(("kind", "message"), [
    ("garbage", "cannot read image photo.png: not a recognised image format"),
    ("bomb", "decompression bomb"),
    ("paths", "'/etc/passwd'"),
    ("size", "greater than maximum value 2048"),
])
def test_hostile_requests_get_one_line(server, tmp_path, kind, message):
    photo = tmp_path / "photo.png"
    photo.write_bytes(b"not a photo at all")
    if kind == "bomb":
        png_bomb(photo)
    options = {"paths": ["/etc/passwd"]} if kind == "paths" else {}
    if kind in ("paths", "size"):
        Image.new("RGB", (64, 48), "gray").save(photo)
        options |= {"size": 10**6} if kind == "size" else {}
    with pytest.raises(gradio_client.exceptions.AppError) as err:
        client(server, tmp_path).predict(photo=gradio_client.handle_file(photo),
                                         api_name="/make", **options)
    text = str(err.value)
    assert message in text and "\n" not in text.strip()
    assert str(server.workspace.root.parent) not in text  # no server folder


def test_a_path_the_client_names_is_never_opened(server, tmp_path):
    secret = tmp_path / "secret.png"
    Image.new("RGB", (64, 48), "red").save(secret)  # a valid photo, outside the uploads
    fake = {"path": str(secret), "meta": {"_type": "gradio.FileData"}, "orig_name": "p.png"}
    data = [fake, None, None, 256, "diffusion", "auto", "disparity", False, ["circle"], False]
    before = set(server.workspace.root.glob("request-*"))
    with httpx.Client(base_url=server.url, timeout=60) as http:
        event = http.post("gradio_api/call/make", json={"data": data}).json()["event_id"]
        reply = http.get(f"gradio_api/call/make/{event}").text
    assert "event: error" in reply and "event: complete" not in reply
    assert set(server.workspace.root.glob("request-*")) == before  # no request started


def test_uploads_beyond_the_byte_limit_are_refused(server):
    with httpx.Client(base_url=server.url, timeout=60) as http:
        reply = http.post("gradio_api/upload",
                          files={"files": ("big.png", b"\0" * (MAX_UPLOAD + 1), "image/png")})
    assert reply.status_code == 413


def test_two_clients_at_once_each_get_their_own_result_in_queue_order(server, sample,
                                                                      tmp_path):
    first_photo, depth = sample
    second_photo = tmp_path / "grey.png"
    rng = np.random.default_rng(1)
    Image.fromarray(rng.integers(0, 255, (96, 128, 3), np.uint8)).save(second_photo)
    second_depth = tmp_path / "grey_depth.png"
    Image.fromarray(np.tile(np.arange(128, dtype=np.uint16) * 500, (96, 1))).save(second_depth)
    handle = gradio_client.handle_file
    common = dict(size=256, videos=False, api_name="/make")
    first = client(server, tmp_path / "a").submit(photo=handle(first_photo),
                                                  depth=handle(depth), **common)
    states = []
    second = client(server, tmp_path / "b").submit(photo=handle(second_photo),
                                                   depth=handle(second_depth), **common)
    done = threading.Event()

    def watch():
        while not done.is_set():
            states.append(second.status().code.name)
            time.sleep(0.02)

    watcher = threading.Thread(target=watch)
    watcher.start()
    try:
        results = [first.result(timeout=300), second.result(timeout=300)]
    finally:
        done.set()
        watcher.join()
    assert "IN_QUEUE" in states  # the second waited for the one worker
    sizes = []
    for (_, bundle, preview, _), stem in zip(results, ("sample", "grey"), strict=True):
        assert bundle.endswith(f"{stem}-3d.zip")
        check_zip(bundle)
        with Image.open(preview) as im:
            sizes.append(im.size)
    assert sizes == [(741, 500), (128, 96)]


def test_the_page_is_served_on_loopback_without_a_share_link(server):
    assert server.url.startswith("http://127.0.0.1:")
    assert server.demo.share is False and server.demo.share_url is None
    with httpx.Client(base_url=server.url, timeout=60) as http:
        assert http.get("/").status_code == 200
        assert http.get("monitoring").status_code in (403, 404)


def test_with_a_login_the_page_and_the_api_need_it(tmp_path):
    with running(auth=("ana", "s3cret"), warmup=False) as server:
        with httpx.Client(base_url=server.url, timeout=60) as http:
            assert http.get("config").status_code == 401
            assert http.post("gradio_api/upload",
                             files={"files": ("a.png", b"x", "image/png")}).status_code == 401
        with pytest.raises(gradio_client.exceptions.AuthenticationError):
            gradio_client.Client(server.url, verbose=False, download_files=str(tmp_path))
        api = gradio_client.Client(server.url, auth=("ana", "s3cret"), verbose=False,
                                   download_files=str(tmp_path))
        assert "/make" in api.view_api(print_info=False, return_format="dict")[
            "named_endpoints"]
