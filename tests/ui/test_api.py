"""The ``/make`` API with Gradio's own client: the sample and its depth give a valid
GLB and zip; hostile requests get one line (and leave no traceback in the server's
log) and never make the server read a file of its choosing; results are addresses,
and only they are served; a cancelled request stops and its folder goes; two clients
at once each get their own result, in queue order; only this machine's and the
configured host names are answered."""

from __future__ import annotations

import json
import secrets
import socket
import threading
import time
import zipfile

import numpy as np
import pytest
from conftest import wait_for
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
    glb, bundle, preview, videos = client(server, tmp_path).predict(  # four, as before
        photo=handle(photo), depth=handle(depth), size=256, paths=["swing"], api_name="/make")
    check_glb(glb, min_faces=1000)
    names = check_zip(bundle, videos=("swing",))
    with zipfile.ZipFile(bundle) as z:  # the splats reach the API in the zip
        splats = tmp_path / "splats.spz"
        splats.write_bytes(z.read("splats.spz"))
        (tmp_path / "photo3d.npz").write_bytes(z.read("photo3d.npz"))
    # the adaptive splats of the 3D photo in the zip, hidden layers included
    assert len(read_spz(splats)) == len(build_splats(load_npz(tmp_path / "photo3d.npz")[0]))
    assert "mesh.ply" not in names  # off unless asked for
    with zipfile.ZipFile(bundle) as z:
        assert b'"size": 256' in z.read("config.json")
    with Image.open(preview) as im:
        # the depth map at the size the photo was read at: the photo's, or about
        # twice the working size for a photo more than twice as large (issue 36)
        w, h = im.size
        assert 2 * 256 <= max(w, h) <= 741 and abs(w / h - 741 / 500) < 0.01
    assert len(videos) == 1 and videos[0].endswith("swing.mp4")


@pytest.mark.parametrize(("kind", "options", "message"), [
    ("garbage", {}, "cannot read image photo.png: not a recognised image format"),
    ("bomb", {}, "decompression bomb"),
    ("photo", {"paths": ["/etc/passwd"]}, "'/etc/passwd'"),
    ("photo", {"size": 10**6}, "size must be 0 (the photo's size) or 64..2048, got 1000000"),
    ("photo", {"size": 4096}, "size must be 0 (the photo's size) or 64..2048, got 4096"),
    ("photo", {"videos": "no"}, "videos must be true or false, got 'no'"),
    ("photo", {"paths": ["swing"] * 20}, "paths must be a list of at most 16 camera paths"),
    ("photo", {"fill": {"x": 1}}, "unknown fill {'x': 1}"),
])
def test_hostile_requests_get_one_line(server, tmp_path, capfd, kind, options, message):
    photo = tmp_path / "photo.png"
    photo.write_bytes(b"not a photo at all")
    if kind == "bomb":
        png_bomb(photo)
    if kind == "photo":
        Image.new("RGB", (64, 48), "gray").save(photo)
    capfd.readouterr()
    options = {"size": 256, **options}  # small: the memory check passes on a busy machine
    with pytest.raises(gradio_client.exceptions.AppError) as err:
        client(server, tmp_path).predict(photo=gradio_client.handle_file(photo),
                                         api_name="/make", **options)
    text = str(err.value)
    assert message in text and "\n" not in text.strip()
    assert str(server.workspace.root.parent) not in text  # no server folder
    assert "Traceback" not in capfd.readouterr().err  # the server's log


def call(server, data) -> tuple[str, str]:
    """``(event, data)`` of the last message of a raw ``/gradio_api/call/make``."""
    with httpx.Client(base_url=server.url, timeout=120) as http:
        event = http.post("gradio_api/call/make", json={"data": data}).json()["event_id"]
        reply = http.get(f"gradio_api/call/make/{event}").text
    kind, _, payload = reply.strip().rpartition("event: ")[2].partition("\ndata: ")
    return kind, payload


def uploaded(server, path) -> dict:
    """``path`` uploaded, as the FileData a client sends back."""
    with httpx.Client(base_url=server.url, timeout=60) as http:
        (stored,) = http.post("gradio_api/upload",
                              files={"files": (path.name, path.read_bytes())}).json()
    return {"path": stored, "orig_name": path.name, "meta": {"_type": "gradio.FileData"}}


def test_malformed_requests_get_one_line_and_leave_no_traceback(server, tmp_path, capfd):
    photo = tmp_path / "photo.png"
    Image.new("RGB", (64, 48), "gray").save(photo)
    sent = uploaded(server, photo)
    rest = [None, None, 256, "diffusion", "auto", "disparity", False, ["circle"], False,
            "align"]
    capfd.readouterr()
    for data, message in [
        ([sent], "bad request: An event handler (make) didn't receive enough input values "
                 "(needed: 11, got: 1)."),
        ([sent["path"], *rest], "bad request: a file must be sent as an uploaded file"),
        ([{**sent, "path": "/etc/passwd"}, *rest],
         "bad request: a file was not uploaded to this server"),
        ([{"name": "x"}, *rest], "bad request: a file must be sent as an uploaded file"),
        ([sent, *rest[:2], {"size": 1}, *rest[3:]],
         "size must be 0 (the photo's size) or 64..2048, got {'size': 1}"),
    ]:
        kind, payload = call(server, data)
        assert kind == "error" and json.loads(payload)["error"].startswith(message), payload
    assert "Traceback" not in capfd.readouterr().err


def test_the_events_of_an_unknown_session_leave_no_traceback(server, capfd):
    capfd.readouterr()
    with httpx.Client(base_url=server.url, timeout=60) as http:
        reply = http.get("gradio_api/queue/data", params={"session_hash": "nobody"})
        assert reply.status_code == 200  # Gradio's stream had started: it just ends
        assert http.get("config").status_code == 200  # and the server serves on
    assert "Traceback" not in capfd.readouterr().err


def test_results_are_addresses_and_only_they_are_served(server, sample, tmp_path):
    photo, depth = sample
    data = [uploaded(server, photo), uploaded(server, depth), None, 256, "diffusion", "auto",
            "disparity", False, ["circle"], False, "align"]
    kind, payload = call(server, data)
    assert kind == "complete"
    for folder in (server.workspace.root, server.workspace.root.parent):
        assert str(folder) not in payload  # no path of the server in the result
    glb, bundle, preview, videos = json.loads(payload)
    assert videos == []
    token = glb["url"].split("/")[-2]
    request = server.workspace.published(token).parents[1]
    with httpx.Client(base_url=server.url, timeout=60) as http:
        for value, path in ((glb, "out/mesh.glb"), (bundle, "sample-3d.zip"),
                            (preview, "depth_preview.png")):
            assert value["path"] == value["url"]
            assert value["url"].startswith(f"{server.url}photo3d/file/")
            assert http.get(value["url"]).content == (request / path).read_bytes()
            # Gradio's client asks Gradio's file route for the same address
            via = http.get("gradio_api/file=" + value["url"].replace(":", "%3A"))
            assert via.content == (request / path).read_bytes()
        never = [request / "out" / "photo3d.npz", request / "out" / "mesh.glb",
                 server.workspace.root / ".photo3d-ui.lock"]
        for path in never:  # by their paths: nothing (not even a returned file)
            assert http.get(f"gradio_api/file={path}").status_code in (403, 404), path
        name = glb["url"].rsplit("/", 1)[1]
        for url in (f"photo3d/file/{secrets.token_urlsafe(16)}/{name}",  # another token
                    glb["url"].replace(name, "photo3d.npz"),  # another file of the request
                    "photo3d/file/", "photo3d/secret"):
            assert http.get(url).status_code == 404, url
        assert http.post(glb["url"]).status_code == 405


def test_a_cancelled_request_stops_and_the_next_one_runs(server, sample, tmp_path):
    photo, depth = sample
    handle = gradio_client.handle_file
    before = set(server.workspace.root.glob("request-*"))
    first = client(server, tmp_path / "a").submit(photo=handle(photo), depth=handle(depth),
                                                  size=512, paths=["circle"],
                                                  api_name="/make")
    assert wait_for(lambda: server.runner.making == 1, timeout=120)
    second = client(server, tmp_path / "b").submit(photo=handle(photo), depth=handle(depth),
                                                   size=256, videos=False, api_name="/make")
    seen = []
    first.cancel()
    assert wait_for(lambda: seen.append(server.runner.making) or second.done(), timeout=300)
    second.result(timeout=10)  # made: its own cancel event was never set
    assert max(seen) == 1  # the cancelled one stopped before the next began
    made = set(server.workspace.root.glob("request-*")) - before
    assert len(made) == 1  # the second's; the first's was removed


def test_a_path_the_client_names_is_never_opened(server, tmp_path):
    secret = tmp_path / "secret.png"
    Image.new("RGB", (64, 48), "red").save(secret)  # a valid photo, outside the uploads
    fake = {"path": str(secret), "meta": {"_type": "gradio.FileData"}, "orig_name": "p.png"}
    data = [fake, None, None, 256, "diffusion", "auto", "disparity", False, ["circle"], False,
            "align"]
    before = set(server.workspace.root.glob("request-*"))
    with httpx.Client(base_url=server.url, timeout=60) as http:
        event = http.post("gradio_api/call/make", json={"data": data}).json()["event_id"]
        reply = http.get(f"gradio_api/call/make/{event}").text
    assert "event: error" in reply and "event: complete" not in reply
    assert "a file was not uploaded to this server" in reply
    assert set(server.workspace.root.glob("request-*")) == before  # no request started


def test_uploads_beyond_the_byte_limit_are_refused(server):
    with httpx.Client(base_url=server.url, timeout=60) as http:
        reply = http.post("gradio_api/upload",
                          files={"files": ("big.png", b"\0" * (MAX_UPLOAD + 1), "image/png")})
    assert reply.status_code == 413


def test_a_page_of_another_site_cannot_upload_or_call(server):
    """A browser sends a cross-site multipart upload without asking first (it only
    hides the answer): any page the user visited could fill the server's disk."""
    port = server.options.port
    uploads = server.workspace.uploads
    before = sorted(uploads.rglob("*"))
    with httpx.Client(base_url=server.url, timeout=60) as http:
        for origin in ("https://evil.example", f"http://evil.example:{port}", "null"):
            for route in ("gradio_api/upload", "gradio_api/call/make", "gradio_api/queue/join"):
                reply = http.post(route, headers={"Origin": origin},
                                  files={"files": ("cross.png", b"cross-site")})
                assert reply.status_code == 403, (origin, route)
                assert reply.text.startswith("Forbidden: a page of another site")
        assert sorted(uploads.rglob("*")) == before
        for origin in (f"http://127.0.0.1:{port}", f"http://localhost:{port}", None):
            headers = {} if origin is None else {"Origin": origin}
            reply = http.post("gradio_api/upload", headers=headers,
                              files={"files": ("same.png", b"same-site")})
            assert reply.status_code == 200, origin


def test_two_clients_at_once_each_get_their_own_result_in_queue_order(server, sample,
                                                                      tmp_path, monkeypatch):
    first_photo, depth = sample
    second_photo = tmp_path / "grey.png"
    rng = np.random.default_rng(1)
    Image.fromarray(rng.integers(0, 255, (96, 128, 3), np.uint8)).save(second_photo)
    second_depth = tmp_path / "grey_depth.png"
    Image.fromarray(np.tile(np.arange(128, dtype=np.uint16) * 500, (96, 1))).save(second_depth)
    handle = gradio_client.handle_file
    common = dict(size=256, videos=False, api_name="/make")
    # the first request holds the worker until the second is seen in the queue: a make
    # of 256 px may otherwise end before the second is submitted
    with first_request_held(monkeypatch) as (gate, calls):
        first = client(server, tmp_path / "a").submit(photo=handle(first_photo),
                                                      depth=handle(depth), **common)
        states = []
        second = client(server, tmp_path / "b").submit(photo=handle(second_photo),
                                                       depth=handle(second_depth), **common)
        done = threading.Event()

        def watch():  # either may reach the server first (each client connects on a
            while not done.is_set():  # thread of its own): the other one queues
                states.extend(job.status().code.name for job in (first, second))
                if "IN_QUEUE" in states[-2:]:
                    gate.set()
                time.sleep(0.02)

        watcher = threading.Thread(target=watch)
        watcher.start()
        try:
            results = [first.result(timeout=300), second.result(timeout=300)]
        finally:
            done.set()
            watcher.join()
    assert "IN_QUEUE" in states and len(calls) == 2  # one waited for the one worker
    sizes = []
    for (_, bundle, preview, _), stem in zip(results, ("sample", "grey"), strict=True):
        assert bundle.endswith(f"{stem}-3d.zip")
        check_zip(bundle)
        with Image.open(preview) as im:
            sizes.append(im.size)
    (w, h), grey = sizes  # each request's own depth map (the sample's possibly reduced)
    assert max(w, h) <= 741 and abs(w / h - 741 / 500) < 0.01 and grey == (128, 96)


def test_the_page_is_served_on_loopback_without_a_share_link(server):
    assert server.url.startswith("http://127.0.0.1:")
    assert server.demo.share is False and server.demo.share_url is None
    with httpx.Client(base_url=server.url, timeout=60) as http:
        assert http.get("/").status_code == 200
        assert http.get("monitoring").status_code in (403, 404)


def test_the_page_says_what_the_learned_fill_downloads(server):
    with httpx.Client(base_url=server.url, timeout=60) as http:
        config = http.get("config").text
    assert "the first use downloads the authors' weights (about 460 MB)" in config


def test_only_this_machines_names_are_answered(server):
    port = server.options.port
    with httpx.Client(base_url=server.url, timeout=60) as http:
        for host in (f"127.0.0.1:{port}", f"localhost:{port}", f"[::1]:{port}", "localhost"):
            assert http.get("/", headers={"Host": host}).status_code == 200, host
        for host in ("evil.example.com", f"evil.example.com:{port}", f"10.0.0.5:{port}"):
            for method, route in (("GET", "/"), ("GET", "config"), ("POST", "gradio_api/upload"),
                                  ("POST", "gradio_api/call/make"),
                                  ("GET", "gradio_api/file=/etc/hostname")):
                reply = http.request(method, route, headers={"Host": host,
                                                             "Origin": f"http://{host}"})
                assert reply.status_code == 421, (host, route)
                assert reply.text.startswith("Misdirected Request")
    with socket.create_connection(("127.0.0.1", port), timeout=30) as conn:  # no Host at all
        conn.sendall(b"GET / HTTP/1.0\r\n\r\n")
        assert conn.recv(100).startswith(b"HTTP/1.1 400")


def test_an_ipv6_loopback_address_is_served(tmp_path):
    try:
        socket.socket(socket.AF_INET6).close()
    except OSError:
        pytest.skip("no IPv6 on this machine")
    with running(host="::1", warmup=False) as server:
        assert server.url.startswith("http://[::1]:")
        with httpx.Client(base_url=server.url, timeout=60) as http:
            assert http.get("/").status_code == 200


def test_with_a_login_the_page_the_api_and_the_results_need_it(tmp_path):
    with running(auth=("ana", "s3cret"), warmup=False, allowed_hosts=("photos.lan",)) as server:
        with server.workspace.request() as folder:
            (folder / "a.zip").write_bytes(b"PK")
            url = f"photo3d/file/{server.workspace.publish(folder / 'a.zip')}/a.zip"
        with httpx.Client(base_url=server.url, timeout=60) as http:
            assert http.get("config").status_code == 401
            for page in ("openapi.json", "docs", "redoc"):  # issue 45: served to anyone
                assert http.get(page).status_code == 401, page
            assert http.post("gradio_api/upload",
                             files={"files": ("a.png", b"x", "image/png")}).status_code == 401
            assert http.get(url).status_code == 401
            assert http.get("config", headers={"Host": "photos.lan:80"}).status_code == 401
            assert http.get("config", headers={"Host": "other.lan"}).status_code == 421
            assert http.post("login", data={"username": "ana",
                                                       "password": "s3cret"}).status_code == 200
            assert http.get(url).content == b"PK"  # logged in
        with pytest.raises(gradio_client.exceptions.AuthenticationError):
            gradio_client.Client(server.url, verbose=False, download_files=str(tmp_path))
        api = gradio_client.Client(server.url, auth=("ana", "s3cret"), verbose=False,
                                   download_files=str(tmp_path))
        assert "/make" in api.view_api(print_info=False, return_format="dict")[
            "named_endpoints"]
