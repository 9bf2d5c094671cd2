#!/usr/bin/env bash
# The test suite, in .venv (created on first use). Extra arguments go to pytest.
source "$(dirname "$0")/env.sh"
python -m pytest -q "$@"
