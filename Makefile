# Fresh machine: `make demo` (set up + text → URDF) and `make test` (set up + tests).
SHELL := /bin/bash
ENV := source scripts/env.sh &&
PROMPT ?= a storage cabinet with two drawers and a door on the left
OUT ?= out/demo

.PHONY: setup demo generate test test-all clean
setup:
	bash scripts/setup.sh

ARGS ?=

# Main job: start the ROS 2 node on the shipped model, send PROMPT, print URDF + mesh paths.
demo: setup
	$(ENV) python -m artformer_ros.demo "$(PROMPT)" --output-dir $(OUT) $(ARGS)

# The same job without ROS.
generate: setup
	$(ENV) artformer generate "$(PROMPT)" --out $(OUT)

test: setup
	$(ENV) python -m pytest -q test

test-all: setup
	$(ENV) python -m pytest -q -m "slow or not slow" test

clean:
	rm -rf out build install log .pytest_cache
