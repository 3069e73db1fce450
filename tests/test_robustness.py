"""What photo3d promises about bad inputs and output folders (README "Inputs").

Every case checks the exit status, that the message is one line without a
traceback, that no file that existed before is lost or changed, and that nothing
partial (no hidden temporary folder, no half-written output) is left behind.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import two_planes
from PIL import Image

import photo3d
from photo3d.cli import main
from photo3d.errors import OutputError
from photo3d.files.staging import stage_output
from photo3d.pipeline import make as make_photo  # before any test patches it

SRC = str(Path(photo3d.__file__).parents[1])
FAST = ["--size", "48", "--no-video", "--no-glb", "--no-viewer", "-q"]


@pytest.fixture
def photos(tmp_path, monkeypatch):
    """``tmp/photos/{a.png, a.npy, notes.txt}``; the current folder is ``tmp``."""
    folder = tmp_path / "photos"
    folder.mkdir()
    img, d = two_planes(48, 64, 32)
    Image.fromarray((img * 255).astype(np.uint8)).save(folder / "a.png")
    np.save(folder / "a.npy", d)
    (folder / "notes.txt").write_text("my notes")
    monkeypatch.chdir(tmp_path)
    return folder


def snapshot(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` (relative path -> content)."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


def leftovers(root: Path) -> list[str]:
    """Temporary files or folders of photo3d anywhere under ``root``."""
    return [str(p) for p in root.rglob(".*")
            if p.name.endswith((".tmp", ".old", ".part")) or ".tmp." in p.name]


def run(capsys, *argv, status: int, message: str = "", root: Path | None = None) -> str:
    """Run the CLI in-process; check status, one line, no loss, nothing partial."""
    root = root or Path.cwd()
    before = snapshot(root)
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err.strip()
    assert code == status, err
    after = snapshot(root)
    lost = {k for k, v in before.items() if after.get(k) != v}
    assert not lost or status == 0, f"lost or changed: {lost}"
    assert not leftovers(root)
    if status != 0:
        assert len(err.splitlines()) == 1 and "Traceback" not in err, err
        assert message in err, err
        assert set(after) == set(before), "a failed run wrote files"
    return err


def make(photos: Path, out, *extra) -> list:
    return ["make", photos / "a.png", "--depth", photos / "a.npy", "-o", out, *FAST, *extra]


# --- data loss ---------------------------------------------------------------------------


@pytest.mark.parametrize("out", ["photos", ".", "photos/..", "..", "photos/sub/../.."])
def test_overwrite_never_deletes_inputs_the_cwd_or_its_parents(photos, capsys, out):
    msg = "holds the input" if out == "photos" else "current folder"
    run(capsys, *make(photos, out, "--overwrite"), status=2, message=msg,
        root=photos.parent)


def test_overwrite_only_replaces_a_folder_photo3d_wrote(photos, capsys):
    mine = photos.parent / "mine"
    mine.mkdir()
    (mine / "mesh.ply").write_text("my own mesh")  # a photo3d name, but not photo3d's folder
    run(capsys, *make(photos, "mine", "--overwrite"), status=2,
        message="only replaces a folder photo3d wrote")
    run(capsys, *make(photos, "out"), status=0)
    first = (photos.parent / "out" / "photo3d.npz").stat().st_ino
    run(capsys, *make(photos, "out"), status=2, message="not empty (use --overwrite)")
    (photos.parent / "out" / "notes.txt").write_text("added by the user")
    run(capsys, *make(photos, "out", "--overwrite"), status=2, message="holds notes.txt")
    (photos.parent / "out" / "notes.txt").unlink()
    run(capsys, *make(photos, "out", "--overwrite"), status=0)
    assert (photos.parent / "out" / "photo3d.npz").stat().st_ino != first
    assert sorted(os.listdir(photos.parent)) == ["mine", "out", "photos"]


def test_a_symlinked_output_is_written_into_its_target(photos, capsys):
    target = photos.parent / "target"
    (photos.parent / "link").symlink_to(target.name)
    run(capsys, *make(photos, "link"), status=2, message="symbolic link to target, which "
        "does not exist")
    target.mkdir()
    run(capsys, *make(photos, "link"), status=0)
    run(capsys, *make(photos, "link", "--overwrite"), status=0)
    assert (photos.parent / "link").is_symlink()
    assert (target / "photo3d.npz").is_file()
    photo3d.load(photos.parent / "link")


def test_output_folders_respect_the_umask(photos, capsys):
    for mask in (0o022, 0o002):
        old = os.umask(mask)
        try:
            run(capsys, *make(photos, f"out{mask}"), status=0)
        finally:
            os.umask(old)
        assert (photos.parent / f"out{mask}").stat().st_mode & 0o777 == 0o777 & ~mask


def test_the_final_rename_is_checked(tmp_path):
    """A folder that appears or changes while the run works is never replaced."""
    out = tmp_path / "out"
    with stage_output(out) as staging:
        out.mkdir()
        (out / "theirs.txt").write_text("another run")
        with pytest.raises(OutputError, match="changed while photo3d was working"):
            staging.commit()
    assert sorted(os.listdir(tmp_path)) == ["out"]
    assert (out / "theirs.txt").read_text() == "another run"


def _cli(*argv, cwd: Path, **kwargs) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": SRC}
    return subprocess.Popen([sys.executable, "-m", "photo3d", *map(str, argv)], cwd=cwd,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, **kwargs)


def finish(proc: subprocess.Popen, timeout: float = 120) -> tuple[int, str]:
    """``(exit status, stderr)`` of a finished :func:`_cli` process."""
    _, err = proc.communicate(timeout=timeout)
    return proc.returncode, err.strip()


def test_concurrent_runs_to_the_same_output(photos):
    procs = [_cli(*make(photos, "same"), cwd=photos.parent) for _ in range(2)]
    results = sorted(finish(p) for p in procs)
    assert [code for code, _ in results] == [0, 2], results
    err = results[1][1]
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert "another run" in err or "not empty" in err
    assert not leftovers(photos.parent)
    photo3d.load(photos.parent / "same")


@pytest.mark.parametrize(("sig", "status"), [(signal.SIGINT, 130), (signal.SIGTERM, 143),
                                             (signal.SIGHUP, 129)])
def test_signals_while_rendering_videos_leave_nothing(photos, sig, status):
    """Ctrl-C (or SIGTERM/SIGHUP) inside the numba rasterizer: one line, no temp folder."""
    proc = _cli("make", photos / "a.png", "--depth", photos / "a.npy", "-o", "out",
                "--size", "64", "--frames", "2000", "--video-size", "320x240", "-q",
                cwd=photos.parent)
    deadline = time.monotonic() + 180
    while not list(photos.parent.glob(".out.*.tmp/video/.*.part")):
        assert proc.poll() is None and time.monotonic() < deadline, finish(proc)
        time.sleep(0.05)
    time.sleep(0.3)
    proc.send_signal(sig)
    code, err = finish(proc)
    assert code == status and err.startswith("photo3d: interrupted"), err
    assert len(err.splitlines()) == 1
    assert sorted(os.listdir(photos.parent)) == ["photos"]


# --- the output location is checked before the work ------------------------------------


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if the pipeline starts."""
    def refuse(*args, **kwargs):
        raise AssertionError("the pipeline ran before the output was checked")

    monkeypatch.setattr("photo3d.pipeline.make", refuse)


def test_unwritable_outputs_are_refused_before_the_work(photos, capsys, no_work):
    (photos.parent / "file").write_text("a file")
    run(capsys, *make(photos, "file/out"), status=2, message="not a folder")
    run(capsys, *make(photos, "file"), status=2, message="exists and is not a folder")
    run(capsys, *make(photos, "x" * 256), status=2, message="File name too long")
    run(capsys, *make(photos, "/proc/photo3d-out"), status=2, message="cannot write in /proc")


def _mount_tmpfs(path: Path, options: str) -> bool:
    path.mkdir()
    if os.geteuid() != 0 or not shutil.which("mount"):
        return False
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(path)],
                          capture_output=True, check=False)
    return done.returncode == 0


@pytest.mark.parametrize(("options", "message"), [("ro,size=1m", "Read-only file system"),
                                                  ("size=64k", "MB free")])
def test_read_only_and_full_file_systems(photos, capsys, no_work, options, message):
    mnt = photos.parent / "mnt"
    if not _mount_tmpfs(mnt, options):
        pytest.skip("needs root to mount a small tmpfs")
    try:
        run(capsys, *make(photos, mnt / "out"), status=2, message=message)
    finally:
        subprocess.run(["umount", str(mnt)], check=True)


def test_a_disk_that_fills_up_during_the_run(photos, capsys, monkeypatch):
    """The estimate can be wrong: running out of space mid-way is one line too."""
    mnt = photos.parent / "mnt"
    if not _mount_tmpfs(mnt, "size=200k"):
        pytest.skip("needs root to mount a small tmpfs")
    monkeypatch.setattr("photo3d.cli.make.output_bytes", lambda *a: 0)
    try:
        run(capsys, "make", photos / "a.png", "--depth", photos / "a.npy", "-o", mnt / "o",
            "--size", "256", "-q", "--no-video", status=2, message="No space left on device")
        assert os.listdir(mnt) == []
    finally:
        subprocess.run(["umount", str(mnt)], check=True)


def test_a_parent_without_write_permission(photos):
    import tempfile

    base = Path(tempfile.mkdtemp())  # outside pytest's 0700 folder: readable by nobody
    try:
        _unwritable_parent(photos, base)
    finally:
        shutil.rmtree(base)


def _unwritable_parent(photos: Path, base: Path) -> None:
    shutil.copytree(photos, base / "photos")
    locked, cache = base / "locked", base / "numba-cache"
    locked.mkdir()
    cache.mkdir()
    prefix = []
    if os.geteuid() == 0:  # root writes anywhere: run as nobody
        if not shutil.which("setpriv"):
            pytest.skip("needs setpriv to drop root")
        prefix = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"]
    for p in [base, *base.rglob("*")]:
        p.chmod(0o755 if p.is_dir() else 0o644)
    locked.chmod(0o555)
    cache.chmod(0o777)
    env = {**os.environ, "PYTHONPATH": SRC, "NUMBA_CACHE_DIR": str(cache)}
    proc = subprocess.run([*prefix, sys.executable, "-m", "photo3d",
                           *map(str, make(base / "photos", locked / "out"))], cwd=base,
                          env=env, capture_output=True, text=True, check=False, timeout=120)
    err = proc.stderr.strip()
    assert proc.returncode == 2 and len(err.splitlines()) == 1, err
    assert "Permission denied" in err
    assert os.listdir(locked) == []


# --- hostile and broken input files: one line, never a traceback -------------------------


def _png_header_only(width: int, height: int) -> bytes:
    """A PNG that declares ``width x height`` grey pixels but holds almost no data."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0"))
            + chunk(b"IEND", b""))


def _tiff_header_only(width: int, height: int, bits: int) -> bytes:
    """A little-endian float TIFF that declares ``width x height`` but holds 8 bytes."""
    import struct

    tags = [(256, 4, width), (257, 4, height), (258, 3, bits), (259, 3, 1), (262, 3, 1),
            (273, 4, 8), (277, 3, 1), (278, 4, height), (279, 4, 8), (339, 3, 3)]
    ifd = struct.pack("<H", len(tags)) + b"".join(
        struct.pack("<HHII", tag, kind, 1, value) if kind == 4
        else struct.pack("<HHIHH", tag, kind, 1, value, 0) for tag, kind, value in tags)
    return b"II*\x00" + struct.pack("<I", 16) + b"\0" * 8 + ifd + b"\0\0\0\0"


def _npy_header_only(shape: tuple[int, ...]) -> bytes:
    import io

    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f4", "fortran_order": False,
                                               "shape": shape})
    return buf.getvalue() + b"\0" * 16


DEPTH_FILES = {
    "bomb.png": (_png_header_only(100_000, 100_000), "decompression bomb"),
    "bomb.tif": (_tiff_header_only(100_000, 100_000, 32), "decompression bomb"),
    "bomb64.tif": (_tiff_header_only(100_000, 100_000, 64), "decompression bomb"),
    "short.png": (b"\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR", "not a complete PNG"),
    "huge.npy": (_npy_header_only((100_000, 100_000)), "at most"),
    "truncated.npy": (_npy_header_only((480, 640)), "truncated"),
    "text.npy": (b"just some text\n", "not a .npy array"),
    "empty.pfm": (b"", "not a PFM file"),
    "bomb.pfm": (b"Pf\n100000 100000\n-1.0\n" + b"\0" * 64, "truncated"),
}


@pytest.mark.parametrize("name", sorted(DEPTH_FILES))
def test_hostile_depth_files(photos, capsys, no_work, name):
    data, message = DEPTH_FILES[name]
    (photos / name).write_bytes(data)
    run(capsys, "make", photos / "a.png", "--depth", photos / name, "-o", "out", *FAST,
        status=2, message=message)


def test_folders_and_odd_files_as_inputs(photos, capsys, no_work):
    run(capsys, "make", photos, "--depth", photos / "a.npy", "-o", "out", status=2,
        message="it is a folder")
    run(capsys, "make", photos / "a.png", "--depth", photos, "-o", "out", status=2,
        message="depth file not found")
    run(capsys, "make", photos / "notes.txt", "--depth", photos / "a.npy", "-o", "out",
        status=2, message="not a recognised image format")
    (photos / "bomb.png").write_bytes(_png_header_only(100_000, 100_000))
    run(capsys, "make", photos / "bomb.png", "--depth", photos / "a.npy", "-o", "out",
        status=2, message="decompression bomb")


def _saved(photos: Path, capsys) -> Path:
    run(capsys, *make(photos, "saved"), status=0)
    return photos.parent / "saved"


def _rewrite_npz(path: Path, **changes) -> None:
    """Rewrite ``photo3d.npz`` with some arrays or header fields replaced."""
    import json

    from photo3d.io.npz import load_npz

    ldi, meta = load_npz(path)
    arrays = {k: getattr(ldi, k) for k in ("y", "x", "color", "disparity", "links", "label")}
    header = {"format": "photo3d-ldi", "version": 1,
              "intrinsics": [ldi.intrinsics.fx, ldi.intrinsics.fy, ldi.intrinsics.cx,
                             ldi.intrinsics.cy, ldi.intrinsics.width, ldi.intrinsics.height],
              "mapping": [ldi.mapping.scale, ldi.mapping.offset, ldi.mapping.floor],
              "border": ldi.border, "meta": meta}
    for key, value in changes.items():
        (arrays if key in arrays else header)[key] = value
    arrays["header"] = np.frombuffer(json.dumps(header).encode(), np.uint8)
    np.savez(path, **arrays)


def test_broken_saved_photos(photos, capsys):
    saved = _saved(photos, capsys)
    npz = saved / "photo3d.npz"
    good = npz.read_bytes()

    def check(message: str, *args: str) -> None:
        run(capsys, *(args or ("render", saved, "--still")), status=2, message=message)
        npz.write_bytes(good)

    npz.write_bytes(good[: len(good) // 2])
    check("not a photo3d file")  # truncated: the zip directory is gone
    npz.write_bytes(good[:200] + bytes(2000) + good[2200:])
    check("damaged or truncated")
    npz.write_bytes(os.urandom(4000))
    check("not a photo3d file", "view", saved, "--no-browser")
    (photos.parent / "text.npz").write_text("hello")
    # a file where the folder goes: said so (it was read as a photo3d.npz before)
    check("is a file: give the 3D photo's folder", "view", photos.parent / "text.npz",
          "--no-browser")
    from photo3d.io.npz import load_npz

    n = np.load(npz)["links"].shape[0]
    for changes, message in [
        ({"links": np.full((n, 4), n + 5, np.int32)}, "links point outside"),
        ({"links": np.roll(load_npz(npz)[0].links, 1, axis=0)}, "inconsistent links"),
        ({"intrinsics": [1e300, 1, 0, 0, 64, 48]}, "not plausible"),
        ({"intrinsics": [10, 10, 0, 0, 1e9, 48]}, "not between 1 and 65536"),
        ({"intrinsics": [float("nan"), 10, 0, 0, 64, 48]}, "not finite"),
        ({"color": np.zeros((n, 2), np.float32)}, "color has shape"),
        ({"y": np.zeros(n, np.float32)}, "y has shape"),
        ({"border": -3}, "border"),
        ({"format": "other"}, "not a photo3d file"),
        ({"version": 9}, "format version 9"),
    ]:
        _rewrite_npz(npz, **changes)
        check(message)
    with np.load(npz) as f:
        arrays = {k: f[k] for k in f.files}
    np.savez(npz, **{**arrays, "links": np.array([{"evil": 1}], dtype=object)})
    check("pickled")  # nothing is ever unpickled
    assert not (saved / "still.png").exists()


@pytest.mark.parametrize(("text", "message"), [
    ("[1, 2, 3]", "keyframe 0 is"),
    ('{"keyframes": 5}', "must hold a list"),
    ('[{"position": [0, 0]}]', "3-D positions"),
    ('[{"position": [NaN, 0, 0]}]', "3-D positions"),
    ('[{"position": [0, 0, 0], "rotation": "x"}]', "bad keyframe"),
    ("[]", "at least one keyframe"),
    ("{not json", "cannot parse"),
])
def test_bad_keyframe_files_are_refused_before_the_work(photos, capsys, no_work, text,
                                                        message):
    (photos / "path.json").write_text(text)
    run(capsys, *make(photos, "out")[:-len(FAST)], "--path", photos / "path.json",
        "--size", "48", "-q", status=2, message=message)


@pytest.mark.parametrize(("options", "message"), [
    (["--size", "5"], "size must be between"),
    (["--size", "-1"], "size must be between"),
    (["--fps", "0"], "fps"),
    (["--fps", "inf"], "fps"),
    (["--frames", "0"], "frames"),
    (["--ssaa", "0"], "ssaa"),
    (["--eye-separation", "nan"], "eye separation"),
    (["--video-size", "0x0"], "video size must be positive, got 0x0"),  # said "even"
    (["--video-size", "99999999x48"], "too large: at most 65536 pixels a side"),  # "even"
    (["--video-size", "3x4"], "video size must be even numbers, got 3x4"),
    (["--video-size", "abc"], "must look like"),
    (["--inpainter", "magic"], "unknown inpainter"),
    (["--weights", "nowhere"], "only apply to --inpainter learned"),
])
def test_bad_options_are_refused_before_the_work(photos, capsys, no_work, options, message):
    argv = ["make", photos / "a.png", "--depth", photos / "a.npy", "-o", "out", *options]
    before = snapshot(photos.parent)
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exit:  # argparse's own errors: usage line + message, status 2
        code = exit.code
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and message in err[-1] and "Traceback" not in "\n".join(err), err
    assert snapshot(photos.parent) == before and not leftovers(photos.parent)


def test_missing_extras_are_named_in_one_line(photos, capsys, monkeypatch, no_work):
    monkeypatch.setitem(sys.modules, "torch", None)
    monkeypatch.setitem(sys.modules, "moderngl", None)
    for name in [m for m in sys.modules if m.startswith("photo3d.nets")]:
        monkeypatch.delitem(sys.modules, name)
    run(capsys, *make(photos, "out", "--inpainter", "learned"), status=2,
        message="pip install 'photo3d[learned]'")
    run(capsys, *make(photos, "out")[:-len(FAST)], "--backend", "gl", status=2,
        message="pip install 'photo3d[gl]'")


def test_unicode_and_very_long_paths(photos, capsys):
    odd = photos.parent / "fötos 📷 (copy)"
    shutil.copytree(photos, odd)
    run(capsys, *make(odd, "résultat 3D ✓"), status=0)
    photo3d.load(photos.parent / "résultat 3D ✓")
    run(capsys, *make(photos, "n" * 255), status=0)  # the longest name: the temp's is shorter
    deep = photos.parent.joinpath(*["d" * 200] * 8, "out")  # a 1.6 kB path
    run(capsys, *make(photos, deep), status=0)
    assert (deep / "photo3d.npz").is_file()
    too_deep = photos.parent.joinpath(*["e" * 250] * 20, "out")  # beyond PATH_MAX
    run(capsys, *make(photos, too_deep), status=2, message="too long")
    assert not (photos.parent / ("e" * 250)).exists()  # created parents removed again


# --- smaller promises ---------------------------------------------------------------------


def test_16_bit_colour_png_is_read_at_full_precision(tmp_path):
    cv2 = pytest.importorskip("cv2")
    from photo3d.io.images import read_image

    values = np.random.default_rng(1).integers(0, 65536, (12, 16, 3), dtype=np.uint16)
    cv2.imwrite(str(tmp_path / "deep.png"), values[:, :, ::-1])  # OpenCV writes BGR
    image = read_image(tmp_path / "deep.png")
    assert np.abs(image * 65535.0 - values).max() < 0.02  # not 8 bits (error up to 128)


def test_upscaling_a_small_photo_is_announced(photos, capsys):
    argv = [str(a) for a in make(photos, "up")[:-len(FAST)]] + ["--size", "96", "--no-video"]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "the photo is 64x48; it is upscaled to a 96x72 working size" in err
    assert main(argv[:4] + ["-o", "up2", "-q", "--size", "32", "--no-video"]) == 0
    assert "upscaled" not in capsys.readouterr().err  # larger than --size: no note


def test_a_size_beyond_the_memory_is_refused_up_front(photos, capsys, monkeypatch, no_work):
    monkeypatch.setattr("photo3d.resources.available_memory", lambda: 2_000_000_000)
    run(capsys, *make(photos, "out")[:-len(FAST)], "--size", "16384", status=2,
        message="--size 16384 needs at least 367.2 GB of memory (working pixels: 366.9 GB "
                "of make's estimate) but 2.0 GB are available: use a smaller --size (1024 "
                "needs about 1.7 GB)")
    from photo3d.config import Config
    from photo3d.errors import ConfigError

    img, d = two_planes(48, 64, 32)
    with pytest.raises(ConfigError, match="a 4096x3072 working size needs about 29.6 GB"):
        make_photo(img, depth=d, config=Config(size=4096))


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs Linux's /proc")
def test_a_depth_edge_every_few_pixels_stays_within_the_memory_make_checked_for(tmp_path):
    """An 8 px checkerboard depth for a 741x500 photo at --size 384: the estimate
    make checks (photo3d.resources.memory_estimate) is 507 MB (before: 382); before,
    the run took 832 MB (its regions overlapping 9 times over; at 1024 px 5.4 GB), now
    about 260. Peak resident memory of the child (VmHWM)."""
    from photo3d.config import Config
    from photo3d.resources import memory_estimate

    yy, xx = np.mgrid[0:500, 0:741]
    np.save(tmp_path / "checker.npy", (1.0 + (yy // 8 + xx // 8) % 2).astype(np.float32))
    Image.fromarray(np.full((500, 741, 3), 128, np.uint8)).save(tmp_path / "photo.png")
    code = ("import re, sys; from photo3d.cli import main; code = main(sys.argv[1:]); "
            "status = open('/proc/self/status').read(); "
            "print(code, re.search(r'VmHWM:\\s*(\\d+)', status)[1])")
    done = subprocess.run([sys.executable, "-c", code, "make", str(tmp_path / "photo.png"),
                           "--depth", str(tmp_path / "checker.npy"), "--size", "384",
                           "--no-video", "--ply", "none", "--no-glb", "--no-viewer", "-q",
                           "-o", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=300, check=False)
    status, peak = done.stdout.split()[-2:]
    assert status == "0", done.stderr
    assert int(peak) * 1024 < memory_estimate((500, 741), Config(size=384))


def test_depth_warnings_are_printed_once(photos, capsys):
    small = np.load(photos / "a.npy")[::2, ::2].copy()
    small[:, :28] = np.nan  # 88 % unknown
    np.save(photos / "half.npy", small)
    code = main([str(a) for a in ["make", photos / "a.png", "--depth", photos / "half.npy",
                                  "-o", "out", *FAST]])
    err = capsys.readouterr().err
    assert code == 0
    assert err.count("resampling the depth") == 1, err
    assert err.count("depth is unknown at 88% of the pixels") == 1, err


@pytest.mark.parametrize(("args", "message"), [
    (["--synthetic", "0"], "between 1 and 1000"),
    (["--synthetic", "-2"], "between 1 and 1000"),
    (["--methods", ","], "--methods is empty"),
    (["--pair", "l.png", "r.png", "d.pfm", "calib.txt"], "file not found"),
])
def test_eval_options_are_checked(photos, capsys, args, message):
    run(capsys, "eval", *args, "-o", "ev/out", "-q", status=2, message=message)


def test_a_failed_eval_leaves_no_folder(photos, capsys):
    bad = [photos / "notes.txt"] * 4
    run(capsys, "eval", "--pair", *bad, "-o", "ev/out", "-q", "--no-lpips",
        status=2, message="notes.txt")


def test_the_licence_is_an_spdx_expression():
    import tomllib

    root = Path(__file__).parents[1]
    project = tomllib.loads((root / "pyproject.toml").read_text())["project"]
    assert project["license"] == "MIT"


def test_render_and_depth_on_a_read_only_file_system(photos, capsys):
    mnt = photos.parent / "mnt"
    if not _mount_tmpfs(mnt, "size=20m"):
        pytest.skip("needs root to mount a small tmpfs")
    try:
        run(capsys, *make(photos, mnt / "p"), status=0)
        subprocess.run(["mount", "-o", "remount,ro", str(mnt)], check=True)
        run(capsys, "render", mnt / "p", "--path", "circle", "--frames", "2", "-q", status=2,
            message="Read-only file system")
        run(capsys, "render", mnt / "p", "--still", "-q", status=2,
            message="Read-only file system")
        run(capsys, "depth", photos / "a.png", "--depth", photos / "a.npy", "-o",
            mnt / "d.png", status=2, message="Read-only file system")
    finally:
        subprocess.run(["umount", str(mnt)], check=True)


def test_a_folder_filled_meanwhile_is_not_replaced_without_overwrite(tmp_path):
    out = tmp_path / "out"
    out.mkdir()  # an empty folder may be used
    from photo3d.output import check_output, stage_photo

    with stage_photo(out, overwrite=False) as staging:
        (out / "photo3d.npz").write_text("written meanwhile")
        with pytest.raises(OutputError, match="not empty"):
            staging.commit()
    assert os.listdir(tmp_path) == ["out"] and os.listdir(out) == ["photo3d.npz"]
    with stage_photo(tmp_path / "new", overwrite=False) as staging:
        (tmp_path / "new").mkdir()  # an empty folder appearing meanwhile is fine
        staging.commit()
    assert sorted(os.listdir(tmp_path)) == ["new", "out"]
    assert check_output(tmp_path / "other", overwrite=False).name == "other"
    assert sorted(os.listdir(tmp_path)) == ["new", "out"]  # a check leaves nothing


def test_interruptions_anywhere_in_main_are_one_line(photos, capsys, monkeypatch):
    """Ctrl-C while the parser is built (it imports a lot), and a KeyboardInterrupt
    wrapped by numba's dispatcher (``SystemError ... with an exception set``)."""
    import photo3d.cli as cli

    def interrupted():
        raise KeyboardInterrupt

    with monkeypatch.context() as m:
        m.setattr(cli, "build_parser", interrupted)
        assert main(["make"]) == 130
    assert capsys.readouterr().err == "photo3d: interrupted\n"

    def wrapped(*args, **kwargs):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as err:
            raise SystemError("CPUDispatcher(<function _raster>) returned a result with an "
                              "exception set") from err

    monkeypatch.setattr("photo3d.pipeline.make", wrapped)
    run(capsys, *make(photos, "out"), status=130, message="photo3d: interrupted")


def test_import_photo3d_stays_light():
    """The command line starts (and handles Ctrl-C) before the heavy imports."""
    code = ("import sys, photo3d.cli; "
            "print(sorted(m for m in ('numpy', 'numba', 'scipy', 'PIL') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], env={**os.environ, "PYTHONPATH": SRC},
                         capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
