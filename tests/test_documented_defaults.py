"""The defaults that docs state and that can drift from the code: the default fill named
in ``make``'s docstring, in docs/ui.md's option table and in the UI's request options;
the default depth edges in docs/ui.md's table, the UI's options and docs/cli.md."""

import re
from pathlib import Path

from photo3d.config import Config
from photo3d.pipeline import make
from photo3d.ui.job import JobOptions

DOCS = Path(__file__).resolve().parents[1] / "docs"


def test_make_docstring_names_the_default_fill_and_size():
    stated = re.search(r"defaults: (\d+) px, (\w+) inpainting", make.__doc__)
    assert stated, "make's docstring no longer states its defaults"
    assert (int(stated[1]), stated[2]) == (Config().size, Config().inpainter)


def test_ui_docs_and_page_take_the_default_fill():
    row = next(line for line in (DOCS / "ui.md").read_text().splitlines()
               if line.startswith("| `fill` |"))
    default = row.split("|")[3].strip().strip("`")
    assert default == Config().inpainter == JobOptions().fill


def test_ui_and_cli_docs_take_the_default_edges():
    row = next(line for line in (DOCS / "ui.md").read_text().splitlines()
               if line.startswith("| `edges` |"))
    assert row.split("|")[3].strip().strip("`") == Config().edges == JobOptions().edges
    cli = next(line for line in (DOCS / "cli.md").read_text().splitlines()
               if line.startswith("| `--edges"))
    assert f"`{Config().edges}` (default" in cli
