#!/usr/bin/env bash
# The test suite, in .venv (created on first use). Extra arguments go to pytest.
# It runs on every core (pytest-xdist, `-n auto`); tests that share an expensive module fixture
# or a port range are kept on one worker by `xdist_group` marks (`--dist loadgroup`).
# `-n 0` runs it in one process; `-p no:xdist` without the plugin.
source "$(dirname "$0")/env.sh"
parallel=(-n "${TEST_WORKERS:-auto}" --dist loadgroup)
previous=
for arg in "$@"; do
  if [ "$arg" = "-pno:xdist" ] || { [ "$previous" = "-p" ] && [ "$arg" = "no:xdist" ]; }; then
    parallel=()
  fi
  previous=$arg
done
python -m pytest -q "${parallel[@]}" "$@"
