#!/usr/bin/env bash
# The test suite (what CI runs).
source "$(dirname "${BASH_SOURCE[0]}")/env.sh"
cd "$ROOT"
# every core, one test file per worker (module fixtures build once)
python -m pytest -q -n auto --dist loadfile "$@"
