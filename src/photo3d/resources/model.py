"""The one memory model: an :class:`Estimate` of a command's peak, by term, and the one
check that refuses it before the work (:func:`check`).

Every command states its peak as a sum of named terms (:data:`BASE_BYTES`, the
interpreter and libraries, plus terms linear in what the command holds: working
pixels, LDI pixels, output pixels, decoded pixels), each term's bytes per unit
measured (``benchmarks/bench_memory.py``) and rounded up. A refusal names the
command's estimate, its largest term and what to change.

Example:
    >>> est = Estimate("render --still", (("base", 200_000_000), ("frame", 900_000_000)))
    >>> est.bytes, est.largest
    (1100000000, ('frame', 900000000))
"""

from __future__ import annotations

from dataclasses import dataclass

from photo3d.errors import ConfigError
from photo3d.io import limits

BASE_BYTES = 200e6
"""Interpreter, numpy, numba and the nets' code, resident before any pixel."""


@dataclass(frozen=True)
class Estimate:
    """A command's estimated peak resident memory.

    Attributes:
        command: the command it is of (``"make"``, ``"render --still"``, ``"export"``,
            ``"depth"``, ``"train"``), named in a refusal.
        terms: ``(name, bytes)`` pairs whose sum is the peak (``"base"`` first).
    """

    command: str
    terms: tuple[tuple[str, int], ...]

    @property
    def bytes(self) -> int:
        """The estimated peak: the sum of the terms (bytes)."""
        return int(sum(b for _, b in self.terms))

    @property
    def largest(self) -> tuple[str, int]:
        """The term with the most bytes, ``(name, bytes)``."""
        return max(self.terms, key=lambda t: t[1])


def available_memory() -> int | None:
    """Bytes the system can give this process now (Linux ``MemAvailable``), or None
    (:func:`photo3d.io.limits.available_memory`, which the file readers check)."""
    from photo3d import resources  # tests stand in a smaller machine there

    return resources.available_memory()


def check(estimate: Estimate, *, what: str, advice: str, at_least: bool = False) -> None:
    """Raise :class:`ConfigError` (one line) if ``estimate`` exceeds the available
    memory: ``{what} needs about N GB of memory ({largest term}: M GB of {command}'s
    estimate) but A GB are available: {advice}``. Nothing when the available memory
    is unknown.

    ``at_least``: the estimate is a lower bound (``needs at least``).

    Example:
        >>> check(Estimate("make", (("base", 1000),)), what="a tiny photo", advice="")
    """
    need, have = estimate.bytes, available_memory()
    if have is None or need <= have:
        return
    name, part = estimate.largest
    raise ConfigError(f"{what} needs {'at least' if at_least else 'about'} "
                      f"{limits.format_bytes(need)} of memory ({name}: "
                      f"{limits.format_bytes(part)} of {estimate.command}'s estimate) but "
                      f"{limits.format_bytes(have)} are available: {advice}")
