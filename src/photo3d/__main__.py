"""``python -m photo3d`` runs the command line."""

import sys

from photo3d.cli import main

sys.exit(main())
