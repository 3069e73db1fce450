"""Each request's folder is removed once its time-to-live has passed (never while it
runs), or at once when it is cancelled, everything at close, and the upload folder's
leftovers after the time-to-live; only files the server received as uploads are read;
a request's files are found only by the tokens they were published under."""

from __future__ import annotations

import os
import time

import pytest
from conftest import wait_for

from photo3d.errors import InputError
from photo3d.ui.workspace import TOKEN, Workspace, check_upload


class Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def test_a_finished_request_is_removed_after_its_ttl_and_not_before(tmp_path):
    clock = Clock()
    ws = Workspace(tmp_path / "ws", ttl=60, clock=clock)
    with ws.request() as first:
        (first / "mesh.glb").write_bytes(b"glTF")
    clock.now += 30
    with ws.request() as second:
        pass
    assert ws.sweep() == 0 and first.exists()
    clock.now += 31  # 61 s after the first ended, 31 s after the second
    assert ws.sweep() == 1
    assert not first.exists() and second.exists()
    clock.now += 30
    assert ws.sweep() == 1 and not second.exists()
    ws.close()
    assert not ws.root.exists()


def test_a_running_request_is_never_swept_and_its_ttl_starts_at_its_end(tmp_path):
    clock = Clock()
    ws = Workspace(tmp_path / "ws", ttl=10, clock=clock)
    with ws.request() as folder:
        clock.now += 1000  # a long request
        assert ws.sweep() == 0 and folder.exists()
    clock.now += 9
    assert ws.sweep() == 0 and folder.exists()
    clock.now += 2
    assert ws.sweep() == 1 and not folder.exists()
    ws.close()


def test_the_ttl_also_starts_when_a_request_fails(tmp_path):
    clock = Clock()
    ws = Workspace(tmp_path / "ws", ttl=5, clock=clock)
    with pytest.raises(RuntimeError), ws.request() as folder:
        raise RuntimeError("boom")
    clock.now += 6
    assert ws.sweep() == 1 and not folder.exists()
    ws.close()


def test_the_sweeper_thread_removes_expired_folders_and_close_removes_the_rest(tmp_path):
    ws = Workspace(tmp_path / "ws", ttl=0.2)
    ws.start_sweeper(every=0.05)
    with ws.request() as expiring:
        (expiring / "a.zip").write_bytes(b"PK")
    assert wait_for(lambda: not expiring.exists(), timeout=10)
    with ws.request() as kept:
        ws.ttl = 3600  # folders made from now on stay until close
    ws.close()
    assert not kept.exists() and not ws.root.exists()


@pytest.fixture
def uploads(tmp_path):
    root = tmp_path / "uploads"
    (root / "ab12").mkdir(parents=True)
    (root / "ab12" / "photo.png").write_bytes(b"x" * 100)
    return root


def test_an_upload_inside_the_upload_folder_is_accepted(uploads):
    found = check_upload(uploads / "ab12" / "photo.png", upload_root=uploads, max_bytes=100)
    assert found == (uploads / "ab12" / "photo.png").resolve()


@pytest.mark.parametrize(("make", "message"), [
    (lambda root, outside: outside, "the photo was not uploaded to this server"),
    (lambda root, outside: root / "ab12" / ".." / ".." / outside.name,
     "the photo was not uploaded to this server"),
    (lambda root, outside: _link(root / "link.png", outside),
     "the photo was not uploaded to this server"),
    (lambda root, outside: _link(root / "inner.png", root / "ab12" / "photo.png"),
     "the photo upload is a symbolic link"),
    (lambda root, outside: root / "ab12", "the photo upload is not a regular file"),
    (lambda root, outside: root / "ab12" / "gone.png", "the photo upload is gone"),
    (lambda root, outside: _big(root / "ab12" / "big.png"),
     "the photo is 101 bytes; this server accepts at most 100 bytes"),
])
def test_anything_else_is_refused_in_one_line(uploads, tmp_path, make, message):
    outside = tmp_path / "secret.txt"
    outside.write_text("secret")
    with pytest.raises(InputError) as err:
        check_upload(make(uploads, outside), upload_root=uploads, max_bytes=100)
    assert str(err.value).startswith(message) and "\n" not in str(err.value)


def test_another_requests_results_are_not_an_upload(uploads):
    ws = Workspace(uploads / "photo3d-ui-test", ttl=60)  # inside the upload folder
    with ws.request() as folder:
        (folder / "mesh.glb").write_bytes(b"glTF")
        with pytest.raises(InputError, match="not uploaded to this server"):
            check_upload(folder / "mesh.glb", upload_root=uploads, workspace=ws,
                         max_bytes=100)
    ws.close()


def _link(link, target):
    os.symlink(target, link)
    return link


def _big(path):
    path.write_bytes(b"x" * 101)
    return path


def test_a_killed_servers_root_is_removed_by_the_next_and_a_live_one_is_kept(tmp_path):
    import signal
    import subprocess
    import sys

    from photo3d.ui.workspace import remove_stale

    child = subprocess.Popen(
        [sys.executable, "-c",
         "import sys, time; from photo3d.ui.workspace import Workspace; "
         f"ws = Workspace({str(tmp_path)!r} + '/photo3d-ui-00112233aabbccdd', ttl=60); "
         "(ws.root / 'request-x').mkdir(); print('ready', flush=True); time.sleep(120)"],
        stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "ready"
        root = tmp_path / "photo3d-ui-00112233aabbccdd"
        assert remove_stale(tmp_path) == [] and root.is_dir()  # its server is alive
        child.send_signal(signal.SIGKILL)
        child.wait(timeout=30)
        assert root.is_dir()  # SIGKILL: no clean-up ran
        assert remove_stale(tmp_path) == [root] and not root.exists()
    finally:
        child.kill()
        child.wait()
        child.stdout.close()


def test_uploads_live_in_the_workspace_and_requests_results_are_not_uploads(tmp_path):
    ws = Workspace(tmp_path / "ws", ttl=60)
    assert ws.uploads == ws.root / "uploads" and ws.uploads.is_dir()
    (ws.uploads / "ab12").mkdir()
    (ws.uploads / "ab12" / "photo.png").write_bytes(b"x")
    assert check_upload(ws.uploads / "ab12" / "photo.png", upload_root=ws.uploads,
                        workspace=ws, max_bytes=10).name == "photo.png"
    with ws.request() as folder:
        assert len(folder.name) == len("request-") + 32  # 128 random bits
        (folder / "mesh.glb").write_bytes(b"glTF")
        for path in (folder / "mesh.glb", ws.root / ".photo3d-ui.lock"):
            with pytest.raises(InputError, match="not uploaded to this server"):
                check_upload(path, upload_root=ws.root, workspace=ws, max_bytes=100)
    ws.close()


def test_only_published_files_are_found_by_their_token_until_their_folder_goes(tmp_path):
    clock = Clock()
    ws = Workspace(tmp_path / "ws", ttl=10, clock=clock)
    with ws.request() as folder:
        (folder / "out").mkdir()
        (folder / "out" / "mesh.glb").write_bytes(b"glTF")
        (folder / "out" / "photo3d.npz").write_bytes(b"PK")
        token = ws.publish(folder / "out" / "mesh.glb")
    assert TOKEN.fullmatch(token) and ws.published(token) == folder / "out" / "mesh.glb"
    assert ws.publish(folder / "out" / "mesh.glb") != token  # a new token each time
    with pytest.raises(ValueError):
        ws.publish(ws.root / ".photo3d-ui.lock")  # only a request's files
    clock.now += 11
    assert ws.sweep() == 1 and ws.published(token) is None


def test_a_discarded_request_is_removed_at_once_with_what_it_published(tmp_path):
    ws = Workspace(tmp_path / "ws", ttl=3600)
    with ws.request() as folder:
        (folder / "a.zip").write_bytes(b"PK")
        token = ws.publish(folder / "a.zip")
        ws.discard(folder)
        assert not folder.exists() and ws.published(token) is None
    assert ws.sweep(now=ws.clock() + 7200) == 0  # not scheduled again
    ws.close()


def test_the_upload_folders_leftovers_go_after_the_ttl(tmp_path):
    ws = Workspace(tmp_path / "ws", ttl=5)
    old = time.time() - 60
    empty, kept, fresh = (ws.uploads / name for name in ("a" * 64, "b" * 64, "c" * 64))
    for folder in (empty, kept, fresh):
        folder.mkdir()
    (kept / "photo.png").write_bytes(b"x")  # an upload the framework still holds
    partial = ws.uploads / "tmpab12cd34"  # an aborted upload's partial file
    partial.write_bytes(b"")
    for path in (empty, kept, partial):
        os.utime(path, (old, old))
    ws.sweep()
    assert sorted(p.name for p in ws.uploads.iterdir()) == ["b" * 64, "c" * 64]
    ws.close()
    assert not tmp_path.joinpath("ws").exists()
