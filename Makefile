# One command sets up and runs each job; the virtual environment is created on first use.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.mjccd-installed
# the default set-up stays on MuJoCo 3; test-mujoco4 pins MuJoCo 4 with the first dm-control that runs on it
MUJOCO3 ?= mujoco>=3.17,<4
MUJOCO4 ?= mujoco==4.0.1
DM_CONTROL4 ?= dm-control>=1.0.52

.PHONY: demo test test-mujoco4 warmup docs bench bench-quick tunneling clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e ".[test]" "$(MUJOCO3)"
	touch $(STAMP)

# the first run compiles the kernels the replay needs (one to two minutes of CPU on 2 cores, with a note on
# stderr); numba caches them in mjccd/__pycache__, so later runs start at once
demo: $(STAMP)
	$(VENV)/bin/mjccd replay models/boxing.xml data/boxing_traj.npz --out replay-out --force

# no warmup first: the suite compiles the same kernels as it goes (the CPU is the same either way)
test: $(STAMP)
	$(PY) -m pytest

# compile every kernel a user may need (solver, scene, replay, monitor and guard, fit, patches), one line per job
warmup: $(STAMP)
	$(VENV)/bin/mjccd warmup

# the suite on MuJoCo 4 in an environment of its own, dm-control's tests included (1.0.52 runs on MuJoCo 4).
# PYTEST4="-m mujoco" runs only the MuJoCo-facing files (fit, monitor, guard, replay, scene, testing, examples;
# tests/conftest.py), under a minute once `make test` has compiled the kernels (numba's cache is shared)
PYTEST4    ?=
VENV4      := .venv-mujoco4-test
PY4        := $(VENV4)/bin/python
STAMP4     := $(VENV4)/.mjccd-installed
$(STAMP4): pyproject.toml
	test -x $(PY4) || $(PYTHON) -m venv $(VENV4)
	$(PY4) -m pip install -q --upgrade pip
	$(PY4) -m pip install -q -e ".[test]" "$(MUJOCO4)" "$(DM_CONTROL4)"
	touch $(STAMP4)

test-mujoco4: $(STAMP4)
	$(PY4) -c "import mujoco; v = mujoco.__version__; assert v.startswith('4.'), v; print('MuJoCo', v)"
	$(PY4) -m pytest -rs $(PYTEST4)

# the documentation site with its API reference from the docstrings, into site/; --strict: a warning fails it
docs: $(STAMP)
	$(VENV)/bin/mkdocs build --strict

bench: $(STAMP)
	$(PY) -m pip install -q -e ".[bench]"
	$(VENV)/bin/mjccd bench core

# every bench suite on small sizes and the packaged data: a smoke test of a few seconds each once compiled
bench-quick: $(STAMP)
	for suite in core scene monitor patches; do $(VENV)/bin/mjccd bench $$suite --quick || exit 1; done

# MuJoCo >= 4 in an environment of its own: the speculative-contacts peer of the tunneling benchmark
MJ4 := .venv-mujoco4/bin/python
$(MJ4):
	$(PYTHON) -m venv .venv-mujoco4
	$(MJ4) -m pip install -q "mujoco>=4" numpy

tunneling: $(STAMP) $(MJ4)
	$(PY) benchmarks/tunneling/run.py --mujoco4 $(MJ4)

# numba's on-disk cache does not notice edits to other modules a kernel calls: clear it after editing kernels
clean:
	rm -rf $(VENV) .venv-mujoco4 $(VENV4) .pytest_cache .hypothesis site
	find mjccd -name '*.nbi' -delete -o -name '*.nbc' -delete
