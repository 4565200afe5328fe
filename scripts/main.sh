#!/usr/bin/env bash
# The main job: build the built-in paper scenes, simulate them, write results and figures under out/.
source "$(dirname "${BASH_SOURCE[0]}")/env.sh"
cd "$ROOT"
grasping-sym simulate paper2d --t-final 3 --out out/paper2d
grasping-sym simulate paper3d --t-final 5 --out out/paper3d
