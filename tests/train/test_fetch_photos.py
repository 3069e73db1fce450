"""scripts/data/fetch_photos.py: split rule, licences, Qt resources, preparing a fake package."""

from __future__ import annotations

import hashlib
import importlib.util
import io
import shutil
import struct
import sys
import tarfile
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "data" / "fetch_photos.py"


def _load():
    spec = importlib.util.spec_from_file_location("fetch_photos", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules["fetch_photos"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


fp = _load()

DEP5 = """
Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/
Upstream-Name: fake

Files: *
Copyright: 2014 Someone
License: GPL-2+

Files: nature/Storm.jpg
       nature/Aqua.jpg
Copyright: 2010 A Photographer
License: CC-BY-SA-4.0

Files: 16.04/friends_by_X.jpg
Copyright: 2016 X
License: CC-BY-NC-4.0

Files: src/activities/erase/resource/*
Copyright: Various
License: public-domain
Comment: converted to WebP at build time

Files: debian/*
Copyright: 2020 Packager
License: Expat

License: GPL-2+
 This package is free software; you can redistribute it
 .
 and so on.
"""


def test_split_rule_is_a_stable_tenth_by_name():
    names = [f"package{i % 7}--photo{i}" for i in range(5000)]
    held = [fp.is_heldout(n) for n in names]
    assert 0.08 < np.mean(held) < 0.12
    assert held == [int(hashlib.sha256(n.encode()).hexdigest(), 16) % 10 == 0 for n in names]
    # known answers: the rule must not change, or photos move between the splits
    assert fp.is_heldout("kphotoalbum--jesper") and fp.is_heldout("tuxpaint-data--sheep")
    assert not fp.is_heldout("kphotoalbum--snow") and not fp.is_heldout("lxqt-themes--fog")


@pytest.mark.parametrize(("expression", "free"), [
    ("GPL-2+", True), ("LGPL-2.1+", True), ("CC-BY-SA-4.0", True), ("CC0-1.0", True),
    ("public-domain", True), ("Expat", True), ("GPL-3 or LGPL-2.1 with Digia-1.1 exception", True),
    ("CC-BY-3.0 and CC0-1.0", True), ("CC-BY-NC-4.0", False), ("CC-BY-ND-4.0", False),
    ("CC-BY-3.0 and Bitstream", False), ("custom", False), ("", False), ("unstated", False)])
def test_licence_ok_accepts_free_licences_only(expression, free):
    assert fp.licence_ok(expression) is free


def test_dep5_stanzas_give_each_installed_file_its_licence():
    stanzas = fp.parse_copyright(DEP5)
    assert [s.licence for s in stanzas] == ["GPL-2+", "CC-BY-SA-4.0", "CC-BY-NC-4.0",
                                            "public-domain", "Expat"]
    assert stanzas[1].patterns == ("nature/Storm.jpg", "nature/Aqua.jpg")
    licence = {path: fp.licence_of(stanzas, path) for path in (
        "usr/share/backgrounds/mate/nature/Aqua.jpg",  # installed under other folders
        "usr/share/backgrounds/friends_by_X.jpg",  # the source folder 16.04/ is not installed
        "usr/share/backgrounds/mate/nature/Dune.jpg",
        "gcompris/src/activities/erase/resource/alpaca.webp")}
    assert licence == {"usr/share/backgrounds/mate/nature/Aqua.jpg": "CC-BY-SA-4.0",
                       "usr/share/backgrounds/friends_by_X.jpg": "CC-BY-NC-4.0",
                       "usr/share/backgrounds/mate/nature/Dune.jpg": "GPL-2+",
                       "gcompris/src/activities/erase/resource/alpaca.webp": "public-domain"}
    assert not fp.licence_ok(licence["usr/share/backgrounds/friends_by_X.jpg"])
    assert fp.parse_copyright("This package was debianized by someone.\n\nGPL.\n") is None


def test_the_stanza_matching_more_folders_wins_over_a_later_one():
    stanzas = fp.parse_copyright("Format: x\n\nFiles: data/themes/maldives/background.jpg\n"
                                 "License: CC-BY-3.0\n\nFiles: data/themes/elarun/background.png\n"
                                 "License: LGPL-3\n")
    assert fp.licence_of(stanzas, "usr/share/sddm/themes/maldives/background.jpg") == "CC-BY-3.0"
    assert fp.licence_of(stanzas, "usr/share/sddm/themes/elarun/background.png") == "LGPL-3"
    assert fp.licence_of(stanzas, "usr/share/other.png") is None


def _rcc(files: dict[str, tuple[bytes, bool]]) -> bytes:
    """A version-2 Qt resource file holding ``dir/<name>`` for each of ``files``."""
    names, data, nodes = b"", b"", []

    def name(text: str) -> int:
        nonlocal names
        offset = len(names)
        names += struct.pack(">HI", len(text), 0) + text.encode("utf-16-be")
        return offset

    nodes.append(struct.pack(">IHII", 0, 2, 1, 1) + bytes(8))  # root: one child, node 1
    nodes.append(struct.pack(">IHII", name("dir"), 2, len(files), 2) + bytes(8))
    for file, (payload, packed) in files.items():
        stored = struct.pack(">I", len(payload)) + zlib.compress(payload) if packed else payload
        nodes.append(struct.pack(">IHHHI", name(file), int(packed), 0, 0, len(data)) + bytes(8))
        data += struct.pack(">I", len(stored)) + stored
    tree = b"".join(nodes)
    header = 20
    return (b"qres" + struct.pack(">4I", 2, header, header + len(tree),
                                  header + len(tree) + len(data)) + tree + data + names)


def test_rcc_reader_returns_images_plain_and_zlib_packed():
    png, jpg = b"\x89PNG fake", b"\xff\xd8 fake jpeg " * 20
    blob = _rcc({"a.png": (png, False), "b.jpg": (jpg, True), "c.qml": (b"Item {}", False)})
    assert sorted(fp.rcc_images(blob)) == [("dir/a.png", png), ("dir/b.jpg", jpg)]


def _tar(files: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz") as tar:
        for name, payload in files.items():
            info = tarfile.TarInfo(name)
            info.size = len(payload)
            tar.addfile(info, io.BytesIO(payload))
    return buffer.getvalue()


def _deb(path: Path, files: dict[str, bytes]) -> Path:
    members = {"debian-binary": b"2.0\n",
               "control.tar.gz": _tar({"./control": b"Package: fake\nVersion: 1\n"}),
               "data.tar.gz": _tar(files)}
    blob = b"!<arch>\n"
    for name, payload in members.items():
        blob += f"{name:<16}{0:<12}{0:<6}{0:<6}{100644:<8}{len(payload):<10}`\n".encode()
        blob += payload + b"\n" * (len(payload) % 2)
    path.write_bytes(blob)
    return path


@pytest.mark.parametrize("dpkg", [True, False])
def test_unpack_deb_with_dpkg_deb_or_python(tmp_path, monkeypatch, dpkg):
    if dpkg and not shutil.which("dpkg-deb"):
        pytest.skip("dpkg-deb is not installed")
    if not dpkg:
        monkeypatch.setattr(fp.shutil, "which", lambda name: None)
    deb = _deb(tmp_path / "fake_1_all.deb", {"./usr/share/doc/fake/copyright": b"GPL",
                                             "./usr/share/x/a.png": b"png"})
    tree = fp.unpack_deb(deb, tmp_path / "trees")
    assert tree == tmp_path / "trees" / "fake_1_all"
    assert (tree / "usr/share/x/a.png").read_bytes() == b"png"
    assert fp.unpack_deb(deb, tmp_path / "trees") == tree  # unpacked once
    assert [p.name for p in (tmp_path / "trees").iterdir()] == ["fake_1_all"]


def _photo(path: Path, size: tuple[int, int], seed: int) -> np.ndarray:
    """A smooth random colour picture (a real-looking dHash), saved at ``size``."""
    rng = np.random.default_rng(seed)
    small = Image.fromarray(rng.integers(0, 256, (6, 8, 3), dtype=np.uint8))
    image = small.resize(size, Image.Resampling.BICUBIC)
    path.parent.mkdir(parents=True, exist_ok=True)
    image.save(path, quality=95) if path.suffix == ".jpg" else image.save(path)
    return np.asarray(image)


@pytest.fixture
def package(tmp_path):
    """A fake unpacked package ``fakepkg`` and its review lists."""
    root = tmp_path / "tree"
    pics = root / "usr/share/backgrounds"
    doc = root / "usr/share/doc/fakepkg"
    doc.mkdir(parents=True)
    (doc / "copyright").write_text(DEP5)
    _photo(pics / "Storm.jpg", (1600, 1000), 1)  # CC-BY-SA-4.0, resized to 1229 x 768
    _photo(pics / "Storm_small.jpg", (800, 500), 1)  # the same photo, smaller: dropped
    _photo(pics / "tall.png", (500, 900), 2)  # GPL-2+, kept as it is
    _photo(pics / "turned.png", (640, 480), 3)  # turned a quarter clockwise
    _photo(pics / "friends_by_X.jpg", (640, 480), 4)  # NC licence
    _photo(pics / "tiny.png", (200, 120), 5)
    _photo(pics / "art.png", (640, 480), 6)
    _photo(pics / "new.png", (640, 480), 7)  # not reviewed
    _photo(tmp_path / "outside.png", (640, 480), 8)
    (pics / "link.png").symlink_to(tmp_path / "outside.png")
    (pics / "notes.txt").write_text("not an image")
    source = fp.Source("fakepkg", ("usr/share/backgrounds/*",),
                       keep=dict.fromkeys("Storm Storm_small tall turned friends_by_X tiny link"
                                          .split(), "photo"),
                       drop={"art": "art"}, turns={"turned": 90})
    return source, root


def _build(tmp_path, monkeypatch, package, *args):
    source, root = package
    monkeypatch.setattr(fp, "SOURCES", (source,))
    monkeypatch.setattr(fp, "source_root", lambda *_: (root, "1.0-1"))
    return fp.main(["--out", str(tmp_path / "out"), "--cache", str(tmp_path / "cache"),
                    "--offline", *args])


def test_build_reviews_resizes_names_and_records_a_fake_package(tmp_path, monkeypatch, package,
                                                                capsys):
    assert _build(tmp_path, monkeypatch, package) == 0
    out = tmp_path / "out"
    lines = (out / "SOURCES.tsv").read_text().splitlines()
    assert lines[0].split("\t")[:8] == ["name", "split", "package", "original_path", "licence",
                                       "width", "height", "sha256"]
    rows = {r[0]: r for r in (line.split("\t") for line in lines[1:])}
    assert sorted(rows) == ["fakepkg--Storm.png", "fakepkg--tall.png", "fakepkg--turned.png"]
    sizes = {"fakepkg--Storm.png": (1229, 768), "fakepkg--tall.png": (500, 900),
             "fakepkg--turned.png": (480, 640)}
    for name, row in rows.items():
        split = "heldout" if fp.is_heldout(name[:-4]) else "train"
        path = out / split / name
        assert row[1] == split and row[2] == "fakepkg"
        assert (int(row[5]), int(row[6])) == sizes[name]
        with Image.open(path) as im:
            assert im.mode == "RGB" and im.size == sizes[name]
        assert row[7] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert rows["fakepkg--Storm.png"][3:5] == ["usr/share/backgrounds/Storm.jpg", "CC-BY-SA-4.0"]
    assert rows["fakepkg--tall.png"][4] == "GPL-2+"
    dropped = {line.split("\t")[1].rsplit("/", 1)[-1]: line.split("\t")[2]
               for line in (out / "DROPPED.tsv").read_text().splitlines()[1:]}
    assert dropped == {"Storm_small.jpg": "duplicate of fakepkg--Storm",
                       "friends_by_X.jpg": "licence", "tiny.png": "small", "art.png": "art",
                       "new.png": "unreviewed", "link.png": "symlink"}
    assert "fakepkg 1.0-1: 4 photos" in capsys.readouterr().out


def test_second_run_refuses_in_one_line_unless_update(tmp_path, monkeypatch, package, capsys):
    assert _build(tmp_path, monkeypatch, package) == 0
    first = (tmp_path / "out" / "SOURCES.tsv").read_text()
    capsys.readouterr()
    assert _build(tmp_path, monkeypatch, package) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--update" in err
    assert _build(tmp_path, monkeypatch, package, "--update") == 0
    assert (tmp_path / "out" / "SOURCES.tsv").read_text() == first  # the same photos again
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out")]  # no leftovers


def test_a_foreign_folder_is_refused_even_with_update(tmp_path, monkeypatch, package, capsys):
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "mine.txt").write_text("someone's file")
    assert _build(tmp_path, monkeypatch, package, "--update") == 2
    assert "not made by fetch_photos.py" in capsys.readouterr().err
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["mine.txt"]
