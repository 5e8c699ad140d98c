# bbzide: two commands on a fresh machine.
#   make run    set up (venv, pinned deps, the editor bundle) and open the IDE on the default world
#   make test   set up and run every test (lint, unit, corpus conformance, browser)
# Also: make bench (benchmarks/*.py), make screenshots (docs/screenshots/*.png, the README's
# pictures, taken in headless Chromium), make lint, make lock, make clean.

# Two jobs: on a fresh machine the venv (its install, then the numba warm-up, which keeps one
# core busy) and the editor bundle (npm, mostly waiting on the network) build side by side.
MAKEFLAGS += --jobs=2

PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp
# The editor page's bundle: CodeMirror 6 and our Buzz mode (editor/src/), installed from the npm
# registry at the versions of editor/package-lock.json and bundled by esbuild; never committed.
BUNDLE := bbzide/ui/static/dist/editor.js
EDITOR_SOURCES := $(wildcard editor/src/*.js) editor/build.mjs editor/package-lock.json

# The lock: every package of the whole transitive set (all extras, pip and setuptools too) at an
# exact version with its sha256 hashes, so two fresh machines install the same files. `make lock`
# regenerates it from pyproject.toml with uv (pinned in the dev extra), chosen over pip-tools: its
# --universal resolution writes one lock that holds on every platform and Python >= 3.11
# (pip-compile resolves for the machine it runs on only) and needs no sdist builds to resolve.
# Installing: pip installs the lock's own uv entry (version and hashes), then uv installs the
# whole lock with --require-hashes, which refuses any file not in it. uv rather than pip for the
# whole set: it fetches and unpacks in parallel and compiles no bytecode up front (a module's
# first import does), ~10 s of CPU where pip took ~75 s (measured on this project's lock).
LOCK       := requirements.lock
LOCK_VENV  := .venv-lock
# uv's version: the one pyproject.toml's dev extra pins (so the venv's uv is the lock-writer's)
UV_VERSION := $(shell sed -n 's/^ *"uv==\([^"]*\)",*$$/\1/p' pyproject.toml)
UV         := $(VENV)/bin/uv
UV_QUIET   := --quiet --python $(PY)
# setuptools builds bbzide itself (the editable install, without build isolation so that it is
# the locked one): the same version as [build-system] requires in pyproject.toml.
SETUPTOOLS_VERSION := 80.9.0
PIP_QUIET := --disable-pip-version-check -q

.PHONY: setup run test bench lint lock browser screenshots clean

# A new lock or pyproject.toml rebuilds the venv from nothing, so that packages dropped from the
# lock do not linger; scripts/check_lock.py then refuses a lock older than pyproject.toml's pins.
$(STAMP): pyproject.toml $(LOCK)
	rm -rf $(VENV)
	$(PYTHON) -m venv $(VENV)
	sed -n '/^uv==/,/^ *#/p' $(LOCK) | grep -v '^ *#' > $(VENV)/uv-requirement.txt
	$(PY) -m pip install $(PIP_QUIET) --no-deps --require-hashes -r $(VENV)/uv-requirement.txt
	$(UV) pip sync $(UV_QUIET) --require-hashes $(LOCK)
	$(UV) pip install $(UV_QUIET) --no-deps --no-build-isolation -e .
	$(PY) scripts/check_lock.py
	touch $(STAMP)

# The kernels' machine code (scripts/warm_kernels.py): compiled again whenever a source it is
# built from changes (a pull, an edit), not only with a new venv, so the first swarm after a
# pull does not stall a minute compiling. These are the files fastgc._kernel_sources_digest reads.
KERNEL_SOURCES := $(wildcard bbzide/vm/compiled/*.py) $(addprefix bbzide/vm/,heap_layout.py \
	message_layout.py packed_messages.py states.py)
KERNELS_WARM := $(VENV)/.kernels-warm-stamp

$(KERNELS_WARM): $(STAMP) $(KERNEL_SOURCES) scripts/warm_kernels.py
	$(PY) scripts/warm_kernels.py
	touch $(KERNELS_WARM)

$(BUNDLE): $(EDITOR_SOURCES)
	cd editor && npm ci --no-audit --no-fund --loglevel=error && node build.mjs

setup: $(STAMP) $(KERNELS_WARM) $(BUNDLE)

# Debian's Chromium drives the browser tests (Playwright never downloads a browser here).
browser:
	@bash scripts/ensure_chromium.sh

run: setup
	$(VENV)/bin/bbzide $(ARGS)

lint: setup
	$(VENV)/bin/ruff check bbzide tests benchmarks

# The tests run on every core (pytest-xdist), whole test modules per worker so that a module's
# shared fixture (an IDE and its Chromium, a recorded replay) is built once (tests/conftest.py).
# `make test TEST_WORKERS=0` runs them in one process.
TEST_WORKERS ?= auto

test: setup browser lint
	$(PY) -m pytest -n $(TEST_WORKERS) --dist loadfile $(PYTEST_ARGS)

# Regenerate the lock after a change of pyproject.toml's dependencies, then `make setup`. uv keeps
# the lock's present versions where pyproject.toml allows them (a new dependency brings only its
# own); delete requirements.lock first to move every package to its newest version.
lock:
	$(LOCK_VENV)/bin/uv --version 2>/dev/null | grep -qF 'uv $(UV_VERSION) ' || { $(PYTHON) -m venv $(LOCK_VENV) && \
		$(LOCK_VENV)/bin/pip install $(PIP_QUIET) uv==$(UV_VERSION); }
	printf 'pip\nsetuptools==$(SETUPTOOLS_VERSION)\n' | $(LOCK_VENV)/bin/uv pip compile \
		pyproject.toml - --all-extras --universal --python-version 3.11 --generate-hashes \
		--custom-compile-command 'make lock' --quiet -o $(LOCK)

bench: setup
	@set -e; for bench in benchmarks/*_bench.py; do echo "== $$bench"; $(PY) $$bench; done

screenshots: setup browser
	$(PY) scripts/screenshots.py docs/screenshots

clean:
	rm -rf $(VENV) $(LOCK_VENV) editor/node_modules bbzide/ui/static/dist build *.egg-info .pytest_cache \
		.ruff_cache
