# tactile-torch: every target works on a fresh machine with Python 3.11 and make.
# Targets install on first use and never reinstall unless pyproject.toml changed.

PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
TORCH  := torch==2.13.0
OUT    ?= runs/latest

.PHONY: install run test test-slow test-all bench lint format clean

install: $(STAMP)

# torch goes first, pinned to the CPU build, so that resolving the rest finds it satisfied and
# never pulls a (multi-GB, CUDA) newer release; the last line fails loudly if a CUDA build slipped in.
# Development gets everything: the robot runtime (the package's own dependencies), the `train` extra,
# the optional `dask`, `ros` and `ros2` extras (their tests run in CI) and the `dev` tools.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet $(TORCH)
	$(PY) -m pip install --quiet -e '.[train,dask,ros,ros2,dev]'
	$(PY) -m tactile_torch.warmup
	$(PY) -c "import torch, sys; ok = torch.__version__.startswith('2.13.0') and torch.version.cuda is None; print('torch', torch.__version__, 'cuda', torch.version.cuda); sys.exit(0 if ok else 'expected the CPU build of torch 2.13.0')"
	touch $(STAMP)

run: $(STAMP)
	$(VENV)/bin/tactile-torch report --out $(OUT)

test: $(STAMP)
	$(PY) -m pytest

# The slow experiments alone (end-to-end trade-offs, export round trips, long chains): CI runs them after
# `make test`, the lint and the robot job; the ten longest are listed at the end.
test-slow: $(STAMP)
	$(PY) -m pytest -m slow --durations=10

test-all: $(STAMP)
	$(PY) -m pytest -m ''

bench: $(STAMP)
	$(VENV)/bin/tactile-torch bench --out bench/results

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

format: $(STAMP)
	$(VENV)/bin/ruff check --fix .
	$(VENV)/bin/ruff format .

clean:
	rm -rf $(VENV) runs build *.egg-info .pytest_cache .ruff_cache .hypothesis
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
