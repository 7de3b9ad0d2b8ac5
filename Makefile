# Springwrap: every entry point is here. `make demo` and `make test` work on a fresh clone.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMPS := $(VENV)/.stamps
KERNEL_SOURCES := $(shell find rust_core -name "*.rs" -o -name "*.toml" -o -name "*.py" -o -name "*.pyi" | grep -v /target/) Cargo.toml
ADDON_SOURCES := $(shell find addon -name "*.py" -o -name "*.toml")

.PHONY: setup demo test test-rust test-python bench lint clean test-bpy42 test-blender34 test-gui test-all-lanes package fuzz

setup: $(STAMPS)/kernel $(STAMPS)/addon $(STAMPS)/ray

$(STAMPS)/venv: requirements-dev.txt .ci/system-packages.sh
	bash .ci/system-packages.sh
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements-dev.txt
	mkdir -p $(STAMPS) && touch $@

# The batch's Ray executor and progress bar (optional for users, installed here so that `make test`
# runs the Ray batch test).
$(STAMPS)/ray: $(STAMPS)/venv requirements-ray.txt
	$(PY) -m pip install --quiet -r requirements-ray.txt
	touch $@

# The kernel is built as the same abi3 wheel users get, then installed into the venv: linked by zig
# against glibc 2.28 (tag manylinux_2_28, so it loads on older distributions), the tag checked
# against the symbol versions the library really needs (packaging/wheel_glibc.py).
$(STAMPS)/kernel: $(STAMPS)/venv $(KERNEL_SOURCES)
	rm -rf target/wheels
	PATH="$(CURDIR)/$(VENV)/bin:$$PATH" $(VENV)/bin/maturin build --release --quiet -m rust_core/python/Cargo.toml \
	  -o target/wheels --interpreter $(PY) --zig --compatibility manylinux_2_28
	$(PY) packaging/wheel_glibc.py target/wheels/springwrap_kernel-*.whl
	$(PY) -m pip install --quiet --force-reinstall --no-deps target/wheels/springwrap_kernel-*.whl
	touch $@

# The add-on is linked into the bpy module's add-on folder so addon_utils.enable("springwrap") finds it.
$(STAMPS)/addon: $(STAMPS)/venv $(ADDON_SOURCES)
	$(PY) blender_scripts/install_addon.py
	touch $@

demo: setup
	$(PY) blender_scripts/demo.py

test: setup lint test-rust test-python

# Python: ruff (rules and format in pyproject.toml); Rust: rustfmt and clippy (lints in Cargo.toml's
# [workspace.lints]), warnings as errors.
lint: $(STAMPS)/venv
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	cargo fmt --all -- --check
	cargo clippy --workspace --all-targets -- -D warnings

# The kernel's tests, with the short run of its fuzz targets (rust_core/kernel/tests/fuzz: each
# target's base number of cases, about 5 s in all; `make fuzz` for the long run).
test-rust:
	SPRINGWRAP_FUZZ_SCALE=1 cargo test --workspace --exclude springwrap-python

# The long fuzz run: every kernel fuzz target with FUZZ_SCALE times its base number of cases (60:
# about 1.2 million cases in all). A failure is shrunk and its seed saved in
# rust_core/kernel/tests/fuzz/proptest-regressions/ (commit it: every later run replays it first).
FUZZ_SCALE ?= 60
fuzz:
	SPRINGWRAP_FUZZ_SCALE=$(FUZZ_SCALE) cargo test -p springwrap-kernel --test fuzz -- --nocapture

test-python: setup
	$(PY) -m pytest -q -rs tests benchmarks/tests

# ---------------------------------------------------------------- packages
# For each platform whose kernel wheel is in WHEELS: dist/springwrap-<version>-extension-<platform>.zip
# (Blender 4.2+: manifest, add-on, kernel wheel) and dist/springwrap-<version>-legacy-<platform>.zip
# (Blender 3.4-4.1: springwrap/ with the kernel in _vendor). WHEELS defaults to target/wheels (the
# Linux wheel built here); `make package WHEELS=DIR` packages a folder of wheels for several platforms
# (the release workflow's, .github/workflows/release.yml).
WHEELS ?= target/wheels

package: $(STAMPS)/kernel
	$(PY) packaging/build_packages.py --wheel-dir $(WHEELS) --output dist

# ---------------------------------------------------------------- compatibility lanes
# The same add-on tests on bpy 4.2 LTS (a second venv) and on Debian's blender 3.4 (its own Python,
# with python3-pytest and python3-numpy from .ci/blender-packages.sh). Both use the one abi3 kernel
# wheel built by $(STAMPS)/kernel. Left out: the benchmark harness's tests (benchmarks/tests: they do not
# touch Blender), tests/packaging (the default lane already installs the packages into bpy 5.0 and
# blender 3.4) and the docs' blocks (tests/docs/test_doc_blocks.py: they name .venv's Python, the default lane's).
LANE_TESTS := tests --ignore=tests/packaging --ignore=tests/docs/test_doc_blocks.py
VENV_BPY42 := .venv-bpy42
BLENDER ?= blender
BLENDER34_KERNEL := .cache/blender34/kernel
BLENDER34_SCRIPTS := .cache/blender34/scripts

$(VENV_BPY42)/.stamps/venv: requirements-bpy42.txt
	test -x $(VENV_BPY42)/bin/python || $(PYTHON) -m venv $(VENV_BPY42)
	$(VENV_BPY42)/bin/python -m pip install --quiet --upgrade pip
	$(VENV_BPY42)/bin/python -m pip install --quiet -r requirements-bpy42.txt
	mkdir -p $(dir $@) && touch $@

$(VENV_BPY42)/.stamps/kernel: $(VENV_BPY42)/.stamps/venv $(STAMPS)/kernel
	$(VENV_BPY42)/bin/python -m pip install --quiet --force-reinstall --no-deps target/wheels/springwrap_kernel-*.whl
	touch $@

test-bpy42: $(VENV_BPY42)/.stamps/kernel
	$(VENV_BPY42)/bin/python -m pytest -q -rs $(LANE_TESTS)

$(BLENDER34_KERNEL)/.stamp: $(STAMPS)/kernel
	rm -rf $(BLENDER34_KERNEL)
	$(PY) -m pip install --quiet --no-deps --target $(BLENDER34_KERNEL) target/wheels/springwrap_kernel-*.whl
	touch $@

test-blender34: $(BLENDER34_KERNEL)/.stamp
	bash .ci/blender-packages.sh
	$(BLENDER) --version | head -1 | grep -q "^Blender 3\.4" || { echo "test-blender34: $(BLENDER) is not Blender 3.4"; exit 1; }
	mkdir -p $(BLENDER34_SCRIPTS)/addons
	BLENDER_USER_SCRIPTS=$(CURDIR)/$(BLENDER34_SCRIPTS) SPRINGWRAP_KERNEL_PATH=$(CURDIR)/$(BLENDER34_KERNEL) \
	  $(BLENDER) -b --factory-startup --python-exit-code 1 --python tests/run_in_blender.py -- -q -rs $(LANE_TESTS)

# ---------------------------------------------------------------- GUI lane
# Debian's blender 3.4 *with its interface* under a virtual X server (xvfb, software OpenGL, 1920x1080,
# --enable-event-simulate; .ci/gui-packages.sh installs what it needs): the legacy zip installed as a user
# does, the workflow through the sidebar's operators (INVOKE_DEFAULT: the live wrap, Esc, undo and redo), the
# add-on enabled without numpy, the console checked for Python errors; screenshots and console in out/gui/.
# `make test-gui GUI_ARGS=--update-docs` also copies the user guide's screenshots into docs/img.
GUI_ARGS ?=

test-gui: package
	bash .ci/gui-packages.sh
	$(BLENDER) --version | head -1 | grep -q "^Blender 3\.4" || { echo "test-gui: $(BLENDER) is not Blender 3.4"; exit 1; }
	$(PY) tests/gui/run_gui_lane.py --package "$$(ls -t dist/springwrap-*-legacy-linux_x64.zip | head -1)" --output out/gui \
	  --blender $(BLENDER) $(GUI_ARGS)

test-all-lanes: test test-bpy42 test-blender34 test-gui

# The benchmark: retargeting accuracy against Shrinkwrap and nricp, the performance sweep,
# snap throughput, the batch's throughput, feature curves against known blend centre-lines, then
# docs/benchmarks.md and docs/img/*.png.
# `make bench QUICK=1`: the ~5-minute subset.
# BENCH_OUT (the JSON) and BENCH_DOCS (benchmarks.md and img/) may point elsewhere for a trial run.
BENCH_QUICK := $(if $(QUICK),--quick,)
BENCH_OUT ?= out/bench
BENCH_DOCS ?= docs
# CGAL's fandisk (a machined part) from Debian's libcgal-demo, for benchmarks/feature_lines.py.
FANDISK ?= out/data/fandisk.off

$(FANDISK):
	mkdir -p $(@D)/cgal && cd $(@D)/cgal && apt-get download libcgal-demo && dpkg-deb -x libcgal-demo_*.deb x \
	  && tar xzf x/usr/share/doc/libcgal-dev/data.tar.gz data/meshes/fandisk.off
	cp $(@D)/cgal/data/meshes/fandisk.off $@

$(STAMPS)/bench-requirements: $(STAMPS)/venv benchmarks/requirements.txt
	$(PY) -m pip install --quiet -r benchmarks/requirements.txt
	touch $@

bench: setup $(STAMPS)/bench-requirements $(FANDISK)
	$(PY) -m benchmarks.retarget.run $(BENCH_QUICK) --json $(BENCH_OUT)/retarget.json
	$(PY) benchmarks/performance.py $(BENCH_QUICK) --json $(BENCH_OUT)/performance.json
	$(PY) benchmarks/snap_throughput.py $(BENCH_QUICK) --json $(BENCH_OUT)/snap_throughput.json
	$(PY) benchmarks/wrap_speed.py $(if $(QUICK),,--large) --json $(BENCH_OUT)/wrap_speed.json
	$(PY) benchmarks/pair_tool.py $(if $(QUICK),--edits 3 --moves 20,) --json $(BENCH_OUT)/pair_tool.json
	$(PY) benchmarks/wrap_solvers.py $(if $(QUICK),--cases sphere-ellipsoid heavy,) --scans --nricp \
	  --json $(BENCH_OUT)/wrap_solvers.json --markdown $(BENCH_DOCS)/wrap-solvers.md
	$(PY) benchmarks/batch_throughput.py $(BENCH_QUICK) --json $(BENCH_OUT)/batch_throughput.json
	$(PY) benchmarks/cage_fit.py $(if $(QUICK),--cases heavy,) --json $(BENCH_OUT)/cage_fit.json
	$(PY) benchmarks/quality_readout.py $(if $(QUICK),--cases heavy,) --json $(BENCH_OUT)/quality_readout.json
	$(PY) benchmarks/large_target.py $(if $(QUICK),--triangles 1000000,) --json $(BENCH_OUT)/large_target.json
	$(PY) benchmarks/dense_target.py $(if $(QUICK),--sizes 1250000,) --json $(BENCH_OUT)/dense_target.json
	$(PY) benchmarks/feature_curves.py $(BENCH_QUICK) --json $(BENCH_OUT)/feature_curves.json
	$(PY) benchmarks/few_anchors.py $(if $(QUICK),--cases heavy --anchors 6 24,) --json $(BENCH_OUT)/few_anchors.json
	$(PY) benchmarks/parts.py $(if $(QUICK),--cases heavy,) --json $(BENCH_OUT)/parts.json
	$(PY) benchmarks/sequence.py $(if $(QUICK),--frames 8,) --json $(BENCH_OUT)/sequence.json
	$(PY) benchmarks/feature_lines.py --off $(FANDISK) $(if $(QUICK),--anchors 8 --no-body,) \
	  --json $(BENCH_OUT)/feature_lines.json
	$(PY) benchmarks/figures.py $(if $(QUICK),--cases heavy,) --retarget $(BENCH_OUT)/retarget.json \
	  --performance $(BENCH_OUT)/performance.json --positions $(BENCH_OUT)/retarget-positions --output $(BENCH_DOCS)/img
	$(PY) benchmarks/report.py --retarget $(BENCH_OUT)/retarget.json --performance $(BENCH_OUT)/performance.json \
	  --snap $(BENCH_OUT)/snap_throughput.json --speed $(BENCH_OUT)/wrap_speed.json \
	  --batch $(BENCH_OUT)/batch_throughput.json --features $(BENCH_OUT)/feature_curves.json \
	  --quality $(BENCH_OUT)/quality_readout.json --cage-fit $(BENCH_OUT)/cage_fit.json \
	  --large-target $(BENCH_OUT)/large_target.json --dense-target $(BENCH_OUT)/dense_target.json --few-anchors $(BENCH_OUT)/few_anchors.json \
	  --parts $(BENCH_OUT)/parts.json \
	  --sequence $(BENCH_OUT)/sequence.json \
	  --pair-tool $(BENCH_OUT)/pair_tool.json \
	  --feature-lines $(BENCH_OUT)/feature_lines.json \
	  --output $(BENCH_DOCS)/benchmarks.md

clean:
	rm -rf $(VENV) $(VENV_BPY42) target out dist .cache
