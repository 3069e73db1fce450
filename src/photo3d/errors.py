"""The exception family of photo3d.

Every error a user can cause (a missing file, a depth map of the wrong shape, an
output folder that already exists, an optional package that is not installed) is a
:class:`Photo3DError`. The CLI prints its message on one line and exits with status
2; the library never exits or prints.

Optional packages are imported inside the function that needs them with
:func:`require`, which raises :class:`MissingExtra` naming the extra to install.

Example:
    >>> from photo3d.errors import InputError
    >>> try:
    ...     raise InputError("depth has shape (4, 4) but image is (8, 8, 3)")
    ... except ValueError as err:
    ...     print(err)
    depth has shape (4, 4) but image is (8, 8, 3)
"""

from __future__ import annotations

import functools
import importlib
from types import ModuleType


class Photo3DError(ValueError):
    """Base class of every error photo3d raises on purpose."""


class InputError(Photo3DError):
    """An input file or array is missing, unreadable or inconsistent."""


class OutputError(Photo3DError):
    """An output location cannot be written (exists, not a folder, ...)."""


class ConfigError(Photo3DError):
    """A configuration value is out of range or unknown."""


def install_hint(extra: str) -> str:
    """The command that installs photo3d's optional ``extra``.

    Example:
        >>> install_hint("heif")
        "pip install 'photo3d[heif]'"
    """
    return f"pip install 'photo3d[{extra}]'"


class MissingExtra(InputError, ImportError):
    """An optional package that a feature needs is not installed.

    Both an :class:`InputError` (so the CLI prints it on one line, and callers that
    add context to input errors, such as which file could not be read, still do)
    and an :class:`ImportError` (so ``except ImportError`` keeps working). Raised by
    :func:`require`.

    Args:
        purpose: what needs the package, the subject of the message
            (``"reading HEIF/HEIC photos"``).
        package: the package as users know it (``"pillow-heif"``, ``"PyTorch"``).
        extra: the photo3d extra that installs it (``"heif"``), or None for a core
            dependency (then the hint installs the top-level module itself).
        module: the module that failed to import (``"pillow_heif"``; default
            ``package``); also ``ImportError.name``.
        hint: the install command, when the default one does not fit.

    Attributes:
        purpose, package, extra: as given.
        name: the missing module.
        hint: the install command: ``pip install 'photo3d[EXTRA]'``.

    Example:
        >>> err = MissingExtra("reading HEIF/HEIC photos", "pillow-heif", "heif",
        ...                    module="pillow_heif")
        >>> print(err)
        reading HEIF/HEIC photos needs pillow-heif: pip install 'photo3d[heif]'
        >>> err.extra, err.name, isinstance(err, ImportError)
        ('heif', 'pillow_heif', True)
    """

    def __init__(self, purpose: str, package: str, extra: str | None, *,
                 module: str | None = None, hint: str | None = None) -> None:
        self.purpose = purpose
        self.package = package
        self.extra = extra
        if hint is None:
            hint = (install_hint(extra) if extra
                    else f"pip install {(module or package).split('.')[0]}")
        self.hint = hint
        ImportError.__init__(self, f"{purpose} needs {package}: {hint}", name=module or package)

    def __reduce__(self):
        rebuild = functools.partial(MissingExtra, module=self.name, hint=self.hint)
        return rebuild, (self.purpose, self.package, self.extra)


def require(module: str, extra: str | None, *, purpose: str,
            package: str | None = None) -> ModuleType:
    """Import an optional ``module``, or raise :class:`MissingExtra` naming ``extra``.

    Args:
        module: dotted module name (``"pillow_heif"``, ``"skimage.data"``).
        extra: the photo3d extra that installs it, None for a core dependency.
        purpose: what needs it, for the message (``"reading HEIF/HEIC photos"``).
        package: the package's name for users (default: ``module``).

    Returns:
        The imported module.

    Raises:
        MissingExtra: the import failed (the ImportError is its ``__cause__``).

    Example:
        >>> require("json", None, purpose="reading JSON").__name__
        'json'
        >>> require("no_such_module", "gl", purpose="the OpenGL renderer",
        ...         package="moderngl")
        Traceback (most recent call last):
        photo3d.errors.MissingExtra: the OpenGL renderer needs moderngl: pip install 'photo3d[gl]'
    """
    try:
        importlib.import_module(module.partition(".")[0])  # a missing package fails first
        return importlib.import_module(module)
    except ImportError as err:
        raise MissingExtra(purpose, package or module, extra, module=module) from err
