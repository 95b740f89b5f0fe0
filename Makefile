# RLS: realistic LiDAR simulation for Blender.
#   make demo    set up .venv, scan the sample intersection, print where the output is
#   make test    set up .venv and the Debian tools that judge our files, build every zip,
#                run all three tiers with nothing skipped (RLS_REQUIRE_TOOLS=1):
#     make test-core     the bpy-free core (Blender's modules blocked), with fakes; needs
#                        no Debian package (tests of PCL/CloudCompare skip, saying what
#                        to install)
#     make test-blender  the bpy module: operators, extraction, the installed extension
#                        (builds only the Linux zip it installs)
#     make test-cli      python -m rls_addon in subprocesses, as users run it
#     make test-fast     the core and Blender tiers without the tests marked slow, on
#                        every core (about a minute here)
#   make build   build and validate one zip per platform with Blender's tooling:
#                dist/rls_addon-<version>-{linux_x64,windows_x64,macos_arm64,macos_x64}.zip
#                (docs/platforms.md); the compiled loop is cross-compiled with Zig
#   make bench   benchmarks (about 10 minutes): docs/benchmarks.md and docs/bench_*.png

PYTHON ?= python3.11
VENV   := .venv
PY     := $(VENV)/bin/python
RUNTIME_STAMP := $(VENV)/.runtime-installed
TEST_STAMP    := $(VENV)/.test-installed
BUILD_STAMP   := $(VENV)/.build-installed
VERSION := $(shell sed -n 's/^version = "\(.*\)"/\1/p' blender_manifest.toml)
# The zip Linux x64 users (and the tests) install; the others are built beside it.
ZIP     := dist/rls_addon-$(VERSION)-linux_x64.zip

.PHONY: venv demo test test-core test-blender test-cli test-fast build build-linux system-deps \
	clean bench native

venv: $(RUNTIME_STAMP)

$(RUNTIME_STAMP): requirements.txt
	@command -v $(PYTHON) >/dev/null 2>&1 || { \
	  echo "make: error: Python 3.11 not found (looked for '$(PYTHON)'). The bpy 5.0.1 wheel exists only for CPython 3.11: install Python 3.11, or run 'make PYTHON=/path/to/python3.11'." >&2; exit 1; }
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)' || { \
	  echo "make: error: '$(PYTHON)' is Python $$($(PYTHON) -c 'import sys; print("%d.%d" % sys.version_info[:2])'), but bpy 5.0.1 needs Python 3.11: run 'make PYTHON=/path/to/python3.11'." >&2; exit 1; }
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements.txt
	@touch $@

$(TEST_STAMP): $(RUNTIME_STAMP) requirements-test.txt
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements-test.txt -c requirements.txt
	@touch $@

# The build's own tools: Zig's C compiler (the ziglang wheel) cross-compiles the loop.
# Without it the build still writes every zip and says which have no compiled loop.
$(BUILD_STAMP): $(RUNTIME_STAMP) requirements-build.txt
	@$(PY) -m pip install --quiet --disable-pip-version-check -r requirements-build.txt -c requirements.txt \
	  && touch $@ \
	  || echo "make: warning: could not install requirements-build.txt (ziglang): the zips of other platforms get no compiled loop" >&2

# Debian packages the tests use, as command:package. PCL's command-line tools judge our
# PCD files (pcl-tools); g++, pkg-config and PCL's headers (libpcl-dev: about 1 GB and a
# minute to install) build a reader of each LiDAR driver's typed point
# (tests/core/native); CloudCompare reads our PLY files headless (cloudcompare); open3d,
# the reference caster of tests and benchmarks, loads libusb-1.0 (libusb-1.0-0).
SYSTEM_PACKAGES := pcl_pcd2ply:pcl-tools g++:g++ pkg-config:pkgconf CloudCompare:cloudcompare
system-deps:
	@missing=""; \
	for pair in $(SYSTEM_PACKAGES); do \
	  command -v $${pair%%:*} >/dev/null 2>&1 || missing="$$missing $${pair#*:}"; \
	done; \
	ls /usr/include/pcl-*/pcl/io/pcd_io.h >/dev/null 2>&1 || missing="$$missing libpcl-dev"; \
	ldconfig -p | grep -q 'libusb-1.0.so.0 ' || missing="$$missing libusb-1.0-0"; \
	[ -z "$$missing" ] || { \
	  if [ "$$(id -u)" = 0 ]; then \
	    echo "make: installing Debian packages:$$missing"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing >/dev/null; \
	  else \
	    echo "make: error: Debian packages the tests need are missing: run 'sudo apt-get install$$missing'" >&2; exit 1; \
	  fi; }

# The optional C loop over Embree packets for this machine, in place (needs gcc;
# without it Embree runs slower). make build cross-compiles it for every zip.
native: $(RUNTIME_STAMP)
	$(PY) tools/build_native.py

build: native $(BUILD_STAMP)
	$(PY) tools/build_extension.py --out dist

# Only the zip the Blender and command-line tiers install (Linux x64: no Zig needed),
# built again when a file that goes into it changed.
ZIP_INPUTS = $(shell find rls_addon presets -type f ! -name '*.pyc' ! -path '*/__pycache__/*') \
	blender_manifest.toml tools/build_extension.py
build-linux: native
	@$(MAKE) --no-print-directory $(ZIP)

$(ZIP): $(ZIP_INPUTS)
	$(PY) tools/build_extension.py --out dist --platforms linux-x64

demo: native
	$(PY) -m rls_addon demo --out out/demo

# Everything, nothing skipped: the Debian tools installed, every platform's zip built,
# and a missing tool a failure (RLS_REQUIRE_TOOLS, exported to the tiers below).
test: export RLS_REQUIRE_TOOLS := 1
test: system-deps build test-core test-blender test-cli

test-core: $(TEST_STAMP) native
	$(PY) -m pytest tests/core -p tests.no_blender

test-blender: $(TEST_STAMP) build-linux
	$(PY) -m pytest tests/blender

test-cli: $(TEST_STAMP) build-linux
	$(PY) -m pytest tests/cli

# The quick loop: the core and Blender tiers without the tests marked slow, on every
# core (pytest-xdist); the command-line tier runs with make test-cli.
test-fast: $(TEST_STAMP) build-linux
	$(PY) -m pytest tests/core -p tests.no_blender -m "not slow" -q -n auto --dist loadfile
	$(PY) -m pytest tests/blender -m "not slow" -q -n auto --dist loadfile

# The benchmark needs what the tests need (open3d as the reference caster: its module
# loads libusb-1.0, which a bare Debian lacks).
bench: system-deps $(TEST_STAMP) native
	$(PY) bench/run.py --out docs

clean:
	rm -rf build dist out .pytest_cache
