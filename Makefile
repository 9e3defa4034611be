# The two set-up commands of the README: `make demo` (the main job) and `make test` (lint, then the whole suite).
# Each creates the virtual environment .venv on first use and installs what it needs into it, at the exact
# versions of constraints.txt.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: demo test browser services clean

$(BIN)/.installed: pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -c constraints.txt -e '.[test]'
	touch $@

demo: $(BIN)/.installed
	$(BIN)/ray3d demo

test: $(BIN)/.installed browser services
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/python -m pytest -q

# Headless Chromium for the HTML viewer's test (Debian packages); without it that one test is skipped.
browser:
	@command -v chromium >/dev/null 2>&1 || { \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    apt-get install -y -q chromium chromium-driver >/dev/null 2>&1 || \
	    { apt-get update -q >/dev/null 2>&1 && apt-get install -y -q chromium chromium-driver >/dev/null 2>&1; } || \
	    echo "note: could not install Chromium; the HTML viewer test will be skipped"; \
	  else echo "note: Chromium missing and not installable here; the HTML viewer test will be skipped"; fi; }

# The real servers some tests start (Debian packages): PostgreSQL for the store, Mosquitto for MQTT, an RTSP server
# and FFmpeg for a network stream; without them those tests are skipped, saying why.
SERVICES := postgresql mosquitto rtsp-server-perl ffmpeg
services:
	@missing=""; \
	for package in $(SERVICES); do dpkg -s $$package >/dev/null 2>&1 || missing="$$missing $$package"; done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    apt-get install -y -q $$missing >/dev/null 2>&1 || \
	    { apt-get update -q >/dev/null 2>&1 && apt-get install -y -q $$missing >/dev/null 2>&1; } || \
	    echo "note: could not install$$missing; the tests that need them will be skipped"; \
	  else echo "note:$$missing missing and not installable here; the tests that need them will be skipped"; fi; \
	fi

clean:
	rm -rf $(VENV) build src/*.egg-info .pytest_cache .hypothesis
