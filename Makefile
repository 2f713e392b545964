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

.PHONY: all setup setup-test demo test test-slow clean

all: test

setup:
	@scripts/setup_env.sh

# The set-up plus what only the tests need: Chromium, Node and Foxglove's readers (test/viewer).
setup-test:
	@scripts/setup_env.sh --test

# Replay the bundled all-channels bag through the monitor into build/demo_out (seed 002's
# Table 2 comparison: cable-winch-monitor paper).
demo: setup
	rm -rf build/demo_out
	$(VENV)/bin/cable-winch-monitor demo --out build/demo_out

test: setup-test
	$(VENV)/bin/python -m pytest -q test $(PYTEST_ARGS)

# The full diagnose runs (every candidate effect against recordings at site noise): tens of minutes.
test-slow: setup-test
	$(VENV)/bin/python -m pytest -q test -m slow $(PYTEST_ARGS)

clean:
	rm -rf build $(VENV)
