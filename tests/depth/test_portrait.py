"""Embedded depth: files written here by an independent writer that follows the
published formats (Google GDepth with extended XMP, Dynamic Depth containers)."""

from __future__ import annotations

import base64
import hashlib
import io

import numpy as np
import pytest
from PIL import Image

from photo3d.depth.portrait import decode_range, read_embedded_depth
from photo3d.errors import InputError
from photo3d.io.images import read_image

RDF = 'xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#"'
GDEPTH = 'xmlns:GDepth="http://ns.google.com/photos/1.0/depthmap/"'


def app1(payload: bytes) -> bytes:
    assert len(payload) + 2 <= 0xFFFF
    return b"\xff\xe1" + (len(payload) + 2).to_bytes(2, "big") + payload


def packet(description: str) -> bytes:
    return ('<?xpacket begin="" id="W5M0MpCehiHzreSzNTczkc9d"?>'
            f'<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF {RDF}>{description}</rdf:RDF>'
            '</x:xmpmeta><?xpacket end="w"?>').encode()


def jpeg_bytes(h: int, w: int, orientation: int | None = None) -> bytes:
    rng = np.random.default_rng(3)
    im = Image.fromarray((rng.random((h, w, 3)) * 255).astype(np.uint8))
    buf = io.BytesIO()
    exif = Image.Exif()
    if orientation:
        exif[0x0112] = orientation
    im.save(buf, "JPEG", quality=90, exif=exif.tobytes())
    return buf.getvalue()


def insert_segments(jpeg: bytes, segments: bytes) -> bytes:
    """Put APP1 segments after SOI and the existing APPn segments."""
    i = 2
    while jpeg[i] == 0xFF and 0xE0 <= jpeg[i + 1] <= 0xEF:
        i += 2 + int.from_bytes(jpeg[i + 2:i + 4], "big")
    return jpeg[:i] + segments + jpeg[i:]


def depth_png(v16: np.ndarray, eight_bit_jpeg: bool = False) -> bytes:
    buf = io.BytesIO()
    if eight_bit_jpeg:  # what Google Camera's lens blur writes
        Image.fromarray(np.round(v16 / 257).astype(np.uint8)).save(buf, "JPEG", quality=100)
    else:
        Image.fromarray(v16.astype(np.uint16)).save(buf, "PNG")
    return buf.getvalue()


def write_gdepth_jpeg(path, v16, *, near, far, fmt, orientation=None, original=None,
                      chunk=8000, attributes_as_elements=False, eight_bit_jpeg=False):
    """A Google depth JPEG: GDepth properties in the standard XMP, the PNG (and the
    optional original image) in extended XMP split into ``chunk``-byte segments,
    written in reverse order (readers must use the offsets)."""
    data = base64.b64encode(depth_png(v16, eight_bit_jpeg)).decode()
    extra = ""
    if original is not None:
        buf = io.BytesIO()
        Image.fromarray(original).save(buf, "JPEG", quality=95)
        encoded = base64.b64encode(buf.getvalue()).decode()
        extra = (' xmlns:GImage="http://ns.google.com/photos/1.0/image/" '
                 f'GImage:Mime="image/jpeg" GImage:Data="{encoded}"')
    extended = packet(f'<rdf:Description rdf:about="" {GDEPTH} GDepth:Data="{data}"{extra}/>')
    guid = hashlib.md5(extended).hexdigest().upper()
    props = {"Format": fmt, "Near": near, "Far": far, "Mime": "image/png"}
    if attributes_as_elements:
        body = "".join(f"<GDepth:{k}>{v}</GDepth:{k}>" for k, v in props.items())
        main = (f'<rdf:Description rdf:about="" {GDEPTH} '
                f'xmlns:xmpNote="http://ns.adobe.com/xmp/note/" xmpNote:HasExtendedXMP="{guid}">'
                f"{body}</rdf:Description>")
    else:
        attrs = " ".join(f'GDepth:{k}="{v}"' for k, v in props.items())
        main = (f'<rdf:Description rdf:about="" {GDEPTH} '
                f'xmlns:xmpNote="http://ns.adobe.com/xmp/note/" {attrs} '
                f'xmpNote:HasExtendedXMP="{guid}"/>')
    segments = [app1(b"http://ns.adobe.com/xap/1.0/\x00" + packet(main))]
    parts = []
    for offset in range(0, len(extended), chunk):
        parts.append(app1(b"http://ns.adobe.com/xmp/extension/\x00" + guid.encode()
                          + len(extended).to_bytes(4, "big") + offset.to_bytes(4, "big")
                          + extended[offset:offset + chunk]))
    segments += parts[::-1]
    h, w = v16.shape
    jpeg = jpeg_bytes(h * 2, w * 2, orientation)
    path.write_bytes(insert_segments(jpeg, b"".join(segments)))
    return len(parts)


def expected_depth(v16, near, far, fmt):
    v = v16 / 65535.0
    if fmt == "RangeLinear":
        return near + v * (far - near)
    return far * near / (far - v * (far - near))


def random_v16(h=90, w=120):
    # Noise makes the PNG big enough to need several extended-XMP segments.
    return np.random.default_rng(5).integers(0, 65536, (h, w))


@pytest.mark.parametrize("fmt", ["RangeInverse", "RangeLinear"])
def test_gdepth_jpeg_decodes_by_the_published_formulas(tmp_path, fmt):
    v16 = random_v16()
    path = tmp_path / "portrait.jpg"
    assert write_gdepth_jpeg(path, v16, near=0.3, far=4.2, fmt=fmt) >= 3
    found = read_embedded_depth(path)
    assert found.kind == "depth" and found.image is None
    np.testing.assert_allclose(found.depth, expected_depth(v16, 0.3, 4.2, fmt), rtol=1e-5)
    words = "range inverse" if fmt == "RangeInverse" else "range linear"
    assert found.source == f"embedded GDepth depth map ({words}, near 0.3, far 4.2)"


def test_gdepth_8bit_jpeg_depth(tmp_path):
    v16 = np.tile(np.linspace(0, 65535, 64).round(), (48, 1))  # smooth: JPEG keeps it
    path = tmp_path / "lensblur.jpg"
    write_gdepth_jpeg(path, v16, near=0.5, far=5, fmt="RangeInverse", eight_bit_jpeg=True)
    found = read_embedded_depth(path)
    expected = expected_depth(np.round(v16 / 257) * 257, 0.5, 5, "RangeInverse")
    np.testing.assert_allclose(found.depth, expected, rtol=0.05)
    assert found.depth.max() > 4.5 and found.depth.min() < 0.55


def test_gdepth_properties_as_elements_and_original_image(tmp_path):
    v16 = random_v16(30, 40)
    original = np.zeros((60, 80, 3), np.uint8)
    original[:, 40:] = 200
    path = tmp_path / "lensblur.jpg"
    write_gdepth_jpeg(path, v16, near=1, far=10, fmt="RangeLinear", original=original,
                      attributes_as_elements=True)
    found = read_embedded_depth(path)
    np.testing.assert_allclose(found.depth, expected_depth(v16, 1, 10, "RangeLinear"), rtol=1e-5)
    assert found.image.shape == (60, 80, 3)
    assert found.image[:, :35].max() < 0.05 and found.image[:, 45:].min() > 0.7


@pytest.mark.parametrize("orientation", [3, 6, 8])
def test_depth_is_turned_upright_like_the_photo(tmp_path, orientation):
    v16 = np.zeros((30, 40))
    v16[:10, :10] = 65535  # far corner at the stored image's top-left
    path = tmp_path / "rotated.jpg"
    write_gdepth_jpeg(path, v16, near=1, far=2, fmt="RangeLinear", orientation=orientation)
    found = read_embedded_depth(path)
    photo = read_image(path)  # the project's reader applies EXIF orientation
    h, w = found.depth.shape
    assert photo.shape[0] / h == pytest.approx(photo.shape[1] / w)
    turns = {3: 2, 6: -1, 8: 1}[orientation]  # counter-clockwise quarter turns
    np.testing.assert_allclose(found.depth, np.rot90(1 + v16 / 65535, turns), rtol=1e-6)


def write_dynamic_depth(path, v16, *, near, far, fmt, padding=7):
    """Dynamic Depth 1.0: primary JPEG + directory; depth and confidence PNGs appended."""
    depth = depth_png(v16) + b"\0" * padding
    confidence = depth_png(np.full(v16.shape, 65535))
    xmp = (f'<rdf:Description rdf:about="" '
           'xmlns:Device="http://ns.google.com/photos/dd/1.0/device/" '
           'xmlns:Container="http://ns.google.com/photos/dd/1.0/container/" '
           'xmlns:Item="http://ns.google.com/photos/dd/1.0/item/" '
           'xmlns:Camera="http://ns.google.com/photos/dd/1.0/camera/" '
           'xmlns:DepthMap="http://ns.google.com/photos/dd/1.0/depthmap/">'
           "<Device:Container><Container:Directory><rdf:Seq>"
           '<rdf:li rdf:parseType="Resource"><Container:Item Item:Mime="image/jpeg" '
           'Item:DataURI="primary_image"/></rdf:li>'
           '<rdf:li rdf:parseType="Resource"><Container:Item Item:Mime="image/png" '
           f'Item:Length="{len(depth)}" Item:Padding="{padding}" '
           'Item:DataURI="android/depthmap"/></rdf:li>'
           '<rdf:li rdf:parseType="Resource"><Container:Item Item:Mime="image/png" '
           f'Item:Length="{len(confidence)}" Item:DataURI="android/confidencemap"/></rdf:li>'
           "</rdf:Seq></Container:Directory></Device:Container>"
           '<Device:Cameras><rdf:Seq><rdf:li rdf:parseType="Resource"><Device:Camera '
           'rdf:parseType="Resource"><Camera:DepthMap rdf:parseType="Resource">'
           f"<DepthMap:Format>{fmt}</DepthMap:Format><DepthMap:Near>{near}</DepthMap:Near>"
           f"<DepthMap:Far>{far}</DepthMap:Far><DepthMap:Units>Meters</DepthMap:Units>"
           "<DepthMap:MeasureType>OpticalAxis</DepthMap:MeasureType>"
           "<DepthMap:DepthURI>android/depthmap</DepthMap:DepthURI>"
           "<DepthMap:ConfidenceURI>android/confidencemap</DepthMap:ConfidenceURI>"
           "</Camera:DepthMap></Device:Camera></rdf:li></rdf:Seq></Device:Cameras>"
           "</rdf:Description>")
    h, w = v16.shape
    primary = insert_segments(jpeg_bytes(h, w), app1(b"http://ns.adobe.com/xap/1.0/\x00"
                                                     + packet(xmp)))
    path.write_bytes(primary + depth + confidence)


def test_dynamic_depth_container(tmp_path):
    v16 = random_v16(24, 32)
    path = tmp_path / "pixel.jpg"
    write_dynamic_depth(path, v16, near=0.5, far=8.0, fmt="RangeInverse")
    found = read_embedded_depth(path)
    assert found.kind == "depth" and found.warnings == ()
    assert found.source == "embedded Dynamic Depth map (range inverse, near 0.5, far 8)"
    np.testing.assert_allclose(found.depth, expected_depth(v16, 0.5, 8.0, "RangeInverse"),
                               rtol=1e-5)


def test_plain_files_have_no_embedded_depth(tmp_path):
    (tmp_path / "a.jpg").write_bytes(jpeg_bytes(16, 16))
    Image.new("RGB", (8, 8)).save(tmp_path / "b.png")
    assert read_embedded_depth(tmp_path / "a.jpg") is None
    assert read_embedded_depth(tmp_path / "b.png") is None


def test_metadata_without_image_is_an_error(tmp_path):
    main = f'<rdf:Description rdf:about="" {GDEPTH} GDepth:Near="1" GDepth:Far="2"/>'
    path = tmp_path / "broken.jpg"
    path.write_bytes(insert_segments(jpeg_bytes(16, 16),
                                     app1(b"http://ns.adobe.com/xap/1.0/\x00" + packet(main))))
    with pytest.raises(InputError, match="has depth metadata but no depth image"):
        read_embedded_depth(path)


def test_bad_near_far_and_format():
    with pytest.raises(InputError, match="expected 0 < near < far"):
        decode_range(np.zeros(2), near=2, far=1, fmt="RangeLinear")
    with pytest.raises(InputError, match="expected RangeInverse or RangeLinear"):
        decode_range(np.zeros(2), near=1, far=2, fmt="Disparity")


def test_missing_file():
    with pytest.raises(InputError, match="image file not found"):
        read_embedded_depth("no/such/file.jpg")
