# Fresh machine: `make demo` (set up + text → URDF) and `make test` (set up + tests).
SHELL := /bin/bash
ENV := source scripts/env.sh &&
PROMPT ?= a storage cabinet with two drawers and a door on the left
OUT ?= out/demo

.PHONY: setup demo test test-all bench clean
setup:
	bash scripts/setup.sh

demo: setup
	$(ENV) artformer generate "$(PROMPT)" --out $(OUT)

test: setup
	$(ENV) python -m pytest -q test

test-all: setup
	$(ENV) python -m pytest -q -m "slow or not slow" test

clean:
	rm -rf out build install log .pytest_cache
