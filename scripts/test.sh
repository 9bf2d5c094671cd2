#!/usr/bin/env bash
# The test suite, in .venv (created on first use). Extra arguments go to pytest.
# It runs on every core (pytest-xdist, `-n auto`); tests that share an expensive module fixture
# or a port range are kept on one worker by `xdist_group` marks (`--dist loadgroup`).
# `-n 0` runs it in one process; `-p no:xdist` without the plugin.
source "$(dirname "$0")/env.sh"
# One BLAS thread a process: the matrices are small, and OpenBLAS's idle threads spinning beside
# the other worker and the processes the tests start cost a third of the suite's CPU time.
export OPENBLAS_NUM_THREADS=${OPENBLAS_NUM_THREADS:-1} OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
# A worker that crashes ends the run, the test it ran named: xdist's replacement worker, under
# this grouping, is handed no work, and the run would wait for it for ever.
parallel=(-n "${TEST_WORKERS:-auto}" --dist loadgroup --max-worker-restart=0)
previous=
for arg in "$@"; do
  if [ "$arg" = "-pno:xdist" ] || { [ "$previous" = "-p" ] && [ "$arg" = "no:xdist" ]; }; then
    parallel=()
  fi
  previous=$arg
done
python -m pytest -q "${parallel[@]}" "$@"
