# HandSplice: two commands do all the set-up on a fresh Debian machine (root or sudo).
#   make demo   - install, then open the app on the bundled sample pair (http://127.0.0.1:5006)
#   make test   - install everything the tests need (Chromium, Mesa EGL included), lint
#                 (ruff check, ruff format --check, lint-imports layering contracts), run all tests
#   make bench  - run every benchmark (benchmarks/run_all.py; results in benchmarks/RESULTS.md)

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
SUDO   := $(shell [ "$$(id -u)" = "0" ] || echo sudo)
APT_PACKAGES := chromium libgl1 libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6 libglib2.0-0 fonts-dejavu-core
PORT ?= 5006

export PYOPENGL_PLATFORM ?= egl
export NUMBA_CACHE_DIR ?= $(CURDIR)/.numba_cache

.PHONY: demo test lint system-deps venv bench clean

demo: system-deps venv
	$(BIN)/handsplice serve --port $(PORT) --show-url

test: system-deps venv
	$(BIN)/ruff check engine webapp tests benchmarks
	$(BIN)/ruff format --check engine webapp tests benchmarks
	$(BIN)/lint-imports
	$(BIN)/python -m pytest -q

lint: venv
	$(BIN)/ruff check engine webapp tests benchmarks
	$(BIN)/ruff format --check engine webapp tests benchmarks
	$(BIN)/lint-imports

# System packages: headless OpenGL (EGL on Mesa llvmpipe, OSMesa fallback) and Chromium for browser tests.
system-deps:
	@if dpkg -s $(APT_PACKAGES) >/dev/null 2>&1; then echo "system packages present"; else \
	  $(SUDO) apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $(APT_PACKAGES); fi

venv: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[test]'
	touch $@

bench: venv
	$(BIN)/python -m benchmarks.run_all

clean:
	rm -rf $(VENV) .numba_cache .pytest_cache build *.egg-info
