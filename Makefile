# One command sets up and runs each job; the virtual environment is created on first use.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.mjccd-installed

.PHONY: demo test bench bench-quick tunneling clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e ".[test]"
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/mjccd replay models/boxing.xml data/boxing_traj.npz --out replay-out --force

test: $(STAMP)
	$(PY) -m pytest

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
	rm -rf $(VENV) .venv-mujoco4 .pytest_cache .hypothesis
	find mjccd -name '*.nbi' -delete -o -name '*.nbc' -delete
