# crowdloc: every target creates or updates .venv first (re-installed when pyproject.toml,
# setup.py or constraints.txt change). torch is pinned to the CPU build by constraints.txt.
PYTHON ?= python3
# Where torch comes from: empty uses pip's own configuration (which, here, has the CPU build at
# hand). On a machine without a GPU whose pip would pick the CUDA build, give PyTorch's CPU
# wheel index: make TORCH_INDEX=<index URL> (see the README, "Install").
TORCH_INDEX ?=
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: venv demo test lint test-slow bench clean

$(STAMP): pyproject.toml setup.py constraints.txt
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -c constraints.txt $(if $(TORCH_INDEX),--index-url $(TORCH_INDEX)) torch==2.13.0
	$(PY) -c "import torch; print('installed torch', torch.__version__, '(CUDA ' + torch.version.cuda + ' build)' if torch.version.cuda else '(CPU build)')"
	$(PY) -m pip install --quiet -c constraints.txt -e '.[test,distributed,zoo]'
	$(PY) -m pip check
	touch $(STAMP)

venv: $(STAMP)

# results/demo is the demo's own folder: each make demo replaces the previous demo's files there
# (--overwrite deletes only what the demo writes); crowdloc demo by hand refuses a folder that is not empty
demo: venv
	$(VENV)/bin/crowdloc demo --overwrite

test: venv lint
	$(PY) -m pytest

lint: venv
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(VENV)/bin/mypy core envs localizers agents

test-slow: venv
	$(PY) -m pytest -m slow

bench: venv
	$(PY) -m benchmarks.run --output BENCHMARKS.md

clean:
	rm -rf $(VENV) results .pytest_cache .hypothesis
