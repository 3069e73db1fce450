"""``photo3d ui``: a local web app and API that make 3D photos (extra ``photo3d[ui]``).

Modules, from the page down (only :mod:`~photo3d.ui.page` and
:mod:`~photo3d.ui.server` import Gradio, and only when called):

* :mod:`~photo3d.ui.server`: :func:`start` -> :class:`UiServer` (``url``, ``close()``).
* :mod:`~photo3d.ui.gate`: in front of Gradio: the ``Host:`` check, the results' route.
* :mod:`~photo3d.ui.page`: the Gradio page and the ``/make`` API endpoint.
* :mod:`~photo3d.ui.runner`: a request: checked uploads, a worker place, its own
  folder and cancel event, one-line errors.
* :mod:`~photo3d.ui.job`: :class:`JobOptions` and :func:`~photo3d.ui.job.run_job`
  (:func:`photo3d.folder.make_folder`, the depth preview, the zip, the warnings
  collected by :mod:`~photo3d.ui.notes`; :mod:`~photo3d.ui.learned`: the learned
  fill's weights).
* :mod:`~photo3d.ui.workspace`: the server's upload folder and per-request folders
  with a time-to-live, the published results; the upload check.
* :mod:`~photo3d.ui.warmup`: the background warm-up; :mod:`~photo3d.ui.progress`:
  the progress bar's stage weights; :mod:`~photo3d.ui.bundle`: the zip;
  :mod:`~photo3d.ui.options`: :class:`UiOptions`, the listen/login and Host checks.

Example:
    >>> from photo3d.ui import UiOptions, check_host
    >>> check_host(UiOptions().host, None)   # 127.0.0.1 needs no login
"""

from __future__ import annotations

from photo3d.ui.job import JobOptions
from photo3d.ui.options import UiOptions, check_host, parse_auth
from photo3d.ui.server import UiServer, start

__all__ = ["JobOptions", "UiOptions", "UiServer", "check_host", "parse_auth", "start"]
