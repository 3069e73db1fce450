"""``python -m photo3d`` runs the command line."""

import sys

try:
    from photo3d.cli import main
except KeyboardInterrupt:  # Ctrl-C while starting: still one line
    print("photo3d: interrupted", file=sys.stderr)  # noqa: T201
    sys.exit(130)

sys.exit(main())
