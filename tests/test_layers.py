"""The tree's shape holds: no import cycles between photo3d's modules (every import
statement counted, at any depth), lower layers never import upper ones, and no
module imports another module's private names. docs/architecture.md draws the layers.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"

LAYERS = {
    # 0: foundations every layer may use
    "photo3d.errors": 0, "photo3d.progress": 0, "photo3d.config": 0, "photo3d.camera": 0,
    "photo3d.holes": 0, "photo3d.files": 0, "photo3d.parallel": 0,
    "photo3d.kernel_cache": 0, "photo3d.kernel_build": 0,
    # 1: the types that cross layers (the LDI, the meshes, the patch and its result)
    "photo3d.structures": 1,
    # 2: file formats
    "photo3d.io": 2,
    # 3: depth sources, the bundled sample
    "photo3d.depth": 3, "photo3d.sample": 3,
    # 4: the pipeline's stages, the networks
    "photo3d.stages": 4, "photo3d.nets": 4,
    # 5: fill backends, mesh builders
    "photo3d.inpaint": 5, "photo3d.mesh": 5,
    # 6: rendering, the viewer
    "photo3d.render": 6, "photo3d.viewer": 6,
    # 7: the 3D photo, its folder, the memory check, its exports (splats, USDZ, quilts)
    "photo3d.photo": 7, "photo3d.output": 7, "photo3d.save_options": 7,
    "photo3d.owned": 7, "photo3d.resources": 7, "photo3d.export": 7,
    # 8: make, and make into an output folder (the path `make` and `batch` share)
    "photo3d.pipeline": 8, "photo3d.folder": 8, "photo3d.kernels": 8,
    # 9: what runs make many times
    "photo3d.eval": 9, "photo3d.train": 9, "photo3d.batch": 9,
    # 10: the command line
    "photo3d.cli": 10, "photo3d.__main__": 10, "photo3d.ui": 10,
}


def modules() -> dict[str, Path]:
    """Module name -> file of every module under src/photo3d."""
    found = {}
    for f in (SRC / "photo3d").rglob("*.py"):
        parts = f.relative_to(SRC).with_suffix("").parts
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = f
    return found


def imports(name: str, file: Path) -> list[tuple[str, list[str]]]:
    """``(module, names)`` of every photo3d import statement in ``file``."""
    package = name if file.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(file.read_text())):
        if isinstance(node, ast.Import):
            found += [(a.name, []) for a in node.names if a.name.startswith("photo3d")]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            if base.startswith("photo3d"):
                found.append((base, [a.name for a in node.names]))
    return found


def graph() -> dict[str, set[str]]:
    """Module -> the photo3d modules it imports (a package's __init__ importing its
    own submodules is not an edge)."""
    mods = modules()

    def target(n: str) -> str | None:
        while n and n not in mods:
            n = n.rpartition(".")[0]
        return n or None

    edges: dict[str, set[str]] = {m: set() for m in mods}
    for m, f in mods.items():
        for base, names in imports(m, f):
            for n in [base] + [f"{base}.{x}" for x in names]:
                t = target(n)
                if t and t != m and not (f.name == "__init__.py" and t.startswith(m + ".")):
                    edges[m].add(t)
    return edges


def layer(module: str) -> int | None:
    while module:
        if module in LAYERS:
            return LAYERS[module]
        module = module.rpartition(".")[0]
    return None


def test_every_module_has_a_layer():
    assert [m for m in modules() if m != "photo3d" and layer(m) is None] == []


def test_no_import_cycles():
    edges = graph()
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(v: str) -> None:  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                cycles.append(sorted(group))

    for v in edges:
        if v not in index:
            visit(v)
    assert cycles == []


def test_lower_layers_do_not_import_upper_ones():
    upward = [f"{m} (layer {layer(m)}) imports {t} (layer {layer(t)})"
              for m, targets in graph().items() if m != "photo3d"
              for t in targets if t != "photo3d" and layer(t) > layer(m)]
    assert upward == []


def test_no_module_imports_a_private_name_of_another():
    private = [f"{m} imports {base}.{n}" for m, f in modules().items()
               for base, names in imports(m, f) for n in names
               if n.startswith("_") and not n.startswith("__")]
    assert private == []


@pytest.mark.parametrize("rule", ["upward", "cycle"])
def test_the_checks_catch_a_violation(rule, monkeypatch):
    """The checks above can fail: an upward import or a cycle is reported."""
    fake = {"photo3d.errors": {"photo3d.cli"}, "photo3d.cli": set()}
    if rule == "cycle":
        fake["photo3d.cli"] = {"photo3d.errors"}
    monkeypatch.setitem(globals(), "graph", lambda: fake)
    with pytest.raises(AssertionError):
        if rule == "upward":
            test_lower_layers_do_not_import_upper_ones()
        else:
            monkeypatch.setitem(globals(), "graph", lambda: {k: set(v) for k, v in fake.items()})
            test_no_import_cycles()
