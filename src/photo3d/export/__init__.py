"""``photo3d export``: a saved 3D photo in the formats people view 3D in today.

* ``splats.ply``: ``splats.ply``, the 3DGS PLY (:mod:`photo3d.export.splats`);
* ``splats.spz``: ``splats.spz``, Niantic's SPZ (:mod:`photo3d.export.splats`);
* ``splats.glb``: ``splats.glb``, glTF with ``KHR_gaussian_splatting``
  (:mod:`photo3d.export.splats`);
* ``mesh.usdz``: ``mesh.usdz`` for AR Quick Look (:mod:`photo3d.export.usdz`);
* ``quilt``: ``NAME_qsCOLSxROWSaASPECT.png``, a Looking Glass quilt
  (:mod:`photo3d.export.quilt`).

:data:`FORMATS` names each format's writer by module path: a writer is imported only
when asked for, so usd-core is needed only for ``mesh.usdz``. A writer is
``writer(ldi, path, **options)`` and writes exactly ``path``, atomically.

:func:`export_folder` reads a 3D photo folder's ``photo3d.npz`` and writes the
formats into the folder, recording each file in ``config.json``'s ``"written"`` list
as ``render`` records videos (:mod:`photo3d.owned`), so ``make --overwrite`` and a
later export replace them, and nothing else: a file of the same name that photo3d
did not write is never replaced. ``make --export`` writes them while it saves
(:class:`~photo3d.save_options.SaveOptions` ``exports``); both go through
:func:`submit_writers`, which builds what several formats share once: the splats,
and the light textured mesh that ``mesh.usdz`` and the quilt are made of.
"""

from __future__ import annotations

import fnmatch
import math
import os
from collections.abc import Sequence
from pathlib import Path

from photo3d.errors import ConfigError, InputError, OutputError
from photo3d.export.formats import FORMATS, Format  # noqa: F401 - photo3d.export's API
from photo3d.export.writers import preload, submit_writers  # noqa: F401 - photo3d.export's API
from photo3d.files.gate import check_target, reading
from photo3d.io.npz import ldi_pixels, load_npz
from photo3d.owned import EXPORT_FILES, LDI_FILE, claim_files
from photo3d.parallel import thread_pool
from photo3d.progress import StageProgress
from photo3d.resources import SPZ_LIMIT, check_export_memory, check_free_space, check_spz_limit
from photo3d.resources.outputs import export_bytes
from photo3d.structures.ldi import LDI


def export_folder(folder: str | Path, formats: Sequence[str], *,
                  output: str | Path | None = None, overwrite: bool = False,
                  density: str = "adaptive", spz_version: int = 3,
                  splat_fit: bool = True,
                  progress: StageProgress | None = None) -> list[Path]:
    """Write ``formats`` of the 3D photo saved in ``folder``.

    Args:
        folder: a 3D photo folder (``photo3d make``'s output).
        formats: names from :data:`FORMATS` (repeats are written once).
        output: write the one format asked for to this file instead of into the
            folder; a suffix, if any, must be the format's (``.ply`` for
            ``splats.ply``, ``.png`` for ``quilt``). Inside a 3D photo folder (this
            one or another) it must be an export file's name, new or recorded there,
            and it is recorded there;
            never the photo's own files (``photo3d.npz``, ``config.json``, ...).
        overwrite: replace ``output`` if it exists (files in the folder are
            replaced when photo3d wrote them, whatever this says).
        density: splat formats: ``"adaptive"`` (fewer, larger splats where the
            photo is flat) or ``"dense"`` (one per LDI pixel;
            :func:`photo3d.export.splats.build_splats`).
        spz_version: ``splats.spz``'s version, 3 (gzip) or 4 (zstd streams).
        splat_fit: splat formats: fit the splats' colours to photo3d's render
            through Spark's blend (:mod:`photo3d.export.splat_fit`; sharper in
            splat viewers; False: each splat keeps its pixels' colour).
        progress: ``progress("export", fraction)`` after each file.

    The files are written two at a time (the machine's cores), each atomically, and
    recorded in the same step as it is moved into place, so an error, Ctrl-C or
    SIGTERM leaves the files finished before it recorded and nothing half-written;
    after a signal the writers stop at their next check
    (:func:`photo3d.files.signals.check`) and no file is moved into place.

    Returns:
        The files written, in the order of ``formats``.

    Raises:
        ConfigError: an unknown format, no format, or several with ``output``; an
            unknown density or SPZ version; not enough memory
            (:func:`photo3d.resources.check_export_memory`, checked before the 3D
            photo is read); ``splats.spz`` of more splats than SPZ holds (dense: the
            LDI's pixels, before the 3D photo is read; adaptive: counted once built,
            before any file is written).
        InputError: no 3D photo in ``folder`` (or a damaged one).
        MissingExtra: a package a format needs is missing (:func:`require_extras`).
        OutputError: ``output`` ends with a suffix other than the format's
            (``.ply``, ``.spz``, ``.glb``, ``.usdz``, quilt ``.png``); less free disk
            space than the files need (a low estimate,
            :func:`photo3d.resources.outputs.export_bytes`); a file to write is a
            symbolic link (dangling too), not a
            regular file, the 3D photo being read, a file of a 3D photo folder that
            export does not write, or exists and photo3d did not write it
            (``output`` elsewhere: exists, without ``overwrite``); nothing is
            written then.

    Example:
        >>> import numpy as np, photo3d, pathlib, tempfile
        >>> photo = photo3d.make(np.full((16, 16, 3), 0.5), depth=np.ones((16, 16)),
        ...                      config=photo3d.Config(size=None))
        >>> out = photo.save(pathlib.Path(tempfile.mkdtemp()) / "out", viewer=False)
        >>> [p.name for p in export_folder(out, ["splats.spz", "splats.ply"])]
        ['splats.spz', 'splats.ply']
        >>> from photo3d.owned import recorded_files
        >>> sorted(recorded_files(out))
        ['splats.ply', 'splats.spz']
    """
    from photo3d.kernel_cache import adopt

    chosen = check_formats(formats, output=output)
    from photo3d.save_options import SaveOptions

    SaveOptions(splats=density, spz_version=spz_version, splat_fit=splat_fit)  # checks them
    require_extras([f.name for f in chosen], spz_version=spz_version)
    adopt()  # the wheel's compiled kernels, if they fit (once per process)
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"no 3D photo folder at {folder}")
    if not (folder / LDI_FILE).is_file():
        raise InputError(f"no 3D photo in {folder} (it has no {LDI_FILE})")
    with reading(folder / LDI_FILE):  # no write may reach it (the gate refuses)
        record_in = (None if output is None
                     else _check_output(Path(output), chosen[0], overwrite))
        pixels = ldi_pixels(folder / LDI_FILE)
        names = [f.name for f in chosen]
        check_export_memory(pixels, names, splat_fit=splat_fit)
        check_free_space(Path(output) if output is not None else folder / LDI_FILE,
                         export_bytes(pixels, names), what="this export")
        if "splats.spz" in names and density == "dense":  # one splat per LDI pixel
            _check_spz(pixels, dense=True)
        ldi, meta = load_npz(folder / LDI_FILE)
        return _export(folder, chosen, ldi, meta, output=output, record_in=record_in,
                       density=density, spz_version=spz_version, splat_fit=splat_fit,
                       progress=progress)


def _check_spz(splats: int, *, dense: bool) -> None:
    """Refuse ``splats.spz`` of more splats than SPZ holds, before any file is written."""
    layout = "dense" if dense else "adaptive"
    check_spz_limit(splats, what=f"splats.spz of this 3D photo ({layout})",
                    advice="export splats.ply or splats.glb instead (no such limit)"
                           + (", or --splats adaptive (fewer splats)" if dense else ""))


def _check_output(output: Path, fmt: Format, overwrite: bool) -> Path | None:
    """Refuse an ``-o`` photo3d must not write as ``fmt``, before the work; returns the
    3D photo folder it lies in (where it is recorded), or None.

    In a 3D photo folder (one holding ``photo3d.npz``) ``-o`` may name only an
    export file (:data:`~photo3d.owned.EXPORT_FILES`), one that is new or that the
    folder's record lists: never ``photo3d.npz``, ``config.json`` or the meshes.
    Elsewhere an existing file needs ``overwrite``. A suffix other than the
    format's (:attr:`Format.suffix`, case aside) is refused everywhere: ``splats.ply``
    data under ``splats.spz`` would be recorded as photo3d's SPZ. Links and inputs
    are the gate's (:func:`photo3d.files.gate.check_target`)."""
    check_target(output)
    photo = output.parent
    in_photo = (photo / LDI_FILE).is_file()
    if in_photo and not any(fnmatch.fnmatchcase(output.name, p) for p in EXPORT_FILES):
        raise OutputError(f"{output} is a file of the 3D photo folder {photo}; export "
                          "writes there only its own files (" + ", ".join(EXPORT_FILES[:4])
                          + ", quilts): choose another name")
    if fmt.suffix and output.suffix and output.suffix.lower() != fmt.suffix:
        raise OutputError(f"-o/output {output} ends with {output.suffix} but {fmt.name} is "
                          f"written as {fmt.suffix}: choose a name ending with {fmt.suffix}")
    if in_photo:
        claim_files(photo, [output.name])
        return photo
    if os.path.lexists(output) and not overwrite:
        raise OutputError(f"{output} exists; pass overwrite (--overwrite) to replace it")
    return None


def _export(folder: Path, chosen: list[Format], ldi: LDI, meta: dict, *,
            output: Path | None, record_in: Path | None, density: str,
            spz_version: int, splat_fit: bool, progress: StageProgress | None) -> list[Path]:
    """Write ``chosen`` (:func:`export_folder` once the checks are done)."""
    output = None if output is None else Path(output)
    targets = [output] if output is not None else [folder / f.filename(ldi) for f in chosen]
    if output is None:
        claim_files(folder, [t.name for t in targets])  # before writing anything
        record_in = folder
    splats = None
    if any(f.name == "splats.spz" for f in chosen) and ldi.size > SPZ_LIMIT:
        # adaptive: fewer splats than LDI pixels, how many is known once they are built
        from photo3d.export.splats import build_splats

        splats = build_splats(ldi, density=density, fit=splat_fit)
        _check_spz(len(splats), dense=density == "dense")  # before any file is written
    preload(chosen)  # before the writer threads start
    written: list[Path] = []
    error = None
    with thread_pool(2, name="export") as pool:  # zlib, numpy and writes release the GIL
        jobs = submit_writers(pool, ldi, list(zip(chosen, targets, strict=True)),
                              density=density, spz_version=spz_version,
                              splat_fit=splat_fit, light_error=_light_error(meta),
                              record_in=record_in, splats=splats)
        for job, target in zip(jobs, targets, strict=True):
            while True:  # every job ends (after a signal, at its next check) before
                try:     # this returns or raises: none moves a file in place later
                    job.result()
                except BaseException as err:  # noqa: B036 - raised below, once all ended
                    error = error or err
                    if not job.done():  # a signal interrupted the wait: wait again
                        continue
                    break
                written.append(target)
                if progress and error is None:
                    progress("export", len(written) / len(targets))
                break
    if error is not None:
        raise error
    return written


def require_extras(formats: Sequence[str], *, spz_version: int = 3) -> None:
    """Raise :class:`~photo3d.errors.MissingExtra` now if a package that one of
    ``formats`` needs is missing (``mesh.usdz``: usd-core; ``splats.spz`` of
    ``spz_version`` 4: zstd), so that ``make``, ``batch`` and ``export`` fail before
    the work, not after it.

    Example:
        >>> require_extras(["splats.spz", "quilt"])  # nothing more to install
    """
    if "mesh.usdz" in formats:
        from photo3d.export.usdz import require_usd

        require_usd()
    if "splats.spz" in formats and spz_version == 4:
        from photo3d.io.spz import zstd_module

        zstd_module()


def _light_error(meta: dict) -> float | None:
    """The light mesh's error bound a folder recorded (``save.light_error``), so the
    exports are made of the mesh in its ``mesh.glb``; None if none is recorded."""
    save = meta.get("save") if isinstance(meta, dict) else None
    value = save.get("light_error") if isinstance(save, dict) else None
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    return float(value) if ok and math.isfinite(value) and value >= 0 else None


def check_formats(formats: Sequence[str], *, output: str | Path | None = None
                  ) -> list[Format]:
    """The :class:`Format` of each name in ``formats`` (or of the one name given as a
    string), repeats dropped.

    Raises:
        ConfigError: an unknown name (one line listing the known ones), no name,
            or more than one with ``output``.

    Example:
        >>> [f.name for f in check_formats(["splats.ply", "splats.ply", "quilt"])]
        ['splats.ply', 'quilt']
        >>> check_formats(["splats.obj"])
        Traceback (most recent call last):
        photo3d.errors.ConfigError: unknown export format 'splats.obj'; choose from splats.ply, ...
    """
    if isinstance(formats, str):  # one name, not its letters
        formats = [formats]
    unknown = [name for name in formats if name not in FORMATS]
    if unknown:
        raise ConfigError(f"unknown export format {unknown[0]!r}; choose from "
                          + ", ".join(FORMATS))
    chosen = [FORMATS[name] for name in dict.fromkeys(formats)]
    if not chosen:
        raise ConfigError("no export format given; choose from " + ", ".join(FORMATS))
    if output is not None and len(chosen) > 1:
        raise ConfigError(f"-o/output takes one format, got {len(chosen)}: "
                          + ", ".join(f.name for f in chosen))
    return chosen
