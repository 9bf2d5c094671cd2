#!/usr/bin/env bash
# The main job, in .venv (created on first use). Extra arguments go to the command, whose paths
# are read from the folder this script is run from, as the command's own are.
caller=$PWD
source "$(dirname "$0")/env.sh"
venv=$(realpath --relative-to="$caller" "$VENV")
cd "$caller"
redundancy study "$@"
echo "The redundancy command is in $venv: 'source $venv/bin/activate', then 'redundancy --help'."
