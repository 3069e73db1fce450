"""The exception family of photo3d.

Every error a user can cause (a missing file, a depth map of the wrong shape, an
output folder that already exists) is a :class:`Photo3DError`. The CLI prints its
message on one line and exits with status 2; the library never exits or prints.

Example:
    >>> from photo3d.errors import InputError
    >>> try:
    ...     raise InputError("depth has shape (4, 4) but image is (8, 8, 3)")
    ... except ValueError as err:
    ...     print(err)
    depth has shape (4, 4) but image is (8, 8, 3)
"""

from __future__ import annotations


class Photo3DError(ValueError):
    """Base class of every error photo3d raises on purpose."""


class InputError(Photo3DError):
    """An input file or array is missing, unreadable or inconsistent."""


class OutputError(Photo3DError):
    """An output location cannot be written (exists, not a folder, ...)."""


class ConfigError(Photo3DError):
    """A configuration value is out of range or unknown."""
