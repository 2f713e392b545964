# cable_winch_monitor: set-up, demo and tests in a local .venv (ROS 2 Jazzy wheels from PyPI).
SHELL := /bin/bash
VENV := .venv

# Keep DDS on this machine, and on a domain of its own unless the caller picks one.
ROS_DOMAIN_ID ?= 87
RMW_IMPLEMENTATION ?= rmw_fastrtps_cpp
ROS_LOG_DIR ?= $(CURDIR)/build/ros_log
export ROS_DOMAIN_ID RMW_IMPLEMENTATION ROS_LOG_DIR
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST

PYTEST_ARGS ?=

.PHONY: all setup setup-test setup-docs demo docs lint test test-slow clean

all: test

setup:
	@scripts/setup_env.sh

# The set-up plus what only the tests need: Chromium, Node and Foxglove's readers (test/viewer),
# and the documentation tools.
setup-test:
	@scripts/setup_env.sh --test

# The set-up plus MkDocs and its theme (requirements/docs.txt), which setup-test installs too.
setup-docs:
	@scripts/setup_env.sh --docs

# The manual (docs/, mkdocs.yml) as a site in build/docs; a warning (a broken link, a page
# left out of the navigation) fails the build.
docs: setup-docs
	rm -rf build/docs
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --site-dir build/docs

# Replay the bundled all-channels bag through the monitor into build/demo_out (seed 002's
# Table 2 comparison: cable-winch-monitor paper).
demo: setup
	rm -rf build/demo_out
	$(VENV)/bin/cable-winch-monitor demo --out build/demo_out

# ruff and mypy with the settings in pyproject.toml.
lint: setup-test
	$(VENV)/bin/ruff check .
	$(VENV)/bin/mypy

# The docs are built and the code linted first: a broken link or a type error fails in seconds, not
# after the suite.
test: setup-test docs lint
	$(VENV)/bin/python -m pytest -q test $(PYTEST_ARGS)

# The full diagnose runs (every candidate effect against recordings at site noise): tens of minutes.
test-slow: setup-test
	$(VENV)/bin/python -m pytest -q test -m slow $(PYTEST_ARGS)

clean:
	rm -rf build $(VENV)
