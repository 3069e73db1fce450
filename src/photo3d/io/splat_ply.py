"""Read and write the 3D Gaussian splatting PLY (the INRIA 3DGS layout, ``.ply``).

What :func:`write_splat_ply` writes is the minimum every splat reader takes: a binary
little-endian PLY with one ``vertex`` element and no other, whose properties are, in
this order, all ``float``::

    x y z                  centre, OpenCV camera axes (x right, y down, z forward)
    f_dc_0 f_dc_1 f_dc_2   colour as the degree-0 spherical harmonic: (rgb - 0.5) / SH_C0
    opacity                logit of the opacity
    scale_0 scale_1 scale_2  natural log of the standard deviations
    rot_0 rot_1 rot_2 rot_3  unit quaternion w, x, y, z

No comment lines (some readers stop at them). The axes are those of Apple's SHARP:
a viewer with y up shows the photo upside down until it is turned 180 degrees about
x. :func:`read_splat_ply` reads any binary PLY whose first element is ``vertex``
with these properties (others are skipped; ``f_rest_*`` coefficients are ignored).
"""

from __future__ import annotations

import os

import numpy as np

from photo3d.errors import InputError
from photo3d.files.atomic import open_write
from photo3d.structures.splats import SH_C0, Splats

PathLike = str | os.PathLike[str]

PROPERTIES = ("x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
              "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3")
"""The vertex properties written, in order (all float32)."""

_TYPES = {"char": "i1", "uchar": "u1", "short": "i2", "ushort": "u2", "int": "i4",
          "uint": "u4", "float": "f4", "double": "f8", "int8": "i1", "uint8": "u1",
          "int16": "i2", "uint16": "u2", "int32": "i4", "uint32": "u4", "float32": "f4",
          "float64": "f8"}
_ORDERS = {"binary_little_endian": "<", "binary_big_endian": ">"}
_MAX_HEADER = 1 << 16


def header(count: int) -> bytes:
    """The PLY header of ``count`` splats.

    Example:
        >>> header(7).decode().splitlines()[:3]
        ['ply', 'format binary_little_endian 1.0', 'element vertex 7']
    """
    lines = ["ply", "format binary_little_endian 1.0", f"element vertex {count}"]
    lines += [f"property float {name}" for name in PROPERTIES] + ["end_header"]
    return ("\n".join(lines) + "\n").encode("ascii")


def encode(splats: Splats) -> np.ndarray:
    """``(N, 14) float32`` rows of :data:`PROPERTIES` (the file's body).

    Example:
        >>> s = Splats(np.zeros((1, 3)), np.full((1, 3), 0.5), np.full(1, 0.5),
        ...            np.ones((1, 3)), np.array([[1.0, 0, 0, 0]]))
        >>> encode(s).tolist()
        [[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]]
    """
    positions, colors, opacity, scales, rotations = splats.checked()
    rows = np.empty((len(positions), len(PROPERTIES)), np.float32)
    rows[:, 0:3] = positions
    rows[:, 3:6] = (colors - 0.5) / SH_C0
    alpha = np.clip(opacity, 1e-6, 1 - 1e-6)
    rows[:, 6] = np.log(alpha / (1 - alpha))
    rows[:, 7:10] = np.log(scales)
    rows[:, 10:14] = rotations / np.linalg.norm(rotations, axis=1, keepdims=True)
    return rows


def write_splat_ply(path: PathLike, splats: Splats) -> None:
    """Write ``splats`` as a 3DGS PLY (see the module doc) to ``path``.

    The file is ``len(header) + 56 * N`` bytes. Write into a temporary file and
    rename it (:mod:`photo3d.files.atomic`) for an atomic result.

    Raises:
        InputError: the splats are inconsistent (:meth:`Splats.checked`).

    Example:
        >>> import pathlib, tempfile
        >>> s = Splats(np.zeros((2, 3)), np.full((2, 3), 0.25), np.full(2, 0.9),
        ...            np.full((2, 3), 0.01), np.tile([1.0, 0, 0, 0], (2, 1)))
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "splats.ply"
        >>> write_splat_ply(path, s)
        >>> back = read_splat_ply(path)
        >>> np.allclose(back.colors, 0.25), np.allclose(back.opacity, 0.9)
        (True, True)
    """
    rows = encode(splats)
    with open_write(path) as file:
        file.write(header(len(rows)))
        rows.tofile(file)


def read_splat_ply(path: PathLike) -> Splats:
    """Read a 3DGS PLY (binary, either byte order) into :class:`Splats`.

    Raises:
        InputError: the file is missing, not a binary PLY, its first element is not
            ``vertex`` or it lacks one of :data:`PROPERTIES`.
    """
    try:
        with open(path, "rb") as file:
            head = file.read(_MAX_HEADER)
            end = head.find(b"end_header\n")
            if not head.startswith(b"ply\n") or end < 0:
                raise InputError(f"{path} is not a PLY file with a complete header")
            dtype, count = _vertex_dtype(head[:end].decode("ascii", "replace"), path)
            start = end + len(b"end_header\n")
            if count * dtype.itemsize > os.fstat(file.fileno()).st_size - start:
                raise InputError(f"{path} is truncated: it declares {count} splats")
            file.seek(start)
            data = np.fromfile(file, dtype, count)
    except OSError as err:
        raise InputError(f"cannot read {path}: {err.strerror or err}") from None
    if len(data) != count:
        raise InputError(f"{path} is truncated: {len(data)} of {count} splats")
    stack = lambda *names: np.stack([column[n] for n in names], axis=1)  # noqa: E731
    with np.errstate(all="ignore"):  # non-finite results are refused below
        column = {name: data[name].astype(np.float32) for name in PROPERTIES}
        rotations = stack("rot_0", "rot_1", "rot_2", "rot_3")
        rotations /= np.maximum(np.linalg.norm(rotations, axis=1, keepdims=True), 1e-30)
        splats = Splats(positions=stack("x", "y", "z"),
                        colors=0.5 + SH_C0 * stack("f_dc_0", "f_dc_1", "f_dc_2"),
                        opacity=(1 / (1 + np.exp(-column["opacity"]))).astype(np.float32),
                        scales=np.exp(stack("scale_0", "scale_1", "scale_2")),
                        rotations=rotations)
    return finite_splats(splats, path)


def finite_splats(splats: Splats, path: PathLike) -> Splats:
    """``splats``, refused in one line when a value is NaN or infinite (a damaged file).

    Example:
        >>> s = Splats(np.zeros((1, 3)), np.zeros((1, 3)), np.ones(1), np.ones((1, 3)),
        ...            np.array([[1.0, 0, 0, 0]]))
        >>> finite_splats(s, "a.ply") is s
        True
    """
    for name in ("positions", "colors", "opacity", "scales", "rotations"):
        if not np.isfinite(getattr(splats, name)).all():
            raise InputError(f"{path} has NaN or infinite splat {name}")
    return splats


def _vertex_dtype(text: str, path: PathLike) -> tuple[np.dtype, int]:
    """The numpy dtype and count of the first element of a binary PLY header."""
    order, fields, count, element = None, [], 0, None
    for line in text.splitlines()[1:]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format":
            order = _ORDERS.get(words[1]) if len(words) > 1 else None
        elif words[0] == "element" and len(words) == 3:
            if element is not None:
                break  # only the first element is read
            element, count = words[1], int(words[2]) if words[2].isdigit() else -1
        elif words[0] == "property" and len(words) == 3 and words[1] in _TYPES:
            fields.append((words[2], order + _TYPES[words[1]] if order else "f4"))
        else:
            raise InputError(f"{path}: unsupported PLY header line {line!r}")
    if order is None:
        raise InputError(f"{path} is not a binary PLY")
    if element != "vertex" or count < 0:
        raise InputError(f"{path}: the first PLY element is not a vertex list")
    missing = [name for name in PROPERTIES if name not in dict(fields)]
    if missing:
        raise InputError(f"{path} is not a 3DGS PLY: no {', '.join(missing)}")
    return np.dtype(fields), count
