"""``export``'s peak, and what ``make --export`` adds: per LDI pixel (read from
``photo3d.npz``'s header before the file is loaded), by what each format holds.

The writers run two at a time and share the splats and the light mesh
(:func:`photo3d.export.submit_writers`), so the terms are: the loaded 3D photo, the
splats (built once), the splat files' buffers, the light mesh (built once for
``mesh.usdz`` and the quilt: up to about 700 bytes per pixel of a fragmented LDI) and
the quilt's views. Measured with ``benchmarks/bench_memory.py --export`` on the
noisiest 3D photo (3x3 blocks of noise at 1024 px: every pixel its own splat) and on
the bundled sample (RESULTS.md, "export").

Example:
    >>> round(export_memory_estimate(1_453_295, ["splats.spz", "quilt"]) / 1e9, 2)
    1.95
    >>> round(export_memory_estimate(1_453_295, ["splats.spz"], splat_fit=False) / 1e9, 2)
    0.53
"""

from __future__ import annotations

from collections.abc import Sequence

from photo3d.resources.model import BASE_BYTES, Estimate, check

LOAD_BYTES_PER_LDI_PIXEL = 80
"""The loaded LDI (its arrays and the reader's temporaries), per LDI pixel."""
SPLAT_BYTES_PER_LDI_PIXEL = 120
"""The splats built from it (positions, colours, scales, rotations and the adaptive
quadtree's blocks, or dense: one splat per pixel, 56 bytes and the temporaries making
them; ``splats.spz`` and ``splats.ply`` of 1.86M dense splats peaked at 595 MB)."""
SPLAT_FILE_BYTES = {"splats.ply": 40, "splats.spz": 30, "splats.glb": 40}
"""Each splat file's encoding buffers per splat (at most one per LDI pixel)."""
MESH_BYTES_PER_LDI_PIXEL = 700
"""The light textured mesh of ``mesh.usdz`` and the quilt, per LDI pixel (a fragmented
LDI's)."""
MESH_FILE_BYTES = {"mesh.usdz": 100, "quilt": 50}
"""What writing each mesh format adds per LDI pixel."""
FIT_BYTES_PER_LDI_PIXEL = 120
"""The splats' colours fitted (:mod:`photo3d.export.splat_fit`): Spark's weights from
the input view (about 6 per LDI pixel above the floor, each a row index and a value)
and the solver's vectors; measured 54 bytes per LDI pixel on the sample (all five
formats: 1036 MB fitted, 958 MB not, ``bench_export.py``)."""
QUILT_BYTES = 150e6
"""The quilt's views and its image, whatever the LDI (a fixed size)."""


def export_terms(ldi_pixels: int, formats: Sequence[str], *,
                 splat_fit: bool = True) -> tuple[tuple[str, int], ...]:
    """The terms (besides the base and the loaded LDI) of writing ``formats`` of an LDI
    of ``ldi_pixels`` pixels (``splat_fit``: the splats' colours fitted): what ``make
    --export`` adds to ``make``."""
    formats = list(dict.fromkeys(formats))
    splat_files = [f for f in formats if f in SPLAT_FILE_BYTES]
    mesh_files = [f for f in formats if f in MESH_FILE_BYTES]
    # two writers at once: the two largest buffers
    files = sorted([SPLAT_FILE_BYTES[f] for f in splat_files]
                   + [MESH_FILE_BYTES[f] for f in mesh_files], reverse=True)[:2]
    terms = []
    if splat_files:
        terms.append(("splats", SPLAT_BYTES_PER_LDI_PIXEL * ldi_pixels))
        if splat_fit:
            terms.append(("splat fit", FIT_BYTES_PER_LDI_PIXEL * ldi_pixels))
    if mesh_files:
        terms.append(("light mesh", MESH_BYTES_PER_LDI_PIXEL * ldi_pixels))
    if files:
        terms.append(("writers", sum(files) * ldi_pixels))
    if "quilt" in formats:
        terms.append(("quilt views", int(QUILT_BYTES)))
    return tuple((name, int(b)) for name, b in terms)


def export_estimate(ldi_pixels: int, formats: Sequence[str], *,
                    splat_fit: bool = True) -> Estimate:
    """``photo3d export``'s peak writing ``formats`` of a 3D photo of ``ldi_pixels``
    (``splat_fit``: the splats' colours fitted)."""
    return Estimate("export", (("base", int(BASE_BYTES)),
                               ("the 3D photo", LOAD_BYTES_PER_LDI_PIXEL * ldi_pixels),
                               *export_terms(ldi_pixels, formats, splat_fit=splat_fit)))


def export_memory_estimate(ldi_pixels: int, formats: Sequence[str], *,
                           splat_fit: bool = True) -> int:
    """Peak bytes ``photo3d export`` needs to write ``formats`` (names of
    :data:`photo3d.save_options.EXPORT_FORMATS`) of a 3D photo of ``ldi_pixels``
    LDI pixels, whatever the LDI holds (:func:`export_estimate`)."""
    return export_estimate(ldi_pixels, formats, splat_fit=splat_fit).bytes


def check_export_memory(ldi_pixels: int, formats: Sequence[str], *,
                        splat_fit: bool = True) -> None:
    """Raise :class:`~photo3d.errors.ConfigError` if exporting ``formats`` would need
    more memory than is available (:func:`export_memory_estimate`).

    Example:
        >>> check_export_memory(300_000, ["splats.ply"])  # within any machine
    """
    check(export_estimate(ldi_pixels, formats, splat_fit=splat_fit),
          what=f"exporting {', '.join(dict.fromkeys(formats))} of a 3D photo of "
               f"{ldi_pixels:,} LDI pixels",
          advice="export fewer formats at a time")
