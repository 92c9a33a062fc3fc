# Quick start: `make run` (main job) and `make test` (test suite). Both create .venv and install
# what they need on first use; a second call skips the install.
# The Python that builds .venv: PYTHON if given (a name on PATH or a path), else the first of
# python3.13, python3.12, python3.11, python3 that is 3.11 or newer (tools/find_python.sh)
PYTHON ?=
# (looked up once, on first use: only when .venv is to be made)
PYTHON_FOUND = $(eval PYTHON_FOUND := $$(shell sh tools/find_python.sh $(PYTHON)))$(PYTHON_FOUND)
# the torch version the test suite was run with; the package itself accepts a range (pyproject.toml)
CONSTRAINTS := constraints.txt
# pip's index for torch: empty = pip's default (on Linux the CUDA build, gigabytes);
# e.g. make test TORCH_INDEX=https://download.pytorch.org/whl/cpu for the CPU-only build
TORCH_INDEX ?=
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
BENCH_STAMP := $(VENV)/.installed-bench

.PHONY: install run test test-slow bench clean tb

$(PY):
	@$(if $(PYTHON_FOUND),:,exit 1)
	$(PYTHON_FOUND) -m venv $(VENV)

# torch first and explicitly, at the tested version of constraints.txt (from TORCH_INDEX when
# set): the package's install below then finds it installed and keeps it, instead of choosing a
# build itself.
$(STAMP): $(PY) pyproject.toml $(CONSTRAINTS)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -c $(CONSTRAINTS) torch $(if $(TORCH_INDEX),--index-url $(TORCH_INDEX))
	$(PY) -m pip install --quiet -c $(CONSTRAINTS) -e ".[test]"
	@touch $(STAMP)

install: $(STAMP)

# the benchmarks' reference libraries (MiniSom, pydmps), on top of the install above
$(BENCH_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -c $(CONSTRAINTS) -e ".[bench]"
	@touch $(BENCH_STAMP)

run: $(STAMP)
	$(PY) evaluate.py experiment=exp4 hydra.run.dir=outputs/exp4/latest

test: $(STAMP)
	$(PY) -m pytest -q

test-slow: $(STAMP)
	$(PY) -m pytest -q -m slow

bench: $(BENCH_STAMP)
	$(PY) benchmarks/bench_blocks.py

# TensorBoard on every run under outputs/ (LOGDIR=... for another folder), keeping every image of a
# tag (its default keeps 10 at random, so a sample trial of 20 rotation steps would lose some);
# HOST and PORT: where it listens (HOST=0.0.0.0 to open it from another machine)
LOGDIR ?= outputs/
HOST ?= localhost
PORT ?= 6006
tb: $(STAMP)
	$(VENV)/bin/tensorboard --logdir $(LOGDIR) --host $(HOST) --port $(PORT) --samples_per_plugin images=1000

clean:
	rm -rf $(VENV) outputs multirun .pytest_cache
