# make plan: create .venv, install, run the default job.  make test: the import contracts and the test suite (what CI
# runs).
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: plan test test-slow browser-test chromium bench clean

$(STAMP): pyproject.toml
	python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

plan: $(STAMP)
	mkdir -p out
	$(PY) -m app run window --html out/window.html

# The browser checks need Debian's chromium, and chromedriver for the panel's (Selenium); CI machines start without them.
chromium:
	command -v chromium >/dev/null && command -v chromedriver >/dev/null || (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver >/dev/null)

test: $(STAMP) chromium
	$(VENV)/bin/lint-imports
	$(VENV)/bin/ruff check app tests
	$(VENV)/bin/ruff format --check app tests
	$(PY) -m pytest -q

test-slow: $(STAMP)
	$(PY) -m pytest -q -m slow

# The exported Meshcat page drawn by headless Chromium (WebGL via SwiftShader), and the planning panel driven in it;
# screenshots in out/browser-*.png and out/panel-*.png.
browser-test: $(STAMP) chromium
	mkdir -p out
	$(PY) -m pytest -q -m browser tests/test_browser.py tests/test_panel.py

bench: $(STAMP)
	$(PY) -m app bench oracle

clean:
	rm -rf $(VENV) out .pytest_cache
