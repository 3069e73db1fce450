"""``photo3d ui``: a local web page (and API) that makes 3D photos, until Ctrl-C."""

from __future__ import annotations

import argparse
import math
import os
import sys


def add_parser(sub) -> None:
    """Register ``ui`` on the subparsers ``sub``."""
    ui = sub.add_parser("ui", help="serve a web page (and an API) that makes 3D photos",
                        description="Serve a local web page and API that turn a photo into "
                                    "a 3D photo (needs pip install 'photo3d[ui]').")
    ui.add_argument("--port", type=int, default=7860,
                    help="port (default %(default)s; 0: any free one)")
    ui.add_argument("--host", default="127.0.0.1",
                    help="address to listen on (default %(default)s: this machine only; "
                         "any other needs --auth)")
    ui.add_argument("--allow-host", metavar="NAME", action="append", default=[],
                    help="also answer requests addressed to this host name (repeatable; "
                         "e.g. the machine's name, or a reverse proxy's); this machine's "
                         "names always work")
    ui.add_argument("--auth", metavar="USER:PASS", default=os.environ.get("PHOTO3D_UI_AUTH"),
                    help="require this login for the page and the API (default: "
                         "$PHOTO3D_UI_AUTH, which other users cannot see in the process list)")
    ui.add_argument("--workers", type=int, default=1,
                    help="photos made at once; more requests wait in the queue (default 1)")
    ui.add_argument("--ttl", type=float, default=3600.0, metavar="SECONDS",
                    help="how long a request's results stay downloadable (default 3600)")
    ui.add_argument("--max-upload-mb", type=float, default=200.0, metavar="MB",
                    help="largest upload (default 200)")
    ui.add_argument("--no-warmup", action="store_true",
                    help="do not compile the kernels at start (the first photo does)")
    ui.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run ``photo3d ui`` until Ctrl-C; returns the exit status."""
    from photo3d.errors import ConfigError
    from photo3d.ui import UiOptions, parse_auth, start

    upload = args.max_upload_mb * 2**20
    if not (math.isfinite(upload) and upload >= 1):
        raise ConfigError(f"--max-upload-mb must be a positive number of megabytes, got "
                          f"{args.max_upload_mb:g}")
    options = UiOptions(host=args.host, port=args.port,
                        auth=parse_auth(args.auth) if args.auth else None,
                        workers=args.workers, ttl=args.ttl, max_upload_bytes=int(upload),
                        warmup=not args.no_warmup, allowed_hosts=tuple(args.allow_host))
    server = start(options)
    try:
        login = "" if options.auth is None else f", login {options.auth[0]}"
        warm = " (warming up in the background)" if options.warmup else ""
        print(f"photo3d ui: serving on {server.url}{login}{warm}", flush=True)
        print("press Ctrl-C to stop", flush=True)
        server.wait()
    except KeyboardInterrupt:  # Ctrl-C is how the user stops serving
        pass
    finally:
        server.close()
    print("photo3d ui: stopped", flush=True)
    if not server.warmup.finished:
        # A cold warm-up compiles for minutes in pool threads the interpreter would join
        # at exit; its folder is already removed, so end the process now.
        sys.stderr.flush()
        os._exit(0)
    return 0
