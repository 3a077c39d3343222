#!/usr/bin/env bash
# The main job on a drive bundled in datasets/: installs, builds, then replays the paper's
# three-task drive (faulty left encoder, unequal motors, failing sonar) through the tool and
# prints what a user needs to see. Results go to out/ (override with OUT_DIR=...).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/build.sh
BIN=${BUILD_DIR:-build}/bin/wheelchair
OUT=${OUT_DIR:-out}
mkdir -p "$OUT"
DRIVE=datasets/three_task_faulty

step() { printf '\n=== %s\n' "$*"; }

step "1. import the plain-text recording $DRIVE/ into an MRPT rawlog"
"$BIN" import "$DRIVE" -o "$OUT/three_task_faulty.rawlog"

step "2. what is in it"
"$BIN" info "$OUT/three_task_faulty.rawlog"
