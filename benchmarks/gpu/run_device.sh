#!/usr/bin/env bash
# The GPU checks on a machine with an NVIDIA GPU: the device tests of tests/test_gpu.py, then the timing of
# mjccd.gpu.bench (with 64 worlds checked against the CPU scene).  Run from the repository root with a Python
# that has numpy, numba, numba-cuda and pytest (MuJoCo not needed, no network).  Writes run_device.log and
# bench.json into $OUT (default: a new temporary folder).  About 4.5 minutes on a fresh machine, nearly all of
# it compiling (the CPU kernels the tests compare against, then the CUDA kernels); 3 on one that compiled before.
set -uo pipefail
cd "$(dirname "$0")/../.."
OUT="${OUT:-$(mktemp -d)}"
mkdir -p "$OUT"
PY="${PYTHON:-python3}"
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"
unset NUMBA_ENABLE_CUDASIM
LOG="$OUT/run_device.log"
status=0
{
    echo "== environment"
    date -u
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader 2>&1 || true
    "$PY" -c "import sys, numpy, numba, numba_cuda; print('python', sys.version.split()[0], 'numpy', numpy.__version__, 'numba', numba.__version__, 'numba-cuda', numba_cuda.__version__)" 2>&1
    echo "== device tests (tests/test_gpu.py: device and import checks)"
    start=$(date +%s)
    timeout 360 "$PY" -m pytest -q -s -o addopts="" -p no:cacheprovider tests/test_gpu.py -k "device or import" -rs 2>&1 || status=1
    echo "tests: $(( $(date +%s) - start )) s"
    echo "== benchmark (mjccd.gpu.bench)"
    start=$(date +%s)
    timeout 120 "$PY" -m mjccd.gpu.bench --worlds 256,1024,4096 --steps 20 --check 64 --json "$OUT/bench.json" 2>&1 || status=1
    echo "bench: $(( $(date +%s) - start )) s"
    echo "== exit status $status; log and JSON in $OUT"
} 2>&1 | tee "$LOG"
exit $status
