"""What ``photo3d ui`` is started with, and the checks that keep it safe by default.

:class:`UiOptions` holds the server's settings (address, login, workers, limits);
:func:`check_host` refuses to listen beyond this machine without a login,
:func:`parse_auth` reads ``USER:PASS`` and :func:`host_allowed` says which ``Host:``
headers the server answers. Nothing here imports Gradio.

Example:
    >>> options = UiOptions(host="0.0.0.0", auth=parse_auth("ana:s3cret"))
    >>> check_host(options.host, options.auth)
    >>> options.port, options.workers
    (7860, 1)
"""

from __future__ import annotations

import ipaddress
import math
import re
from dataclasses import dataclass

from photo3d.errors import ConfigError

LOOPBACK_NAMES = ("localhost", "localhost.", "ip6-localhost")
"""Host names that always mean this machine (besides the loopback addresses)."""

HOST_NAME = re.compile(r"[A-Za-z0-9._-]+|\[?[0-9A-Fa-f:.]+\]?")
"""A host name or an IP address (an IPv6 one may be in brackets), without a port."""

MAX_UPLOAD_BYTES = 200 * 2**20
"""Default largest upload, in bytes (a 16-bit TIFF of 24 megapixels is about 150 MB)."""


@dataclass(frozen=True)
class UiOptions:
    """Settings of the ``photo3d ui`` server.

    Attributes:
        host: address to listen on; anything but a loopback address needs ``auth``
            (:func:`check_host`).
        port: TCP port; 0 picks a free one.
        auth: ``(user, password)`` every page and API call must log in with, or None.
        workers: photos made at once; further requests wait in the queue (each
            worker holds a whole ``make`` in memory: about 1.5 GB at 1024 px).
        max_queue: requests that may wait at once; more are refused ("queue full").
        ttl: seconds a request's folder (its uploads' results, the zip) is kept after
            the request ends; the page's download links stop working after that.
        max_upload_bytes: largest file accepted, in bytes. The photo's pixel count
            is limited by ``make`` itself (twice Pillow's ``MAX_IMAGE_PIXELS``, the
            decompression-bomb limit) and the working size by the memory check.
        warmup: make a tiny photo in the background at start, so that the first
            request does not wait for numba's compilation.
        allowed_hosts: more names the server answers to in a request's ``Host:``
            header, besides this machine's (:func:`host_allowed`); e.g. the name of
            the machine or of a reverse proxy in front of it.

    Example:
        >>> UiOptions(workers=0)
        Traceback (most recent call last):
        photo3d.errors.ConfigError: workers must be >= 1, got 0
    """

    host: str = "127.0.0.1"
    port: int = 7860
    auth: tuple[str, str] | None = None
    workers: int = 1
    max_queue: int = 16
    ttl: float = 3600.0
    max_upload_bytes: int = MAX_UPLOAD_BYTES
    warmup: bool = True
    allowed_hosts: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "allowed_hosts", tuple(self.allowed_hosts))
        if not 0 <= self.port <= 65535:
            raise ConfigError(f"port must be in [0, 65535], got {self.port}")
        if self.workers < 1:
            raise ConfigError(f"workers must be >= 1, got {self.workers}")
        if self.max_queue < 1:
            raise ConfigError(f"max_queue must be >= 1, got {self.max_queue}")
        if not (math.isfinite(self.ttl) and self.ttl > 0):
            raise ConfigError(f"ttl must be a positive number of seconds, got {self.ttl}")
        if self.max_upload_bytes < 1:
            raise ConfigError(f"max_upload_bytes must be >= 1, got {self.max_upload_bytes}")
        for name in self.allowed_hosts:
            if not HOST_NAME.fullmatch(name):
                raise ConfigError(f"--allow-host takes a host name or an address without a "
                                  f"port (e.g. photos.lan), got {name!r}")
        if self.auth is not None:
            user, password = self.auth
            if not user or not password:
                raise ConfigError("auth needs a user name and a password, both non-empty")


def parse_auth(text: str) -> tuple[str, str]:
    """``"USER:PASS"`` -> ``(user, password)``; the password may hold colons.

    Raises:
        ConfigError: no colon, or an empty user or password.

    Example:
        >>> parse_auth("ana:a:b")
        ('ana', 'a:b')
        >>> parse_auth("ana")
        Traceback (most recent call last):
        photo3d.errors.ConfigError: --auth must look like USER:PASS (both non-empty)
    """
    user, colon, password = text.partition(":")
    if not (colon and user and password):
        raise ConfigError("--auth must look like USER:PASS (both non-empty)")
    return user, password


def is_loopback(host: str) -> bool:
    """True if ``host`` names this machine only (``127.0.0.0/8``, ``::1``, ``localhost``).

    Example:
        >>> [is_loopback(h) for h in ("127.0.0.1", "[::1]", "localhost", "0.0.0.0", "::")]
        [True, True, True, False, False]
    """
    name = host.strip()
    if name.startswith("[") and name.endswith("]"):
        name = name[1:-1]
    if name.lower() in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:  # another host name: it may resolve to anything
        return False


def check_host(host: str, auth: tuple[str, str] | None) -> None:
    """Refuse to serve beyond this machine without a login.

    Raises:
        ConfigError: ``host`` is not a loopback address and ``auth`` is None (one
            line naming both ways out).

    Example:
        >>> check_host("127.0.0.1", None)
        >>> check_host("0.0.0.0", None)  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        photo3d.errors.ConfigError: --host 0.0.0.0 makes photo3d ui reachable from other ...
    """
    if not host:
        raise ConfigError("--host is empty; give an address such as 127.0.0.1")
    if auth is None and not is_loopback(host):
        raise ConfigError(f"--host {host} makes photo3d ui reachable from other machines: add "
                          "--auth USER:PASS, or keep the default --host 127.0.0.1")


def url_of(host: str, port: int) -> str:
    """The address to open for a server listening on ``host:port``.

    Example:
        >>> url_of("127.0.0.1", 7860), url_of("::1", 80), url_of("0.0.0.0", 7860)
        ('http://127.0.0.1:7860/', 'http://[::1]:80/', 'http://0.0.0.0:7860/')
    """
    name = host.strip()
    if ":" in name and not name.startswith("["):
        name = f"[{name}]"
    return f"http://{name}:{port}/"


def _bare(host: str) -> str:
    """``host`` without brackets and a trailing dot, in lower case."""
    name = host.strip().lower()
    if name.startswith("[") and name.endswith("]"):
        name = name[1:-1]
    return name.rstrip(".")


def _is_address(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


def host_allowed(header: str | None, *, host: str, allowed: tuple[str, ...] = ()) -> bool:
    """True if a request whose ``Host:`` header is ``header`` may be answered by a
    server listening on ``host``; the port in the header is not compared.

    Answered: this machine's names (:func:`is_loopback`), ``host`` itself and the
    ``allowed`` names; and, for a server listening on every address (``0.0.0.0``,
    ``::``), any IP address. A page of another site that rebinds its own name to this
    machine (DNS rebinding) sends its own name, which is none of these, and gets no
    answer.

    Example:
        >>> [host_allowed(h, host="127.0.0.1") for h in
        ...  ("127.0.0.1:7860", "localhost:7860", "[::1]:7860", "evil.example:7860", None)]
        [True, True, True, False, False]
        >>> host_allowed("photos.lan", host="0.0.0.0", allowed=("photos.lan",))
        True
        >>> host_allowed("192.168.1.20:7860", host="0.0.0.0"), host_allowed(
        ...     "192.168.1.20:7860", host="127.0.0.1")
        (True, False)
    """
    if not header or any(c in header for c in " \t,/@"):
        return False
    name = header.strip()
    if name.startswith("["):  # [v6]:port
        name = name[:name.find("]") + 1] if "]" in name else name
    elif name.count(":") == 1:  # name:port
        name = name.split(":")[0]
    name = _bare(name)
    if not name:
        return False
    if is_loopback(name) or name in {_bare(h) for h in (host, *allowed)}:
        return True
    return _bare(host) in ("0.0.0.0", "::", "") and _is_address(name)
