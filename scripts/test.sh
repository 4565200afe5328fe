#!/usr/bin/env bash
# The test suite (what CI runs).
source "$(dirname "${BASH_SOURCE[0]}")/env.sh"
cd "$ROOT"
# the 3D viewer's test opens its page in a real headless browser: Debian's chromium, installed
# here when missing (as root, or through sudo)
if ! command -v chromium >/dev/null 2>&1 && command -v apt-get >/dev/null 2>&1; then
    SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    echo "installing Debian's chromium for the viewer's test" >&2
    $SUDO apt-get update -q >/dev/null && \
        DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q chromium >/dev/null || \
        echo "could not install chromium: the viewer's test will say so" >&2
fi
# the floors: no import runs upward or closes a loop (pyproject.toml's contracts)
lint-imports
# every core, one test file per worker (module fixtures build once); one thread each for
# OpenBLAS and OpenMP: their idle threads spin on the core the other worker needs
export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}" OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}"
python -m pytest -q -n auto --dist loadfile "$@"
