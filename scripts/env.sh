# Sourced by the other scripts: create or reuse .venv with the package and its dev tools.
# Installing compiles the package's C++ core (redundancy._core): it needs a C++17 compiler. It is
# reinstalled whenever pyproject.toml, CMakeLists.txt, the C++ sources in src/ or this file change.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
VENV=${VENV:-.venv}
stamp="$VENV/.installed"
if [ ! -x "$VENV/bin/python" ]; then
  python3 -m venv "$VENV"
fi
# What building the package requires, one a line: pyproject.toml's [build-system] requirements,
# or, given `backend`, what its build backend asks for beyond them (CMake and Ninja where the
# machine has none).
build_requirements() {
  "$VENV/bin/python" -c '
import sys, tomllib
if sys.argv[1:] == ["backend"]:
    from scikit_build_core.build import get_requires_for_build_editable
    print(*get_requires_for_build_editable(), sep="\n")
else:
    with open("pyproject.toml", "rb") as file:
        print(*tomllib.load(file)["build-system"]["requires"], sep="\n")
' "$@"
}
# Install the requirements `build_requirements "$@"` names, if any; fail where it fails.
install_requirements() {
  local named requirements
  named=$(build_requirements "$@") || return
  mapfile -t requirements < <(grep . <<<"$named" || true)
  if [ ${#requirements[@]} -gt 0 ]; then
    "$VENV/bin/python" -m pip install "${requirements[@]}"
  fi
}
if [ ! -f "$stamp" ] ||
  [ -n "$(find pyproject.toml CMakeLists.txt src scripts/env.sh -newer "$stamp")" ]; then
  "$VENV/bin/python" -m pip install --quiet --upgrade pip
  # The core is built in .venv, its build's requirements installed there first, not in a fresh
  # environment of pip's for each build: the compiler's command line then stays the same from
  # build to build, so that a rebuild, and the suite's plain install, recompile only what
  # changed. A failed build ends in the one line that names the missing piece (the whole log
  # beside it).
  if ! { install_requirements && install_requirements backend &&
    "$VENV/bin/python" -m pip install --no-build-isolation -e '.[dev,bench]'; } \
    >"$VENV/install.log" 2>&1; then
    # the first message of ours, its lines joined (CMake wraps a long one)
    missing=$(awk '/redundancy: /{found = 1; sub(/^.*redundancy: /, "redundancy: ")}
      found && /^[[:space:]]*$/ {exit}
      found {sub(/^[[:space:]]+/, ""); printf "%s%s", sep, $0; sep = " "}' "$VENV/install.log")
    echo "${missing:-installing the package failed}; the whole log: $VENV/install.log" >&2
    exit 1
  fi
  touch "$stamp"
fi
export PATH="$PWD/$VENV/bin:$PATH"
