"""Structure of the ``photo3d.cli`` package: one module per subcommand, no import cycle."""

import ast
from pathlib import Path

import photo3d.cli as cli

SHARED = {"options", "progress"}


def _cli_imports(path: Path) -> set[str]:
    """Names of ``photo3d.cli`` submodules a module imports (at any depth of its code)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            if node.module.startswith("photo3d.cli."):
                names.add(node.module.split(".")[2])
            elif node.module == "photo3d.cli":
                names.update(a.name for a in node.names)
        elif isinstance(node, ast.Import):
            names.update(a.name.split(".")[2] for a in node.names
                         if a.name.startswith("photo3d.cli."))
    return names


def test_every_subcommand_has_its_module_and_the_package_has_no_import_cycle():
    folder = Path(cli.__file__).parent
    modules = {p.stem: _cli_imports(p) for p in folder.glob("*.py") if p.stem != "__init__"}
    commands = {c.__name__.rsplit(".", 1)[1] for c in cli.COMMANDS}
    assert commands == set(modules) - SHARED
    # shared modules never import a command; commands import shared ones (demo runs make)
    for name in SHARED:
        assert not modules[name] & commands, name
    for name in commands:
        allowed = SHARED | ({"make"} if name == "demo" else set())
        assert modules[name] <= allowed, (name, modules[name])
    assert modules["progress"] == set() and modules["options"] <= {"progress"}
    # every subcommand the parser knows is routed to its module's run()
    parser = cli.build_parser()
    sub = next(a for a in parser._subparsers._group_actions if a.dest == "command")
    for name, p in sub.choices.items():
        module = p.get_default("run").__module__
        assert module.startswith("photo3d.cli."), (name, module)
