# Sourced by the other scripts: make .venv with everything the project needs, once.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PY="${PYTHON:-python3}"
VENV="$ROOT/.venv"
if [ ! -x "$VENV/bin/python" ]; then
    "$PY" -m venv "$VENV"
fi
STAMP="$VENV/.grasping_sym-installed"
WANT="$(cat "$ROOT/pyproject.toml" | sha256sum | cut -c1-16)"
if [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$WANT" ]; then
    "$VENV/bin/python" -m pip install --quiet --upgrade pip
    "$VENV/bin/python" -m pip install --quiet -e "$ROOT[test]"
    echo "$WANT" > "$STAMP"
fi
# the package's bytecode, written here: an editable install has none, and where
# PYTHONDONTWRITEBYTECODE is set (as on this project's machines) every new process (each
# script, a test's subprocess, a Dask worker) compiled the package's sources again, ~0.25 s
# of a cached build's 0.3 s; Python reads bytecode whatever that variable says, and skips a
# file whose source changed since (compileall rewrites only those); a file that does not
# compile is named here and left to the run that imports it
"$VENV/bin/python" -m compileall -q "$ROOT/grasping_sym" || true
export PATH="$VENV/bin:$PATH"
