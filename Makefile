# HandSplice: two commands do all the set-up on a fresh Debian 12 or 13 machine (root or sudo;
# prerequisites: apt-get install -y make git python3-venv).
#   make demo   - install, then open the app on the bundled sample pair (http://127.0.0.1:5006)
#   make test   - install everything the tests need (Chromium, Mesa EGL, npm's three.js and
#                 glTF validator for the GLB tests), lint (ruff check, ruff format --check,
#                 lint-imports layering contracts), run all tests
#   make bench  - run every benchmark (benchmarks/run_all.py; results in benchmarks/RESULTS.md)
# Tried on minimal (debootstrap minbase) Debian 12 and 13 roots by tools/fresh-check.

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
SUDO   := $(shell [ "$$(id -u)" = "0" ] || echo sudo)
# Same names on Debian 12 and 13. Rendering: Mesa EGL (OSMesa fallback), pyglet headless (no X).
# The server draws no text with system fonts (the browser shows the page), so no fonts here.
DEMO_PACKAGES := libgl1 libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6
# Tests add Chromium and a font for its screenshots, libatomic1 (Playwright's bundled node)
# and npm (tests/js).
TEST_PACKAGES := $(DEMO_PACKAGES) chromium fonts-dejavu-core libatomic1 npm
PORT ?= 5006
# Two pytest-xdist workers: the browser tests one after another in one lane, every other
# module in the other (tests/conftest.py); `make test TEST_LANES=` runs them in one process.
TEST_LANES ?= -n 2 --dist loadscope --no-loadscope-reorder

export PYOPENGL_PLATFORM ?= egl
export NUMBA_CACHE_DIR ?= $(CURDIR)/.numba_cache

.PHONY: demo test gallery lint demo-deps test-deps js venv bench clean

demo: demo-deps venv
	$(BIN)/handsplice serve --port $(PORT) --show-url

test: test-deps venv js
	$(BIN)/ruff check engine webapp tests benchmarks
	$(BIN)/ruff format --check engine webapp tests benchmarks
	$(BIN)/lint-imports
	$(BIN)/python -m pytest -q $(TEST_LANES)

# the README gallery's screenshots, made by the browser tests that reach each state
gallery: test-deps venv js
	HANDSPLICE_GALLERY=1 $(BIN)/python -m pytest -q tests/test_browser.py tests/test_browser_trust.py tests/test_browser_uploads.py

lint: venv
	$(BIN)/ruff check engine webapp tests benchmarks
	$(BIN)/ruff format --check engine webapp tests benchmarks
	$(BIN)/lint-imports

# System packages: only the missing ones are installed, so a second run needs no root and no apt.
# A package counts as present when dpkg has it installed ("ii"); npm also when an npm command
# exists (NodeSource's nodejs ships one and conflicts with Debian's npm package).
define apt_ensure
	@missing=""; for p in $(1); do \
	  dpkg-query -W -f='$${db:Status-Abbrev}' $$p 2>/dev/null | grep -q '^ii' && continue; \
	  [ $$p = npm ] && command -v npm >/dev/null && continue; \
	  missing="$$missing $$p"; done; \
	if [ -z "$$missing" ]; then echo "system packages present"; else \
	  echo "installing system packages:$$missing"; \
	  $(SUDO) apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $$missing; fi
endef

demo-deps:
	$(call apt_ensure,$(DEMO_PACKAGES))

test-deps:
	$(call apt_ensure,$(TEST_PACKAGES))

# three.js (GLTFLoader) and the Khronos glTF validator for the GLB tests, pinned by the lock file
js: tests/js/node_modules/.installed

tests/js/node_modules/.installed: tests/js/package.json tests/js/package-lock.json
	cd tests/js && npm ci --no-audit --no-fund --ignore-scripts
	touch $@

venv: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[test]'
	touch $@

bench: venv
	$(BIN)/python -m benchmarks.run_all

clean:
	rm -rf $(VENV) .numba_cache .pytest_cache build *.egg-info tests/js/node_modules
