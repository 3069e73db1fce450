"""The shareable interactive 3D photo: one self-contained ``viewer.html`` per photo.

:func:`write_viewer` writes the page (WebGL2, mesh embedded, no network access);
:func:`read_viewer` reads its mesh back; :func:`serve` serves a 3D photo folder on
127.0.0.1 and opens the page (``photo3d view OUT``).
"""

from photo3d.viewer.html import VIEWER_FILE, read_viewer, write_viewer

__all__ = ["VIEWER_FILE", "ViewerServer", "read_viewer", "serve", "write_viewer"]


def __getattr__(name: str):
    """:class:`ViewerServer` and :func:`serve` on first use: their ``http.server``
    takes 16-28 ms to import, which every ``make`` (it writes the page, it does not
    serve it) would pay."""
    if name in ("ViewerServer", "serve"):
        import importlib

        module = importlib.import_module("photo3d.viewer.serve")
        # the function, not the submodule of the same name the import just set
        globals().update(ViewerServer=module.ViewerServer, serve=module.serve)
        return globals()[name]
    raise AttributeError(f"module 'photo3d.viewer' has no attribute {name!r}")
