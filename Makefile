# bbzide: two commands on a fresh machine.
#   make run    set up (venv, pinned deps, the editor bundle) and open the IDE on the default world
#   make test   set up and run every test (lint, unit, corpus conformance, browser)
# Also: make bench (benchmarks/*.py), make screenshots (docs/screenshots/*.png, the README's
# pictures, taken in headless Chromium), make lint, make clean.

PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp
# The editor page's bundle: CodeMirror 6 and our Buzz mode (editor/src/), installed from the npm
# registry at the versions of editor/package-lock.json and bundled by esbuild; never committed.
BUNDLE := bbzide/ui/static/dist/editor.js
EDITOR_SOURCES := $(wildcard editor/src/*.js) editor/build.mjs editor/package-lock.json

.PHONY: setup run test bench lint browser screenshots clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --disable-pip-version-check -q -e '.[dev]'
	$(PY) scripts/warm_kernels.py
	touch $(STAMP)

$(BUNDLE): $(EDITOR_SOURCES)
	cd editor && npm ci --no-audit --no-fund --loglevel=error && node build.mjs

setup: $(STAMP) $(BUNDLE)

# Debian's Chromium drives the browser tests (Playwright never downloads a browser here).
browser:
	@bash scripts/ensure_chromium.sh

run: setup
	$(VENV)/bin/bbzide $(ARGS)

lint: setup
	$(VENV)/bin/ruff check bbzide tests benchmarks

test: setup browser lint
	$(PY) -m pytest $(PYTEST_ARGS)

bench: setup
	@set -e; for bench in benchmarks/*_bench.py; do echo "== $$bench"; $(PY) $$bench; done

screenshots: setup browser
	$(PY) scripts/screenshots.py docs/screenshots

clean:
	rm -rf $(VENV) editor/node_modules bbzide/ui/static/dist build *.egg-info .pytest_cache .ruff_cache
