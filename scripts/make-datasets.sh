#!/usr/bin/env bash
# Generates the bundled simulated recordings into datasets/ with the built `wheelchair
# simulate` (docs/simulation.md). Each is a rawlog plus its truth (NAME.rawlog.truth.json).
#
#   three_task_clean   the paper's three-task drive, nominal chair, healthy sensors
#   three_task_faulty  the paper's faults: left encoder pulley ratio wrong (path appears to
#                      deviate to the left, odometry speed too low), right gearbox with more
#                      friction (right current higher when going straight, Fig. 6c), sonar
#                      failing in bursts (Fig. 8)
#   obstacles          Fig. 2 obstacle field, joystick fixed, supervisory control off
#   obstacles_assisted the same with the assist-as-needed supervisory control on
#
# Usage: scripts/make-datasets.sh [BUILD_DIR] [OUT_DIR]   (defaults: build, datasets)
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${1:-build}
OUT_DIR=${2:-datasets}
CLI="$BUILD_DIR/bin/wheelchair"
CONFIG=config/wheelchair.ini
SEED=20200612
if [[ ! -x "$CLI" ]]; then
  echo "make-datasets: $CLI not found; build first (scripts/build.sh)" >&2
  exit 1
fi
mkdir -p "$OUT_DIR"

sim() {  # NAME ARGS...
  local name=$1
  shift
  echo "== $name"
  "$CLI" simulate --config "$CONFIG" --seed "$SEED" --format rawlog -o "$OUT_DIR/$name.rawlog" "$@"
}

sim three_task_clean --scenario three_task
sim three_task_faulty --scenario three_task \
  --effect encoder_scale:side=left,scale=0.95 \
  --effect motor_asymmetry:side=right,friction_ratio=1.3 \
  --effect sonar_dropout:probability=0.15,burst_length=3
sim obstacles --scenario obstacles --supervisory off
sim obstacles_assisted --scenario obstacles --supervisory on

ls -l "$OUT_DIR"
