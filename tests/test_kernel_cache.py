"""The wheel's compiled kernels (photo3d.kernel_cache; built by photo3d.kernel_build): a
cache built for the generic CPU is loaded, not compiled, on this one; one that does not
fit (cut short, altered, from another numba or Python, for a stale source) is left out
and the kernel compiles as before, with the right result; a stale cache fails the
wheel's build."""

from __future__ import annotations

import io
import json
import os
import pickle
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import photo3d
from photo3d import kernel_build, kernel_cache

ROOT = Path(__file__).resolve().parents[1]
PHOTO3D_PATH = str(Path(photo3d.__file__).resolve().parents[1])
KERNEL = """import numba


@numba.njit(cache=True)
def twice_plus(a, b):
    return 2.0 * a + b
"""
# In a fresh process: adopt the shipped folder, call the kernel, report numba's counts.
RUN = """
import json, pathlib
from photo3d.kernel_cache import adopt
import kc_pkg.kern as k
n = adopt(pathlib.Path(k.__file__).parent / "_kernel_cache")
r = k.twice_plus(1.5, 2.0)
print(json.dumps({"adopted": n, "result": r,
                  "hits": sum(k.twice_plus.stats.cache_hits.values()),
                  "misses": sum(k.twice_plus.stats.cache_misses.values())}))
"""


def _env(root: Path, **extra: str) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env.pop(kernel_cache.OFF_ENV, None)
    return dict(env, PYTHONPATH=os.pathsep.join([str(root), PHOTO3D_PATH]), **extra)


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Path:
    """A package ``kc_pkg`` with one cached kernel, its cache built for the generic
    CPU and collected into ``kc_pkg/_kernel_cache`` with a manifest."""
    root = tmp_path_factory.mktemp("built")
    package = root / "kc_pkg"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "kern.py").write_text(KERNEL)
    raw = root / "raw"
    subprocess.run([sys.executable, "-c", "import kc_pkg.kern as k; k.twice_plus(1.5, 2.0)"],
                   env=_env(root, NUMBA_CPU_NAME="generic", NUMBA_CACHE_DIR=str(raw)),
                   check=True)
    shipped = package / "_kernel_cache"
    target = kernel_build.collect(raw, shipped, package, cpu="generic")
    kernel_build.write_manifest(shipped, [target], package)
    return root


@pytest.fixture
def pkg(built, tmp_path) -> Path:
    """A fresh copy of the built package (each test may damage its own)."""
    root = tmp_path / "root"
    shutil.copytree(built, root, ignore=shutil.ignore_patterns("raw", "__pycache__"))
    return root


def run(root: Path, cache: Path) -> dict:
    out = subprocess.run([sys.executable, "-c", RUN], env=_env(root, NUMBA_CACHE_DIR=str(cache)),
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def shipped_files(root: Path) -> tuple[Path, dict]:
    shipped = root / "kc_pkg" / "_kernel_cache"
    return shipped, json.loads((shipped / kernel_cache.MANIFEST).read_text())


def rewrite_manifest(root: Path, change) -> None:
    shipped, manifest = shipped_files(root)
    change(manifest)
    (shipped / kernel_cache.MANIFEST).write_text(json.dumps(manifest))


def test_a_generic_cache_loads_on_this_cpu_without_compiling(pkg, tmp_path):
    shipped, manifest = shipped_files(pkg)
    assert manifest["targets"][0]["cpu"] == "generic"
    assert [f["source"] for f in manifest["targets"][0]["functions"]] == ["kc_pkg/kern.py"]
    got = run(pkg, tmp_path / "cache")
    assert got == {"adopted": 1, "result": 5.0, "hits": 1, "misses": 0}
    # written into numba's cache folder (NUMBA_CACHE_DIR here), not beside the package
    assert list((tmp_path / "cache").rglob("*.nbc"))
    assert not list((pkg / "kc_pkg").glob("__pycache__/*.nb*"))
    # a later process finds it adopted already, and loads it
    assert run(pkg, tmp_path / "cache") == {"adopted": 0, "result": 5.0, "hits": 1,
                                            "misses": 0}


def test_without_adopting_the_kernel_compiles(pkg, tmp_path):
    out = subprocess.run([sys.executable, "-c", RUN], capture_output=True, text=True,
                         env=dict(_env(pkg, NUMBA_CACHE_DIR=str(tmp_path / "c")),
                                  **{kernel_cache.OFF_ENV: "0"}), check=True)
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got == {"adopted": 0, "result": 5.0, "hits": 0, "misses": 1}


@pytest.mark.parametrize("damage", ["truncated data", "altered index"])
def test_a_damaged_shipped_file_is_left_out_and_the_kernel_compiles(pkg, tmp_path, damage):
    shipped, _ = shipped_files(pkg)
    kind = "*.nbi" if "index" in damage else "*.nbc"
    (path,) = shipped.rglob(kind)
    blob = bytearray(path.read_bytes())
    if damage.startswith("truncated"):
        blob = blob[: len(blob) // 2]
    else:
        blob[len(blob) // 2] ^= 0xFF
    path.write_bytes(bytes(blob))
    assert run(pkg, tmp_path / "cache") == {"adopted": 0, "result": 5.0, "hits": 0,
                                            "misses": 1}


def test_a_cache_from_another_numba_is_left_out(pkg, tmp_path):
    # the manifest says so
    rewrite_manifest(pkg, lambda m: m.update(numba="0.1.0"))
    assert run(pkg, tmp_path / "a") == {"adopted": 0, "result": 5.0, "hits": 0, "misses": 1}


def test_an_index_from_another_numba_is_left_out_even_with_a_matching_manifest(pkg, tmp_path):
    shipped, manifest = shipped_files(pkg)
    (index,) = shipped.rglob("*.nbi")
    f = io.BytesIO(index.read_bytes())
    pickle.load(f)  # numba's version, then the rest as numba wrote it
    index.write_bytes(pickle.dumps("0.1.0", protocol=-1) + f.read())
    name = index.relative_to(shipped).as_posix()
    rewrite_manifest(pkg, lambda m: m["files"].update({name: kernel_cache.sha256(index)}))
    assert run(pkg, tmp_path / "a") == {"adopted": 0, "result": 5.0, "hits": 0, "misses": 1}


def test_a_cache_for_another_python_is_left_out(pkg, tmp_path):
    def other_python(manifest):
        for function in manifest["targets"][0]["functions"]:
            function["python"] = "py399"

    rewrite_manifest(pkg, other_python)
    assert run(pkg, tmp_path / "a") == {"adopted": 0, "result": 5.0, "hits": 0, "misses": 1}


def test_a_cache_of_a_changed_source_is_left_out_and_reported(pkg, tmp_path):
    source = pkg / "kc_pkg" / "kern.py"
    source.write_text(KERNEL.replace("2.0 * a", "3.0 * a"))
    assert run(pkg, tmp_path / "a") == {"adopted": 0, "result": 6.5, "hits": 0, "misses": 1}
    shipped, _ = shipped_files(pkg)
    assert kernel_cache.check_current(shipped, pkg / "kc_pkg") == [
        "kc_pkg/kern.py: changed since the caches were built"]


def test_the_check_names_uncovered_kernel_files_and_damaged_caches(pkg):
    shipped, _ = shipped_files(pkg)
    assert kernel_cache.check_current(shipped, pkg / "kc_pkg") == []
    (pkg / "kc_pkg" / "more.py").write_text(KERNEL)
    (path,) = shipped.rglob("*.nbc")
    path.write_bytes(path.read_bytes()[:10])
    problems = kernel_cache.check_current(shipped, pkg / "kc_pkg")
    assert problems == ["kc_pkg/more.py: has cached kernels the caches do not cover",
                        f"{path.relative_to(shipped).as_posix()}: missing or not the file "
                        "the manifest lists"]


def test_the_set_is_chosen_by_triple_and_cpu_features():
    manifest = {"triple": "x86_64-unknown-linux-gnu",
                "targets": [{"cpu": "x86-64-v3"}, {"cpu": "generic"}]}
    v3 = "+avx,+avx2,+bmi,+bmi2,+f16c,+fma,+lzcnt,+movbe,+sse4.2"
    host = "x86_64-unknown-linux-gnu"
    assert kernel_cache.choose_target(manifest, (host, "znver4", v3)) == {"cpu": "x86-64-v3"}
    no_avx2 = v3.replace("+avx2", "-avx2")
    assert kernel_cache.choose_target(manifest, (host, "sandybridge", no_avx2)) == {
        "cpu": "generic"}
    assert kernel_cache.choose_target(manifest, ("aarch64-unknown-linux-gnu", "a", v3)) is None
    assert kernel_cache.choose_target({**manifest, "targets": [{"cpu": "x86-64-v3"}]},
                                      (host, "sandybridge", no_avx2)) is None


def test_a_stale_cache_fails_the_wheel_build(tmp_path):
    pytest.importorskip("setuptools")  # setup.py's own import
    # a cache built from another version of a kernel file than the tree's
    shipped = tmp_path / "kernels"
    shipped.mkdir()
    manifest = {"format": kernel_cache.FORMAT, "numba": "0", "llvmlite": "0", "triple": "t",
                "targets": [], "files": {},
                "sources": {"photo3d/stages/filters.py": "0" * 64}}
    (shipped / kernel_cache.MANIFEST).write_text(json.dumps(manifest))
    env = dict(os.environ, PHOTO3D_KERNEL_CACHE=str(shipped))
    out = subprocess.run([sys.executable, str(ROOT / "setup.py"), "--name"], cwd=ROOT, env=env,
                         capture_output=True, text=True)
    assert out.returncode != 0
    assert "photo3d/stages/filters.py: changed since the caches were built" in out.stderr
