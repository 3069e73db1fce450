"""One gate for every write (issue 45): no module outside ``photo3d.files``' writers
opens a file for writing, moves, copies, links or deletes one, or hands a path to a
library that writes (numpy, Pillow, torch, safetensors, zipfile), unless the path is
one the gate handed out in an enclosing ``with`` (``atomic_path``, ``atomic_write``,
``writing``, ``open_write``, ``stage_output``). The scan reads the source's syntax
tree, the way ``tests/test_layers.py`` reads its imports."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src" / "photo3d"

GATE = {"files/gate.py", "files/atomic.py", "files/temps.py", "files/staging.py",
        "files/rename.py"}
"""The gate: the only modules that write, rename or remove files themselves."""

HANDS_OUT = {"atomic_path", "atomic_write", "writing", "open_write", "stage_output",
             "PendingFile", "stage_photo", "open_append"}
"""Calls whose ``with ... as NAME`` (or whose result) is a path or handle of the gate."""

ALLOWED = {
    ("batch/lock.py", "batch_lock"): "removes batch.lock only if it is the very file it "
                                     "created and still holds locked (samestat)",
    ("batch/lock.py", "_take"): "opens an existing lock O_NOFOLLOW to check it is "
                               "photo3d's before locking it; never writes it",
    ("batch/lock.py", "_create"): "creates the lock with O_EXCL|O_NOFOLLOW under a "
                                  "temporary name of its own, then links it (never replaces)",
    ("batch/lock.py", "_create_in_place"): "O_EXCL|O_NOFOLLOW creation; removes only "
                                           "this call's own file",
    ("batch/manifest.py", "__enter__"): "appends with O_APPEND|O_NOFOLLOW to a manifest "
                                        "check_manifest accepted (a regular file, photo3d's)",
    ("batch/manifest.py", "_abandon"): "removes only the empty manifest this writer created",
    ("kernels.py", "_claim"): "O_EXCL claim files in numba's cache folder of photo3d",
    ("kernel_cache.py", "_write"): "the wheel's kernels into the cache folder numba's own "
                                   "locator picks (numba's files, never a user's output), "
                                   "whole or not at all",
    ("kernel_build.py", "collect"): "the release build's kernel sets (scripts/release), "
                                    "no command runs it",
    ("kernel_build.py", "write_manifest"): "the release build's manifest, likewise",
    ("kernels.py", "compile_kernels"): "removes the claims folder it created",
    ("kernels.py", "compile_from_end"): "marks a kernel done in its own claims folder",
    ("ui/workspace.py", "*"): "the UI's private workspace (0700, under its own root)",
    ("ui/server.py", "*"): "the UI's per-job folders inside its workspace",
    ("viewer/serve.py", "*"): "opens files for reading only (O_RDONLY)",
    ("train/run.py", "_checkpoint"): "prunes only checkpoints checkpoints.json recorded",
    ("train/dataset.py", "_clear_cache"): "removes a data cache only after checking it "
                                          "holds nothing but what preparation writes",
    ("cli/evaluate.py", "*"): "removes only the results folder this run created",
    ("cli/render.py", "*"): "removes only the empty video/ folder this run created",
    ("io/gltf_textured.py", "encode_jpeg"): "Pillow saves into an in-memory buffer",
    ("eval/report.py", "new_results_folder"): "mkdir of a new folder (fails if it exists)",
}
"""(module, function) -> why its own file operations are safe; ``*``: the module."""

WRITE_MODES = set("wax+")
MOVES = {("shutil", n) for n in ("move", "copy", "copy2", "copyfile", "copytree", "rmtree",
                                 "copyfileobj")}
MOVES |= {("os", n) for n in ("replace", "rename", "renames", "link", "symlink", "unlink",
                              "remove", "rmdir", "removedirs", "truncate", "mkfifo")}
PATH_METHODS = {"write_bytes", "write_text", "rename", "replace", "unlink", "rmdir", "touch",
                "symlink_to", "hardlink_to", "link_to"}
LIBRARY_SAVES = {"save", "savez", "savez_compressed", "savetxt", "tofile", "save_file",
                 "imwrite", "imsave"}


def _dotted(node: ast.AST) -> str | None:
    """``a.b.c`` of a chain of attributes on a name, else None."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        head = _dotted(node.value)
        return None if head is None else f"{head}.{node.attr}"
    return None


def _gate_expr(node: ast.AST, names: set[str]) -> bool:
    """True if ``node`` is a path or handle the gate handed out (or built on one)."""
    dotted = _dotted(node)
    if dotted is not None and any(dotted == n or dotted.startswith(n + ".") for n in names):
        return True
    if isinstance(node, ast.Attribute):
        return _gate_expr(node.value, names)
    if isinstance(node, ast.BinOp):
        return _gate_expr(node.left, names)
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in (
            "str", "Path", "os.fspath"):
        return bool(node.args) and _gate_expr(node.args[0], names)
    return False


def _handed_out(node: ast.AST) -> bool:
    call = node
    if isinstance(call, ast.Call):
        func = call.func
        name = func.id if isinstance(func, ast.Name) else getattr(func, "attr", "")
        return name in HANDS_OUT
    return False


def _violations(path: Path) -> list[str]:
    rel = path.relative_to(SRC).as_posix()
    if rel in GATE:
        return []
    tree = ast.parse(path.read_text(), filename=rel)
    found = []

    def visit(node: ast.AST, function: str, names: set[str]) -> None:
        if isinstance(node, ast.ClassDef):  # self.X = PendingFile(...) in any method
            names = names | {d for sub in ast.walk(node) if isinstance(sub, ast.Assign)
                             and _handed_out(sub.value) for t in sub.targets
                             if (d := _dotted(t)) is not None}
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            function = node.name
            names = set(names)
        if isinstance(node, ast.With):
            for item in node.items:  # a handle opened on the gate's (a zip on its file)
                call = item.context_expr
                on_gate = (isinstance(call, ast.Call) and call.args
                           and _gate_expr(call.args[0], names))
                if ((_handed_out(call) or on_gate)
                        and isinstance(item.optional_vars, ast.Name)):
                    names = names | {item.optional_vars.id}
        if isinstance(node, ast.Assign) and _handed_out(node.value):
            names = names | {d for t in node.targets if (d := _dotted(t)) is not None}
        if isinstance(node, ast.Call):
            why = _unsafe(node, names)
            if why and (rel, function) not in ALLOWED and (rel, "*") not in ALLOWED:
                found.append(f"{rel}:{node.lineno} in {function}: {why}")
        for child in ast.iter_child_nodes(node):
            visit(child, function, names)

    visit(tree, "<module>", set())
    return found


def _unsafe(call: ast.Call, names: set[str]) -> str | None:
    func = call.func
    args = call.args
    if isinstance(func, ast.Name) and func.id in LIBRARY_SAVES:  # save_file(data, path)
        target = args[1] if len(args) > 1 else None
        return None if target is not None and _gate_expr(target, names) else f"{func.id}()"
    if isinstance(func, ast.Name) and func.id == "open" and args:
        mode = args[1] if len(args) > 1 else next(
            (k.value for k in call.keywords if k.arg == "mode"), None)
        if isinstance(mode, ast.Constant) and WRITE_MODES & set(str(mode.value)):
            return None if _gate_expr(args[0], names) else f"open(..., {mode.value!r})"
        return None
    if not isinstance(func, ast.Attribute):
        return None
    owner = func.value.id if isinstance(func.value, ast.Name) else None
    if func.attr == "open" and owner != "os" and len(args) > 1:  # av.open(p, "w"), ...
        mode = args[1]
        if isinstance(mode, ast.Constant) and WRITE_MODES & set(str(mode.value)):
            if _gate_expr(args[0], names) or _gate_expr(func.value, names):
                return None  # a path of the gate's, or a member of its zip
            return f"{owner}.open(..., {mode.value!r})"
    if (owner, func.attr) in MOVES:
        return f"{owner}.{func.attr}"
    if owner == "os" and func.attr == "open":
        flags = ast.unparse(args[1]) if len(args) > 1 else ""
        if any(f in flags for f in ("O_WRONLY", "O_RDWR", "O_CREAT", "O_TRUNC", "O_APPEND")):
            return "os.open for writing"
        return None
    if func.attr in PATH_METHODS and owner not in ("str",) and not (
            isinstance(func.value, ast.Constant)):
        if func.attr == "replace" and (args and isinstance(args[0], ast.Constant)
                                       or len(args) != 1 or call.keywords):
            return None  # str.replace("a", "b") / dataclasses.replace(x, **changes)
        if func.attr == "replace" and owner in ("dataclasses",):
            return None
        return None if _gate_expr(func.value, names) else f".{func.attr}()"
    if func.attr == "ZipFile" or (isinstance(func, ast.Attribute) and func.attr in LIBRARY_SAVES):
        if func.attr == "ZipFile":
            mode = args[1] if len(args) > 1 else None
            if not (isinstance(mode, ast.Constant) and WRITE_MODES & set(str(mode.value))):
                return None
        target = args[0] if args else None
        if func.attr == "tofile":
            return None if args and _gate_expr(args[0], names) else ".tofile()"
        if func.attr == "save" and owner == "torch":
            target = args[1] if len(args) > 1 else None
        if func.attr == "save_file":
            target = args[1] if len(args) > 1 else None
        if target is not None and _gate_expr(target, names):
            return None
        return f"{owner + '.' if owner else '.'}{func.attr}()"
    return None


def test_every_write_goes_through_the_gate():
    found = [v for path in sorted(SRC.rglob("*.py")) for v in _violations(path)]
    assert not found, "writes outside photo3d.files' gate:\n" + "\n".join(found)


def test_every_allowed_exception_still_exists():
    """An allow-list entry whose function is gone (or writes through the gate now) is
    dropped, so the list stays short and true."""
    stale = []
    for (rel, function), _ in ALLOWED.items():
        path = SRC / rel
        if not path.is_file():
            stale.append(f"{rel} (missing)")
            continue
        if function != "*" and f"def {function}(" not in path.read_text():
            stale.append(f"{rel}:{function}")
    assert not stale, stale


@pytest.mark.parametrize("code, why", [
    ('def f(p):\n    open(p, "w")\n', "open(..., 'w')"),
    ("def f(p):\n    p.write_bytes(b'')\n", ".write_bytes()"),
    ("import numpy as np\ndef f(p, a):\n    np.save(p, a)\n", "np.save()"),
    ("import shutil\ndef f(p, q):\n    shutil.move(p, q)\n", "shutil.move"),
    ("import os\ndef f(p, q):\n    os.replace(p, q)\n", "os.replace"),
    ("def f(p, q):\n    p.rename(q)\n", ".rename()"),
    ("import torch\ndef f(p, x):\n    torch.save(x, p)\n", "torch.save()"),
    ("def f(image, p):\n    image.save(p)\n", ".save()"),
    ("def f(t, p):\n    save_file(t, str(p))\n", "save_file()"),
    ("import av\ndef f(p):\n    av.open(str(p), 'w')\n", "av.open(..., 'w')"),
])
def test_the_scan_finds_each_kind_of_write(tmp_path, monkeypatch, code, why):
    module = SRC / "_scan_probe.py"
    monkeypatch.setattr(Path, "read_text", lambda self, *a, **k: code)
    found = _violations(module)
    assert found and why in found[0], found


def test_the_scan_accepts_a_pending_file_kept_on_self(monkeypatch):
    code = ("import av\nclass W:\n    def __init__(self, p):\n"
            "        self._file = PendingFile(p)\n"
            "    def start(self):\n        av.open(str(self._file.path), 'w')\n")
    monkeypatch.setattr(Path, "read_text", lambda self, *a, **k: code)
    assert _violations(SRC / "_scan_probe.py") == []


def test_the_scan_accepts_what_the_gate_hands_out(monkeypatch):
    code = ("import numpy as np\nfrom photo3d.files.atomic import atomic_path, open_write\n"
            "def f(p, a):\n    with atomic_path(p) as tmp:\n        np.save(tmp, a)\n"
            "    with open_write(p) as out:\n        out.write(b'')\n")
    monkeypatch.setattr(Path, "read_text", lambda self, *a, **k: code)
    assert _violations(SRC / "_scan_probe.py") == []
