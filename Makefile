# make plan: create .venv, install, run the default job.  make test: the import contracts, ruff, the documentation site
# built --strict and the test suite (what CI runs); it installs nothing outside .venv (the browser tests skip, in one
# line, where Chromium is missing).  make browser-test: installs Chromium (apt-get) and runs the browser tests.
# make test-fast: the Drake-free tests, for the edit loop.  make docs: the documentation site, into site/.
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: plan test test-fast test-slow browser-test chromium bench docs clean

$(STAMP): pyproject.toml
	python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

plan: $(STAMP)
	mkdir -p out
	$(PY) -m app run window --html out/window.html
	@echo "The command line runs in .venv: $(PY) -m app --help (or source $(VENV)/bin/activate, then python -m app ...)"

# The browser checks need Debian's chromium, and chromedriver for the panel's (Selenium): this target installs them
# with apt-get (as root) when they are missing. Only `make browser-test` asks for it; `make test` installs nothing.
chromium:
	@if command -v chromium >/dev/null && command -v chromedriver >/dev/null; then \
		echo "browser-test: using $$(command -v chromium) and $$(command -v chromedriver)"; \
	else \
		echo "browser-test: installing Debian's chromium and chromium-driver (apt-get install, needs root)"; \
		apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver >/dev/null; \
	fi

test: $(STAMP)
	$(VENV)/bin/lint-imports
	$(VENV)/bin/ruff check app tests docs/hooks examples/*.py
	$(VENV)/bin/ruff format --check app tests docs/hooks examples/*.py
	$(VENV)/bin/mypy
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict
	$(PY) -m pytest -q

# The edit loop: the stages after collision checking on a checker of boxes in the plane, without Drake (seconds).
test-fast: $(STAMP)
	$(PY) -m pytest -q -m unit tests/test_on_toy_checker.py

test-slow: $(STAMP)
	$(PY) -m pytest -q -m slow

# The exported Meshcat page drawn by headless Chromium (WebGL via SwiftShader), and the planning panel driven in it;
# screenshots in out/browser-*.png and out/panel-*.png. Installs Debian's chromium and chromium-driver first when they
# are missing (the chromium target: apt-get, as root), and says which it uses.
browser-test: $(STAMP) chromium
	mkdir -p out
	$(PY) -m pytest -q -m browser tests/test_browser.py tests/test_panel.py

# A broken link, a page left out of the nav or an API name that no longer exists fails the build (--strict).
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict

bench: $(STAMP)
	$(PY) -m app bench oracle

clean:
	rm -rf $(VENV) out site .pytest_cache
