"""Depth maps embedded in phone photos: Google depth JPEGs and HEIF depth images.

Supported containers (:func:`read_embedded_depth`):

* **GDepth** (Google "Depthmap metadata", lens-blur and portrait JPEGs): XMP
  properties in namespace ``http://ns.google.com/photos/1.0/depthmap/``:
  ``GDepth:Format`` (``RangeInverse`` or ``RangeLinear``), ``GDepth:Near``,
  ``GDepth:Far``, ``GDepth:Mime`` and ``GDepth:Data`` (a base64 PNG/JPEG, normally
  in the *extended* XMP: APP1 segments headed ``http://ns.adobe.com/xmp/extension/``,
  each carrying a 32-character GUID, the full length and the chunk's offset).
  ``GImage:Data`` (the unblurred original) is returned too when present.
* **Dynamic Depth 1.0** (newer Pixel phones): a ``Device:Container`` directory of
  ``Container:Item`` entries (``Item:Mime``, ``Item:Length``, ``Item:Padding``,
  ``Item:DataURI``) whose data is appended, in order, after the primary JPEG; the
  ``Camera:DepthMap`` element gives ``DepthMap:Format``, ``Near``, ``Far`` and
  ``DepthURI`` (the ``DataURI`` of the depth item).
* **HEIF/HEIC** with an auxiliary depth image: see :mod:`photo3d.depth.heif`.

Both Google formats store ``v`` in [0, 1] (pixel / 255 or / 65535) and decode to
depth (in ``Near``/``Far`` units, usually metres) by the published formulas::

    RangeLinear:   d = near + v * (far - near)
    RangeInverse:  d = far * near / (far - v * (far - near))

The depth map is turned upright with the photo's EXIF orientation, like the photo
itself (:func:`photo3d.io.images.read_image`). Not supported: Apple's MPF depth
JPEGs and depth in PNG/WebP containers.
"""

from __future__ import annotations

import base64
import binascii
import contextlib
import io
import os
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError

from photo3d.depth.embedded import EmbeddedDepth
from photo3d.errors import InputError
from photo3d.io.images import to_float_image

PathLike = str | os.PathLike[str]

XMP_HEADER = b"http://ns.adobe.com/xap/1.0/\x00"
EXTENDED_XMP_HEADER = b"http://ns.adobe.com/xmp/extension/\x00"
NS = {
    "GDepth": "http://ns.google.com/photos/1.0/depthmap/",
    "GImage": "http://ns.google.com/photos/1.0/image/",
    "xmpNote": "http://ns.adobe.com/xmp/note/",
    "Item": "http://ns.google.com/photos/dd/1.0/item/",
    "DepthMap": "http://ns.google.com/photos/dd/1.0/depthmap/",
}
"""XMP namespaces read here, by their usual prefixes."""

MAX_DEPTH_PIXELS = 1 << 24
"""Most pixels an embedded depth map may declare (4096 x 4096; phones write about
1 megapixel): a larger one is refused from its header, before it is decoded."""

_TRANSPOSE = {2: Image.Transpose.FLIP_LEFT_RIGHT, 3: Image.Transpose.ROTATE_180,
              4: Image.Transpose.FLIP_TOP_BOTTOM, 5: Image.Transpose.TRANSPOSE,
              6: Image.Transpose.ROTATE_270, 7: Image.Transpose.TRANSVERSE,
              8: Image.Transpose.ROTATE_90}


def decode_range(v: np.ndarray, *, near: float, far: float, fmt: str) -> np.ndarray:
    """Google's normalised depth ``v`` in [0, 1] -> depth in the units of near/far.

    Args:
        v: ``(h, w)`` values in [0, 1].
        near, far: the nearest and farthest depth (``0 < near < far``).
        fmt: ``"RangeInverse"`` or ``"RangeLinear"``.

    Returns:
        ``(h, w) float32`` depth; ``v = 0`` is ``near``, ``v = 1`` is ``far``.

    Example:
        >>> v = np.array([0.0, 0.5, 1.0])
        >>> decode_range(v, near=1.0, far=4.0, fmt="RangeLinear").tolist()
        [1.0, 2.5, 4.0]
        >>> decode_range(v, near=1.0, far=4.0, fmt="RangeInverse").astype(float).round(3).tolist()
        [1.0, 1.6, 4.0]
    """
    if not (0 < near < far and np.isfinite(far)):
        raise InputError(f"embedded depth has near={near:g}, far={far:g}; expected 0 < near < far")
    v = np.clip(np.asarray(v, np.float64), 0.0, 1.0)
    if fmt == "RangeLinear":
        d = near + v * (far - near)
    elif fmt == "RangeInverse":
        d = far * near / (far - v * (far - near))
    else:
        raise InputError(f"embedded depth has format {fmt!r}; expected RangeInverse or RangeLinear")
    return d.astype(np.float32)


def read_embedded_depth(path: PathLike) -> EmbeddedDepth | None:
    """Find and decode the depth map embedded in a photo file.

    Args:
        path: a JPEG (GDepth or Dynamic Depth XMP) or HEIF/HEIC file.

    Returns:
        :class:`EmbeddedDepth`, or None when the file holds no depth map.

    Raises:
        InputError: one line; the file is missing, or holds a depth map that cannot
            be decoded (bad base64, not a PNG/JPEG, more than :data:`MAX_DEPTH_PIXELS`
            pixels: the message says which part is broken), or is HEIF and
            pillow-heif is not installed. A broken GImage (the optional unblurred
            photo of a GDepth JPEG) is no error: it is left out with a warning.

    Example:
        >>> import pathlib, tempfile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "plain.jpg"
        >>> Image.new("RGB", (8, 8)).save(path)
        >>> read_embedded_depth(path) is None
        True
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"image file not found: {path}")
    data = path.read_bytes()
    if data[:2] == b"\xff\xd8":
        return _read_jpeg(path, data)
    if data[4:8] == b"ftyp" and data[8:12] in (b"heic", b"heix", b"mif1", b"msf1", b"heim",
                                               b"heis", b"hevc", b"hevx", b"avif"):
        from photo3d.depth.heif import read_heif_depth

        return read_heif_depth(path)
    return None


def _jpeg_app1_segments(data: bytes) -> list[bytes]:
    """Payloads of the APP1 segments of a JPEG, in file order (stops at SOS)."""
    out, i = [], 2
    while i + 4 <= len(data) and data[i] == 0xFF:
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        if marker in (0xD9, 0xDA):
            break
        length = int.from_bytes(data[i + 2 : i + 4], "big")
        if marker == 0xE1:
            out.append(data[i + 4 : i + 2 + length])
        i += 2 + length
    return out


def _xmp_packets(data: bytes) -> tuple[bytes | None, dict[str, bytearray]]:
    """The standard XMP packet and the extended XMP packets (by GUID) of a JPEG."""
    main, chunks = None, {}
    for seg in _jpeg_app1_segments(data):
        if seg.startswith(XMP_HEADER) and main is None:
            main = seg[len(XMP_HEADER) :]
        elif seg.startswith(EXTENDED_XMP_HEADER):
            body = seg[len(EXTENDED_XMP_HEADER) :]
            guid = body[:32].decode("ascii", "replace")
            total = int.from_bytes(body[32:36], "big")
            offset = int.from_bytes(body[36:40], "big")
            buf = chunks.setdefault(guid, bytearray(total))
            buf[offset : offset + len(body) - 40] = body[40:]
    return main, chunks


def _parse_xmp(packet: bytes) -> ET.Element | None:
    start, end = packet.find(b"<x:xmpmeta"), packet.rfind(b"</x:xmpmeta>")
    if start < 0 or end < 0:
        start, end = packet.find(b"<rdf:RDF"), packet.rfind(b"</rdf:RDF>")
        if start < 0 or end < 0:
            return None
        end += len(b"</rdf:RDF>")
    else:
        end += len(b"</x:xmpmeta>")
    try:
        return ET.fromstring(packet[start:end])
    except ET.ParseError as err:
        raise InputError(f"the photo's XMP metadata is not valid XML: {err}") from err


def xmp_records(root: ET.Element, namespace: str) -> list[dict[str, str]]:
    """Properties of ``namespace`` held by each XML element, in document order.

    A property is an attribute (``GDepth:Near="0.5"``) or a leaf child element
    (``<GDepth:Near>0.5</GDepth:Near>``), the two forms XMP allows.

    Example:
        >>> root = ET.fromstring('<a xmlns:n="urn:x"><b n:p="1"><n:q>2</n:q></b></a>')
        >>> xmp_records(root, "urn:x")
        [{'p': '1', 'q': '2'}]
    """
    prefix = "{" + namespace + "}"
    records = []
    for element in root.iter():
        props = {k[len(prefix) :]: v for k, v in element.attrib.items() if k.startswith(prefix)}
        for child in element:
            if child.tag.startswith(prefix) and len(child) == 0 and child.text is not None:
                props.setdefault(child.tag[len(prefix) :], child.text.strip())
        if props:
            records.append(props)
    return records


def _read_jpeg(path: Path, data: bytes) -> EmbeddedDepth | None:
    main, chunks = _xmp_packets(data)
    roots = [r for r in [_parse_xmp(main)] if r is not None] if main else []
    wanted = None
    for root in roots:
        for rec in xmp_records(root, NS["xmpNote"]):
            wanted = rec.get("HasExtendedXMP", wanted)
    for guid, buf in chunks.items():
        if wanted is None or guid == wanted:
            root = _parse_xmp(bytes(buf))
            if root is not None:
                roots.append(root)
    gdepth = _merged(roots, NS["GDepth"])
    if "Data" in gdepth:
        return _decode_gdepth(path, gdepth, _merged(roots, NS["GImage"]))
    depthmaps = [r for root in roots for r in xmp_records(root, NS["DepthMap"])]
    items = [r for root in roots for r in xmp_records(root, NS["Item"])]
    if depthmaps and items:
        return _decode_dynamic_depth(path, data, depthmaps[0], items)
    if gdepth or depthmaps:
        raise InputError(f"{path} has depth metadata but no depth image in it")
    return None


def _merged(roots: list[ET.Element], namespace: str) -> dict[str, str]:
    merged: dict[str, str] = {}
    for root in roots:
        for rec in xmp_records(root, namespace):
            for key, value in rec.items():
                merged.setdefault(key, value)
    return merged


def _number(props: dict[str, str], key: str, what: str) -> float:
    try:
        return float(props[key])
    except (KeyError, ValueError) as err:
        raise InputError(f"{what} has no valid {key} (got {props.get(key)!r})") from err


@contextlib.contextmanager
def _open_blob(blob: bytes, what: str, *, max_pixels: int) -> Iterator[Image.Image]:
    """An embedded image, opened (not decoded) and checked to hold at most
    ``max_pixels`` pixels; any failure, there or while the caller decodes it, is
    one :class:`InputError` naming ``what``."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)  # sized below
            im = Image.open(io.BytesIO(blob))
        with im:
            w, h = im.size
            if w * h > max_pixels:
                raise InputError(f"{what} declares {w}x{h} pixels, more than the "
                                 f"{max_pixels:,} photo3d reads (decompression bomb?)")
            yield im
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError, TypeError,
            Image.DecompressionBombError) as err:
        if isinstance(err, InputError):
            raise
        raise InputError(f"{what} is not a readable PNG/JPEG image: "
                         f"{' '.join(str(err).split())[:160]}") from err


def _base64(text: str, what: str) -> bytes:
    try:
        return base64.b64decode(text, validate=False)
    except (binascii.Error, ValueError) as err:
        raise InputError(f"{what} is not valid base64 ({err})") from err


def _grey_unit(blob: bytes, what: str) -> np.ndarray:
    """An 8/16-bit grey PNG or JPEG of at most :data:`MAX_DEPTH_PIXELS` pixels ->
    ``(h, w) float64`` in [0, 1]."""
    with _open_blob(blob, what, max_pixels=MAX_DEPTH_PIXELS) as im:
        im.load()
        wide = im.mode.startswith("I")  # 16-bit grey ("I;16", or "I" on old Pillow)
        arr = np.asarray(im)
    if arr.ndim == 3:
        arr = arr[..., 0]
    return arr.astype(np.float64) / (65535.0 if wide else 255.0)


def _upright(depth: np.ndarray, path: Path) -> np.ndarray:
    """Apply the photo's EXIF orientation to a depth map stored unrotated."""
    with Image.open(path) as im:
        orientation = im.getexif().get(0x0112, 1)
    if orientation not in _TRANSPOSE:
        return depth
    return np.asarray(Image.fromarray(depth.astype(np.float32), "F").transpose(
        _TRANSPOSE[orientation]))


def _decode_gdepth(path: Path, props: dict[str, str], gimage: dict[str, str]) -> EmbeddedDepth:
    what = f"GDepth depth map of {path}"
    near, far = _number(props, "Near", what), _number(props, "Far", what)
    fmt = props.get("Format", "RangeInverse")
    blob = _base64(props["Data"], f"{what}: GDepth:Data")
    depth = _upright(decode_range(_grey_unit(blob, what), near=near, far=far, fmt=fmt), path)
    image, notes = None, []
    if "Data" in gimage:  # the optional unblurred photo: when broken, the photo is used
        try:
            colour = f"the GImage colour image of {path.name}"
            limit = Image.MAX_IMAGE_PIXELS or MAX_DEPTH_PIXELS
            with _open_blob(_base64(gimage["Data"], colour), colour, max_pixels=limit) as im:
                image = to_float_image(np.asarray(im.convert("RGB")))
        except InputError as err:
            notes.append(f"{err}; the photo itself is used")
    words = "range inverse" if fmt == "RangeInverse" else "range linear"
    units = props.get("Units", "")
    source = (f"embedded GDepth depth map ({words}, near {near:g}, far {far:g}"
              f"{' ' + units if units else ''})")
    return EmbeddedDepth(depth=depth, kind="depth", source=source, image=image,
                         warnings=tuple(notes))


def _decode_dynamic_depth(path: Path, data: bytes, dmap: dict[str, str],
                          items: list[dict[str, str]]) -> EmbeddedDepth:
    what = f"Dynamic Depth depth map of {path}"
    near, far = _number(dmap, "Near", what), _number(dmap, "Far", what)
    uri = dmap.get("DepthURI")
    try:
        lengths = [int(it.get("Length", "0")) for it in items]
        paddings = [int(it.get("Padding", "0")) for it in items]
    except ValueError as err:
        raise InputError(f"{what}: a Container:Item has a non-integer Length") from err
    # Items after the primary image are appended to the file in directory order.
    offset = len(data) - sum(lengths[1:])
    blob = None
    for item, length, padding in zip(items[1:], lengths[1:], paddings[1:], strict=True):
        if item.get("DataURI") == uri:
            blob = data[offset : offset + length - padding]
        offset += length
    if blob is None:
        raise InputError(f"{what}: no Container:Item has DataURI {uri!r}")
    if not (blob.startswith(b"\x89PNG") or blob.startswith(b"\xff\xd8")):
        raise InputError(f"{what}: the item for {uri!r} is not where its Length says")
    fmt = dmap.get("Format", "RangeInverse")
    depth = _upright(decode_range(_grey_unit(blob, what), near=near, far=far, fmt=fmt), path)
    notes = []
    if dmap.get("MeasureType") == "OpticRay":
        notes.append("the embedded depth is distance along each ray (OpticRay), used as z")
    words = "range inverse" if fmt == "RangeInverse" else "range linear"
    source = f"embedded Dynamic Depth map ({words}, near {near:g}, far {far:g})"
    return EmbeddedDepth(depth=depth, kind="depth", source=source, warnings=tuple(notes))
