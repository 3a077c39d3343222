#!/usr/bin/env bash
# Generates the bundled simulated recordings into datasets/ with the built `wheelchair
# simulate` (docs/simulation.md). Each is a plain-text recording directory (the format users'
# loggers write; `wheelchair import` turns it into a rawlog) plus its hidden truth
# (NAME.truth.json: true trajectory and the effects applied).
#
#   three_task_clean   the paper's three-task drive, nominal chair, healthy sensors
#   three_task_faulty  the paper's faults: left encoder pulley ratio wrong (path appears to
#                      deviate to the left, odometry speed too low), right gearbox with more
#                      friction (right current higher when going straight, Fig. 6c), sonar
#                      failing in bursts (Fig. 8)
#   obstacles          Fig. 2 obstacle field, joystick fixed, supervisory control off
#   three_task_faulty_b  another drive of the same faulty chair (other seed): validation data
#   excite             a persistently exciting drive of the nominal chair (identification)
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

sim() {  # NAME SEED ARGS...
  local name=$1 seed=$2
  shift 2
  echo "== $name"
  rm -rf "${OUT_DIR:?}/$name"
  "$CLI" simulate --config "$CONFIG" --seed "$seed" --format csv -o "$OUT_DIR/$name" \
    --truth "$OUT_DIR/$name.truth.json" "$@"
}
FAULTS=(--effect encoder_scale:side=left,scale=0.95
        --effect motor_asymmetry:side=right,friction_ratio=1.3
        --effect sonar_dropout:probability=0.15,burst_length=3)

sim three_task_clean "$SEED" --scenario three_task
sim three_task_faulty "$SEED" --scenario three_task "${FAULTS[@]}"
sim three_task_faulty_b $((SEED + 1)) --scenario three_task "${FAULTS[@]}"
sim excite "$SEED" --scenario excite
sim obstacles "$SEED" --scenario obstacles --supervisory off
sim obstacles_assisted "$SEED" --scenario obstacles --supervisory on

ls -l "$OUT_DIR"
