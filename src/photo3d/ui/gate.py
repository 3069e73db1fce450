"""What every request to ``photo3d ui`` meets first: an ASGI middleware in front of
the web framework that checks the ``Host:`` header and serves the requests' results.

* A request whose ``Host:`` names neither this machine nor a name the server was
  given (:func:`photo3d.ui.options.host_allowed`) gets ``421 Misdirected Request``,
  as ``photo3d view`` answers: a page of another site that rebinds its own name to
  this machine (DNS rebinding) reaches nothing.
* Results are served only at ``/photo3d/file/TOKEN/NAME``, TOKEN being what
  :meth:`~photo3d.ui.workspace.Workspace.publish` gave the request that made the file
  (128 random bits, sent only to the page or client that made the request), and
  nowhere by their path. Gradio's client downloads a file by asking Gradio's
  ``/gradio_api/file=`` route for the URL it was given: that form is answered here
  too. Any other ``/photo3d/`` address is 404. (Gradio itself serves only the
  server's upload folder.)
* An upload, a call or a websocket sent by a page of another site (its ``Origin:``
  names a host the server does not answer to) gets ``403``: a browser sends a
  cross-site upload without asking first (it only hides the answer), so any page the
  user visits could otherwise fill the server's disk with uploads.
* With a login, results need it as the rest of the server does (the session cookie
  Gradio's login sets), and so does the web framework's own description of its API
  (:data:`DESCRIPTIONS`: ``/openapi.json``, ``/docs``, ``/redoc``), which Gradio
  serves to anyone.
* A client that hangs up mid-request (an aborted upload) ends it quietly, an
  upload Gradio fails on gets ``400`` with the one-line reason, and a stream Gradio
  refuses once started (the events of an unknown session) ends: none leaves a
  traceback in the server's log.

Example:
    >>> result_token("/photo3d/file/" + "a" * 22 + "/mesh.glb")
    ('aaaaaaaaaaaaaaaaaaaaaa', 'mesh.glb')
    >>> result_token("/gradio_api/file=http://127.0.0.1:7860/photo3d/file/" + "b" * 22
    ...              + "/x.zip")
    ('bbbbbbbbbbbbbbbbbbbbbb', 'x.zip')
    >>> result_token("/gradio_api/file=/tmp/gradio/photo3d-ui-0/.photo3d-ui.lock") is None
    True
"""

from __future__ import annotations

import logging
import mimetypes
import re
from collections.abc import Callable
from http.cookies import CookieError, SimpleCookie
from urllib.parse import urlsplit

from photo3d.ui.workspace import Workspace

log = logging.getLogger(__name__)

PREFIX = "/photo3d/file/"
"""Where results are served (``PREFIX + TOKEN/NAME``)."""

_RESULT = re.compile(r"(?:/gradio_api/file[=/]https?:/+[^/]*)?/photo3d/file/"
                     r"([A-Za-z0-9_-]{22})/([^/]+)")
DESCRIPTIONS = ("/openapi.json", "/docs", "/docs/oauth2-redirect", "/redoc")
"""FastAPI's own pages about the API: they need the login too."""
_INLINE = ("image/png", "image/jpeg", "video/mp4", "video/webm", "image/gif")
"""Types a browser may show in the page (the depth map, the videos); the rest is
downloaded."""


def result_token(path: str) -> tuple[str, str] | None:
    """``(token, name)`` of a result's address (either form), or None."""
    found = _RESULT.fullmatch(path)
    return None if found is None else (found[1], found[2])


def result_url(origin: str, token: str, name: str) -> str:
    """The address of a published file for a client that reached the server at
    ``origin`` (``http://HOST:PORT``).

    Example:
        >>> result_url("http://127.0.0.1:7860", "t" * 22, "mesh.glb")
        'http://127.0.0.1:7860/photo3d/file/tttttttttttttttttttttt/mesh.glb'
    """
    return f"{origin.rstrip('/')}{PREFIX}{token}/{name}"


class Gate:
    """The ASGI middleware (``app_kwargs={"middleware": [Middleware(Gate, ...)]}``).

    Args:
        app: the application behind it.
        allows: ``allows(host header or None) -> bool``
            (:func:`photo3d.ui.options.host_allowed` with the server's settings).
        workspace: whose published files are served.
    """

    def __init__(self, app, *, allows: Callable[[str | None], bool],
                 workspace: Workspace) -> None:
        self.app = app
        self.allows = allows
        self.workspace = workspace

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        hosts = [v.decode("latin-1") for k, v in scope.get("headers", ()) if k == b"host"]
        if len(hosts) != 1 or not self.allows(hosts[0]):
            await _refuse(scope, receive, send, 421 if hosts else 400,
                          "Misdirected Request: this server does not answer to that host name"
                          if hosts else "Bad Request: exactly one Host header is required")
            return
        if not self._same_site(scope):
            await _refuse(scope, receive, send, 403, "Forbidden: a page of another site "
                                                     "cannot send requests to this server")
            return
        path = scope.get("path", "")
        if path.rstrip("/") in DESCRIPTIONS and not _logged_in(scope):
            await _refuse(scope, receive, send, 401, "Not authenticated")
            return
        found = result_token(path)
        if found is None and not path.startswith("/photo3d/"):
            await self._pass(scope, receive, send)
            return
        if scope["type"] != "http":
            await _refuse(scope, receive, send, 404, "Not Found")
            return
        await self._serve(scope, receive, send, found)

    def _same_site(self, scope) -> bool:
        """False for an upload, a call or a websocket sent by a page of another site
        (its ``Origin:`` names a host this server does not answer to, or is
        ``null``): a browser sends such a request without asking, and only hides the
        answer. Requests that change nothing (GET, HEAD, OPTIONS) and clients that are
        not browsers (no ``Origin:``) pass."""
        if scope["type"] == "http" and scope["method"] in ("GET", "HEAD", "OPTIONS"):
            return True
        origins = [v.decode("latin-1") for k, v in scope.get("headers", ()) if k == b"origin"]
        if not origins:
            return True
        parts = urlsplit(origins[0]) if len(origins) == 1 else None
        return parts is not None and parts.scheme in ("http", "https") and self.allows(
            parts.netloc)

    async def _pass(self, scope, receive, send) -> None:
        """The application's answer; a client gone meanwhile ends it quietly, a
        failed upload is a one-line 400, and a refusal of a stream already started
        (Gradio's ``queue/data`` of an unknown session) ends it with one line in the
        log (no traceback)."""
        from starlette.exceptions import HTTPException
        from starlette.requests import ClientDisconnect

        started = []

        async def sending(message) -> None:
            if message["type"] == "http.response.start":
                started.append(True)
            await send(message)

        try:
            await self.app(scope, receive, sending)
        except ClientDisconnect:
            return  # nobody to answer
        except Exception as err:
            refusal = err if isinstance(err, HTTPException) else err.__cause__
            if started and isinstance(refusal, HTTPException):  # a stream refusing late
                log.warning("photo3d ui: %s refused: %s %s", scope["path"],
                            refusal.status_code, refusal.detail)
                await send({"type": "http.response.body", "body": b"", "more_body": False})
                return
            if started or scope["type"] != "http" or not scope["path"].endswith("/upload"):
                raise
            line = f"{type(err).__name__}: {err}".splitlines()[0]
            log.warning("photo3d ui: an upload failed: %s", line)
            await _refuse(scope, receive, send, 400, f"Bad Request: the upload failed ({line})")

    async def _serve(self, scope, receive, send, found) -> None:
        from starlette.responses import FileResponse

        if scope["method"] not in ("GET", "HEAD"):
            await _refuse(scope, receive, send, 405, "Method Not Allowed")
            return
        if not _logged_in(scope):
            await _refuse(scope, receive, send, 401, "Not authenticated")
            return
        file = None if found is None else self.workspace.published(found[0])
        if file is None or file.name != found[1] or not file.is_file():
            await _refuse(scope, receive, send, 404, "Not Found (results expire; make the "
                                                     "3D photo again)")
            return
        kind = mimetypes.guess_type(file.name)[0] or "application/octet-stream"
        response = FileResponse(
            file, media_type=kind, filename=file.name,
            content_disposition_type="inline" if kind in _INLINE else "attachment",
            headers={"Cache-Control": "private, no-store", "X-Content-Type-Options": "nosniff"})
        await response(scope, receive, send)


def _logged_in(scope) -> bool:
    """True if the server has no login, or the request carries the session cookie of
    one (Gradio's ``access-token-<cookie id>``)."""
    app = scope.get("app")
    if getattr(app, "auth", None) is None and getattr(app, "auth_dependency", None) is None:
        return True
    tokens, cookie_id = getattr(app, "tokens", None), getattr(app, "cookie_id", None)
    if not isinstance(tokens, dict) or not cookie_id:
        return False
    cookie = SimpleCookie()
    for key, value in scope.get("headers", ()):
        if key == b"cookie":
            try:
                cookie.load(value.decode("latin-1"))
            except CookieError:
                return False
    names = (f"access-token-{cookie_id}", f"access-token-unsecure-{cookie_id}")
    return any(name in cookie and cookie[name].value in tokens for name in names)


async def _refuse(scope, receive, send, status: int, text: str) -> None:
    if scope["type"] == "websocket":
        await send({"type": "websocket.close", "code": 1008})
        return
    from starlette.responses import PlainTextResponse

    await PlainTextResponse(text, status_code=status)(scope, receive, send)
