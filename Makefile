# One command sets up and runs each job; the virtual environment is created on first use.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.mjccd-installed

.PHONY: demo test bench clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e ".[test]"
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/mjccd replay models/boxing.xml data/boxing_traj.npz --out replay-out

test: $(STAMP)
	$(PY) -m pytest

bench: $(STAMP)
	$(PY) -m pip install -q -e ".[bench]"
	$(VENV)/bin/mjccd bench core

# numba's on-disk cache does not notice edits to other modules a kernel calls: clear it after editing kernels
clean:
	rm -rf $(VENV) .pytest_cache .hypothesis
	find mjccd -name '*.nbi' -delete -o -name '*.nbc' -delete
