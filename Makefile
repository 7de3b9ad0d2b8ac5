# Springwrap: every entry point is here. `make demo` and `make test` work on a fresh clone.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMPS := $(VENV)/.stamps
KERNEL_SOURCES := $(shell find rust_core -name "*.rs" -o -name "*.toml" -o -name "*.py" -o -name "*.pyi" | grep -v /target/) Cargo.toml
ADDON_SOURCES := $(shell find addon -name "*.py" -o -name "*.toml")

.PHONY: setup demo test test-rust test-python bench lint clean

setup: $(STAMPS)/kernel $(STAMPS)/addon

$(STAMPS)/venv: requirements-dev.txt .ci/system-packages.sh
	bash .ci/system-packages.sh
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements-dev.txt
	mkdir -p $(STAMPS) && touch $@

# The kernel is built as the same abi3 wheel users get, then installed into the venv.
$(STAMPS)/kernel: $(STAMPS)/venv $(KERNEL_SOURCES)
	rm -rf target/wheels
	$(VENV)/bin/maturin build --release --quiet -m rust_core/python/Cargo.toml -o target/wheels --interpreter $(PY)
	$(PY) -m pip install --quiet --force-reinstall --no-deps target/wheels/springwrap_kernel-*.whl
	touch $@

# The add-on is linked into the bpy module's add-on folder so addon_utils.enable("springwrap") finds it.
$(STAMPS)/addon: $(STAMPS)/venv $(ADDON_SOURCES)
	$(PY) blender_scripts/install_addon.py
	touch $@

demo: setup
	$(PY) blender_scripts/demo.py

test: setup test-rust test-python

test-rust:
	cargo fmt --all -- --check
	cargo test --workspace --exclude springwrap-python
	cargo clippy --workspace --all-targets -- -D warnings

test-python: setup
	$(PY) -m pytest -q tests

# The benchmark (issue 4): retargeting accuracy against Shrinkwrap and nricp, the performance sweep,
# snap throughput, then docs/benchmarks.md and docs/img/*.png. `make bench QUICK=1`: the ~5-minute subset.
BENCH_QUICK := $(if $(QUICK),--quick,)

$(STAMPS)/bench-requirements: $(STAMPS)/venv benchmarks/requirements.txt
	$(PY) -m pip install --quiet -r benchmarks/requirements.txt
	touch $@

bench: setup $(STAMPS)/bench-requirements
	$(PY) -m benchmarks.retarget.run $(BENCH_QUICK) --json out/bench/retarget.json
	$(PY) benchmarks/performance.py $(BENCH_QUICK) --json out/bench/performance.json
	$(PY) benchmarks/snap_throughput.py $(BENCH_QUICK) --json out/bench/snap_throughput.json
	$(PY) benchmarks/figures.py $(if $(QUICK),--cases heavy,)
	$(PY) benchmarks/report.py

clean:
	rm -rf $(VENV) target out dist
