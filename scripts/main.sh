#!/usr/bin/env bash
# The main job on drives bundled in datasets/: installs, builds, then takes the paper's
# three-task drive (left encoder with a wrong pulley ratio, unequal motors, failing sonar)
# through the whole tool — import, inspect, filter, compare with ground truth, diagnose what
# the model leaves out, re-filter with the corrected model, and write the report.
# Results go to out/ (override with OUT_DIR=...).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/build.sh
BIN=${BUILD_DIR:-build}/bin/wheelchair
OUT=${OUT_DIR:-out}
CFG=config/wheelchair.ini
mkdir -p "$OUT"

step() { printf '\n=== %s\n' "$*"; }

step "1. import the plain-text recordings into MRPT rawlogs"
"$BIN" import datasets/three_task_faulty -o "$OUT/three_task_faulty.rawlog" --config "$CFG"
"$BIN" import datasets/three_task_faulty_b -o "$OUT/three_task_faulty_b.rawlog" --config "$CFG"

step "2. what is in the drive"
"$BIN" info "$OUT/three_task_faulty.rawlog"

step "3. replay it through the CVODE-integrated EKF (and the paper's Fig. 5 raw variants)"
"$BIN" filter "$OUT/three_task_faulty.rawlog" --config "$CFG" --variants \
  --trajectory "$OUT/ekf.tum" --estimates "$OUT/estimates.csv"

step "4. compare every variant with the Pozyx ground truth (nominal model)"
"$BIN" evaluate "$OUT/three_task_faulty.rawlog" --config "$CFG" -q \
  --markdown "$OUT/metrics_nominal.md" --csv "$OUT/metrics_nominal.csv"

step "5. diagnose: what physics does the model leave out? (validated on another drive)"
"$BIN" diagnose "$OUT/three_task_faulty.rawlog" --validate "$OUT/three_task_faulty_b.rawlog" \
  --config "$CFG" --json "$OUT/diagnosis.json" --write-config "$OUT/corrected.ini" \
  --report "$OUT/diagnosis"

step "6. the other drive, filtered with the nominal and with the corrected configuration"
echo "nominal model:"
"$BIN" evaluate "$OUT/three_task_faulty_b.rawlog" --config "$CFG" -q --no-baseline \
  --markdown "$OUT/metrics_validation_nominal.md"
echo "corrected model:"
"$BIN" evaluate "$OUT/three_task_faulty_b.rawlog" --config "$OUT/corrected.ini" -q --no-baseline \
  --markdown "$OUT/metrics_validation_corrected.md"

step "7. report: figures like the paper's Fig. 5-8 and the metrics"
"$BIN" report "$OUT/three_task_faulty.rawlog" --config "$CFG" -o "$OUT/report" \
  --truth datasets/three_task_faulty.truth.json

step "8. real data: a UTIAS MRCLAM robot (commands + landmark sightings), EKF vs Vicon"
"$BIN" import --format mrclam datasets/mrclam --robot 3 -o "$OUT/mrclam_robot3.rawlog"
"$BIN" evaluate "$OUT/mrclam_robot3.rawlog" --config config/mrclam.ini -q --alignment none \
  --markdown "$OUT/metrics_mrclam.md"

echo
echo "done: results in $OUT/ (report: $OUT/report/index.md, diagnosis: $OUT/diagnosis/index.md)"
