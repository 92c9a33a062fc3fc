# Quick start: `make run` (main job) and `make test` (test suite). Both create .venv and install
# what they need on first use; a second call skips the install.
PYTHON ?= python3.11
# pip's index for torch: empty = pip's default (on Linux the CUDA build, gigabytes);
# e.g. make test TORCH_INDEX=https://download.pytorch.org/whl/cpu for the CPU-only build
TORCH_INDEX ?=
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
BENCH_STAMP := $(VENV)/.installed-bench

.PHONY: install run test test-slow bench clean tb

$(PY):
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "error: $(PYTHON) not found (Python 3.11 is required)"; exit 1; }
	$(PYTHON) -m venv $(VENV)

# torch==2.13.0 first and explicitly (from TORCH_INDEX when set): the package's install below then
# finds it installed and keeps it, instead of choosing a build itself.
$(STAMP): $(PY) pyproject.toml
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet torch==2.13.0 $(if $(TORCH_INDEX),--index-url $(TORCH_INDEX))
	$(PY) -m pip install --quiet -e ".[test]"
	@touch $(STAMP)

install: $(STAMP)

# the benchmarks' reference libraries (MiniSom, pydmps), on top of the install above
$(BENCH_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e ".[bench]"
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
# tag (its default keeps 10 at random, so a sample trial of 20 rotation steps would lose some)
LOGDIR ?= outputs/
tb: $(STAMP)
	$(VENV)/bin/tensorboard --logdir $(LOGDIR) --samples_per_plugin images=1000

clean:
	rm -rf $(VENV) outputs multirun .pytest_cache
