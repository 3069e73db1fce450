"""The shareable interactive 3D photo: one self-contained ``viewer.html`` per photo.

:func:`write_viewer` writes the page (WebGL2, mesh embedded, no network access);
:func:`read_viewer` reads its mesh back; :func:`serve` serves a 3D photo folder on
127.0.0.1 and opens the page (``photo3d view OUT``).
"""

from photo3d.viewer.html import VIEWER_FILE, read_viewer, write_viewer
from photo3d.viewer.serve import ViewerServer, serve

__all__ = ["VIEWER_FILE", "ViewerServer", "read_viewer", "serve", "write_viewer"]
