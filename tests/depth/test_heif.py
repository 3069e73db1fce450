"""HEIF depth images. pillow-heif cannot write them, so the test builds one from a
two-image HEIF by editing its boxes per ISO/IEC 23008-12: the second image becomes
an auxiliary image (``auxC`` = ``urn:mpeg:hevc:2015:auxid:2``, depth) of the first
through an ``auxl`` item reference. The depth representation info (an HEVC SEI
message in ``auxC``) is not written, so the reader's fallback is what is tested."""

from __future__ import annotations

import io
import struct
import sys

import numpy as np
import pytest
from PIL import Image

from photo3d.depth.heif import read_heif_depth, read_heif_image
from photo3d.depth.portrait import read_embedded_depth
from photo3d.depth.sources import resolve_depth
from photo3d.errors import InputError

pillow_heif = pytest.importorskip("pillow_heif")


def box(kind: bytes, payload: bytes) -> bytes:
    return struct.pack(">I4s", 8 + len(payload), kind) + payload


def full_box(kind: bytes, version: int, flags: int, payload: bytes) -> bytes:
    return box(kind, bytes([version]) + flags.to_bytes(3, "big") + payload)


def children(data: bytes) -> list[tuple[bytes, bytes]]:
    out, i = [], 0
    while i < len(data):
        size, kind = struct.unpack(">I4s", data[i:i + 8])
        out.append((kind, data[i:i + size]))
        i += size
    return out


def shift_iloc(iloc: bytes, delta: int) -> bytes:
    """Add ``delta`` to every file offset of an ``iloc`` box (construction method 0)."""
    b, v = bytearray(iloc), iloc[8]
    off_size, len_size = b[12] >> 4, b[12] & 15
    base_size, idx_size = b[13] >> 4, b[13] & 15
    wide = 4 if v >= 2 else 2
    count, p = int.from_bytes(b[14:14 + wide], "big"), 14 + wide

    def field(p: int, size: int, add: int = 0) -> int:
        value = int.from_bytes(b[p:p + size], "big")
        if add:
            b[p:p + size] = (value + add).to_bytes(size, "big")
        return value

    for _ in range(count):
        p += wide
        method = 0
        if v in (1, 2):
            method, p = field(p, 2) & 15, p + 2
        p += 2  # data_reference_index
        base = field(p, base_size) if base_size else 0
        if base and method == 0:
            field(p, base_size, delta)
        p += base_size
        extents, p = field(p, 2), p + 2
        for _ in range(extents):
            p += idx_size if v in (1, 2) else 0
            if method == 0 and not base:
                field(p, off_size, delta)
            p += off_size + len_size
    return bytes(b)


def make_depth_auxiliary(data: bytes, depth_item: int = 2, master_item: int = 1) -> bytes:
    out = []
    for kind, whole in children(data):
        if kind != b"meta":
            out.append(whole)
            continue
        parts = []
        for sub, sb in children(whole[12:]):
            if sub == b"iprp":
                props = dict(children(sb[8:]))
                index = len(children(props[b"ipco"][8:])) + 1
                ipco = box(b"ipco", props[b"ipco"][8:]
                           + full_box(b"auxC", 0, 0, b"urn:mpeg:hevc:2015:auxid:2\0"))
                ipma = props[b"ipma"]
                v, flags = ipma[8], int.from_bytes(ipma[9:12], "big")
                id_size, width = (2 if v < 1 else 4), (2 if flags & 1 else 1)
                n, q, entries = struct.unpack(">I", ipma[12:16])[0], 16, b""
                for _ in range(n):
                    item = int.from_bytes(ipma[q:q + id_size], "big")
                    count = ipma[q + id_size]
                    q += id_size + 1
                    assoc, q = ipma[q:q + count * width], q + count * width
                    if item == depth_item:
                        count += 1
                        assoc += (index | (0x80 << 8 * (width - 1))).to_bytes(width, "big")
                    entries += item.to_bytes(id_size, "big") + bytes([count]) + assoc
                ipma = full_box(b"ipma", v, flags, struct.pack(">I", n) + entries)
                sb = box(b"iprp", ipco + ipma)
                parts.append((b"iref", full_box(b"iref", 0, 0, box(
                    b"auxl", struct.pack(">HHH", depth_item, 1, master_item)))))
            parts.append((sub, sb))
        size = 12 + sum(len(p) for _, p in parts)
        delta = size - len(whole)
        body = b"".join(shift_iloc(p, delta) if k == b"iloc" else p for k, p in parts)
        out.append(box(b"meta", whole[8:12] + body))
    return b"".join(out)


def photo_and_ramp(h: int = 64, w: int = 96):
    rgb = (np.random.default_rng(0).random((h, w, 3)) * 255).astype(np.uint8)
    ramp = np.tile(np.linspace(0, 255, w).round().astype(np.uint8), (h, 1))
    return rgb, ramp


def write_heif(path, with_depth: bool) -> np.ndarray:
    rgb, ramp = photo_and_ramp()
    heif = pillow_heif.from_pillow(Image.fromarray(rgb))
    if with_depth:
        heif.add_from_pillow(Image.fromarray(ramp))
    buf = io.BytesIO()
    heif.save(buf, quality=-1)  # lossless
    data = make_depth_auxiliary(buf.getvalue()) if with_depth else buf.getvalue()
    path.write_bytes(data)
    return ramp


def test_heif_depth_image_is_read_as_normalised_disparity(tmp_path):
    path = tmp_path / "portrait.heic"
    ramp = write_heif(path, with_depth=True)
    assert len(pillow_heif.open_heif(path)) == 1  # the depth image is no longer top-level
    found = read_embedded_depth(path)
    assert found.kind == "disparity"
    assert found.source == "embedded HEIF depth image (8-bit, taken as disparity: bright = near)"
    np.testing.assert_allclose(found.depth, ramp / 255.0, atol=2 / 255)


def test_heif_without_depth(tmp_path):
    path = tmp_path / "plain.heic"
    write_heif(path, with_depth=False)
    assert read_heif_depth(path) is None
    assert read_heif_image(path).shape == (64, 96, 3)


@pytest.mark.parametrize("keep", [0.5, 0.1])
def test_a_truncated_heif_is_one_line(tmp_path, keep):
    """libheif's message for a file cut in half ends in a newline, which printed a
    second, empty error line."""
    path = tmp_path / "cut.heic"
    write_heif(path, with_depth=False)
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])
    with pytest.raises(InputError, match="cannot read HEIF") as err:
        read_heif_image(path)
    assert "\n" not in str(err.value) and str(err.value) == str(err.value).strip()


def test_resolve_depth_uses_the_heif_depth_image(tmp_path):
    path = tmp_path / "portrait.heic"
    ramp = write_heif(path, with_depth=True)
    est = resolve_depth(path)
    assert est.kind == "disparity" and est.depth.shape == ramp.shape
    assert est.source.startswith("embedded HEIF depth image")


def test_missing_pillow_heif_names_the_extra(tmp_path, monkeypatch):
    path = tmp_path / "portrait.heic"
    write_heif(path, with_depth=True)
    monkeypatch.setitem(sys.modules, "pillow_heif", None)
    with pytest.raises(InputError, match=r"pip install 'photo3d\[heif\]'"):
        read_embedded_depth(path)


def test_the_photo_reader_is_chosen_by_content_not_extension(tmp_path):
    """A JPEG named .heic was refused ("No 'ftyp' box"); a HEIF named .jpg is read."""
    from photo3d.depth.sources import read_photo

    rgb, _ = photo_and_ramp()
    Image.fromarray(rgb).save(tmp_path / "jpeg.heic", format="JPEG", quality=95)
    assert read_photo(tmp_path / "jpeg.heic").shape == (64, 96, 3)
    write_heif(tmp_path / "heif.jpg", with_depth=False)
    np.testing.assert_array_equal(read_photo(tmp_path / "heif.jpg"),
                                  read_heif_image(tmp_path / "heif.jpg"))


def test_a_tiny_heif_gets_the_minimum_size_error(tmp_path):
    from photo3d.depth.sources import read_photo

    path = tmp_path / "tiny.heic"
    heif = pillow_heif.from_pillow(Image.fromarray(np.zeros((4, 4, 3), np.uint8)))
    heif.save(path, quality=-1)
    with pytest.raises(InputError, match=r"^image .*tiny.heic is 4x4 pixels; photo3d needs "
                                         r"at least 8x8$"):
        read_photo(path)
