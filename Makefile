# Two entry points: `make demo` (3D photo of the bundled sample in out/demo/) and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
# Two installs: the demo's (photo3d and the sample: what `photo3d demo` runs), then for
# the tests everything else on top (torch, every extra, the test tools).
DEMO_STAMP := $(VENV)/.installed-demo
STAMP := $(VENV)/.installed
# The Khronos glTF validator (npm, 0.4 MB, no dependencies) for tests/io/test_gltf_validator.py;
# installed by `make test` when npm is there, skipped (and the test with it) otherwise.
# A real Gaussian splat renderer, Spark on three.js (npm, 50 MB, served from .node/ to
# headless Chromium) for tests/export/test_splats_browser.py; the same way.
# SPZ version 4 readers others wrote, for tests/export/test_spz_readers.py: three.js's
# SPZLoader (three 0.187, which Spark also runs on) and PlayCanvas's splat-transform
# on its engine (npm scripts off: splat-transform's optional native WebGPU module
# would download a binary; the tests use its browser build only).
NODE_DIR := .node
VALIDATOR := $(NODE_DIR)/node_modules/gltf-validator
SPARK := $(NODE_DIR)/node_modules/@sparkjsdev/spark
SPZ4 := $(NODE_DIR)/node_modules/@playcanvas/splat-transform

# A release (docs/development.md#releases): `make wheel` builds dist/photo3d-VERSION-py3-none-any.whl
# holding make's, render's and export's numba kernels compiled for portable x86-64 CPUs
# (build/kernels, rebuilt when a source changes: scripts/release/build_kernels.py, one
# set per Python 3.11+ on PATH), `make sdist` the source archive; twine checks both.
KERNELS := build/kernels
# x86-64-v3 (AVX2, FMA) first, for the CPUs that have it; generic for every other x86-64 CPU
KERNEL_CPUS ?= x86-64-v3 generic
RELEASE_STAMP := $(VENV)/.installed-release
KERNEL_SOURCES := $(shell find src/photo3d -name '*.py') scripts/release/build_kernels.py

.PHONY: demo test lint bench clean kernels wheel sdist

$(DEMO_STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --disable-pip-version-check -e '.[sample]'
	touch $(DEMO_STAMP)

$(STAMP): $(DEMO_STAMP)
	$(BIN)/pip install --quiet --upgrade pip
	# torch pinned first: an unpinned spec would pull the newest CUDA build (GBs)
	$(BIN)/pip install --quiet torch==2.13.0
	$(BIN)/pip install --quiet -e '.[all,test]'
	touch $(STAMP)

# The first run compiles photo3d's numba kernels once ("compiling, once" in the bar).
demo: $(DEMO_STAMP)
	$(BIN)/photo3d demo -o out/demo --overwrite

test: $(STAMP)
	-if command -v npm >/dev/null && ! test -d $(VALIDATOR); then \
		npm install --prefix $(NODE_DIR) --no-audit --no-fund --silent gltf-validator@2.0.0-dev.3.10; fi
	-if command -v npm >/dev/null && ! test -d $(SPARK); then \
		npm install --prefix $(NODE_DIR) --no-audit --no-fund --silent @sparkjsdev/spark@2.2.0 three@0.187.0; fi
	-if command -v npm >/dev/null && ! test -d $(SPZ4); then \
		npm install --prefix $(NODE_DIR) --no-audit --no-fund --silent --ignore-scripts \
		three@0.187.0 playcanvas@2.23.3 @playcanvas/splat-transform@3.10.2; fi
	$(BIN)/ruff check src tests benchmarks scripts
	PHOTO3D_NODE_MODULES=$(CURDIR)/$(NODE_DIR) $(BIN)/python -m pytest -q

$(RELEASE_STAMP): $(DEMO_STAMP)
	$(BIN)/pip install --quiet --disable-pip-version-check -e '.[sample,release]'
	touch $(RELEASE_STAMP)

$(KERNELS)/manifest.json: $(DEMO_STAMP) $(KERNEL_SOURCES)
	$(BIN)/python scripts/release/build_kernels.py --out $(KERNELS) --all-pythons \
		$(foreach cpu,$(KERNEL_CPUS),--cpu $(cpu))

kernels: $(KERNELS)/manifest.json

# setup.py checks the caches are current (fails otherwise) and pins numba to theirs.
wheel: $(KERNELS)/manifest.json $(RELEASE_STAMP)
	rm -rf build/lib build/bdist.* dist/photo3d-*.whl
	PHOTO3D_KERNEL_CACHE=$(CURDIR)/$(KERNELS) $(BIN)/python -m build --wheel --no-isolation \
		--outdir dist .
	$(BIN)/twine check --strict dist/photo3d-*.whl

sdist: $(RELEASE_STAMP)
	rm -f dist/photo3d-*.tar.gz
	$(BIN)/python -m build --sdist --no-isolation --outdir dist .
	$(BIN)/twine check --strict dist/photo3d-*.tar.gz

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_make.py

clean:
	rm -rf $(VENV) out .pytest_cache $(NODE_DIR) build dist
