# Sourced by the other scripts: create or reuse .venv with the package and its dev tools.
# Installing compiles the package's C++ core (redundancy._core): it needs a C++17 compiler. It is
# reinstalled whenever pyproject.toml, CMakeLists.txt or the C++ sources in src/ change.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
VENV=${VENV:-.venv}
stamp="$VENV/.installed"
if [ ! -x "$VENV/bin/python" ]; then
  python3 -m venv "$VENV"
fi
if [ ! -f "$stamp" ] || [ -n "$(find pyproject.toml CMakeLists.txt src -newer "$stamp")" ]; then
  "$VENV/bin/python" -m pip install --quiet --upgrade pip
  # A failed build ends in the one line that names the missing piece (the whole log beside it).
  if ! "$VENV/bin/python" -m pip install -e '.[dev,bench]' >"$VENV/install.log" 2>&1; then
    missing=$(grep -o -m 1 'redundancy: .*' "$VENV/install.log" || true)
    echo "${missing:-installing the package failed}; the whole log: $VENV/install.log" >&2
    exit 1
  fi
  touch "$stamp"
fi
export PATH="$PWD/$VENV/bin:$PATH"
