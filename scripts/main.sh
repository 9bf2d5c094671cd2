#!/usr/bin/env bash
# The main job, in .venv (created on first use). Extra arguments go to the command.
source "$(dirname "$0")/env.sh"
redundancy study "$@"
echo "The redundancy command is in .venv: 'source .venv/bin/activate', then 'redundancy --help'."
