#!/usr/bin/env bash
# The test suite (what CI runs).
source "$(dirname "${BASH_SOURCE[0]}")/env.sh"
cd "$ROOT"
python -m pytest -q "$@"
