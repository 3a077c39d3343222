#!/usr/bin/env bash
# Cross-check libwheelchair's trajectory metrics against evo (https://github.com/MichaelGrupp/evo).
#
# evo is not installable in the build environment (no PyPI); run this where `pip install evo`
# works. Without evo the script only prints the commands.
#
# Input: the three files written by wheelchair::evaluation::writeEvoFiles(PREFIX, est, gt, opt)
# (libwheelchair/evaluation/Metrics.h), all at the SAME timestamps (the matched, outlier-free
# ground-truth times), so evo's nearest-timestamp association is exact:
#   PREFIXgt.tum           ground truth (tag positions). Heading = ground-truth heading, or, for
#                          position-only ground truth (Pozyx), the aligned estimate's heading.
#   PREFIXest.tum          estimate moved to the tag (x + R(phi) l), interpolated, NOT aligned
#   PREFIXest_aligned.tum  the same after our alignment (opt.alignment)
#
# Usage: scripts/evo_check.sh PREFIX [none|origin|se2|first SECONDS]   (default: se2)
# Compare with our CSV (writeMetricsCsv): ate_rmse_m <-> APE "rmse", ate_max_m <-> "max",
# ate_median_m <-> "median", rpe_1m_m / rpe_5m_m <-> RPE "rmse". See docs/evaluation.md.
set -euo pipefail

if [[ $# -lt 1 ]]; then
  sed -n '2,20p' "$0"
  exit 2
fi
P="$1"
MODE="${2:-se2}"
GT="${P}gt.tum"
EST="${P}est.tum"
ESTA="${P}est_aligned.tum"
for f in "$GT" "$EST" "$ESTA"; do
  [[ -f "$f" ]] || { echo "missing $f (write it with writeEvoFiles)" >&2; exit 1; }
done

# Timestamps are identical in the three files: a tiny max diff makes the association 1:1.
SYNC=(--t_max_diff 1e-6)

case "$MODE" in
  none) ALIGN=() ;;
  origin) ALIGN=(--align_origin) ;;
  se2) ALIGN=(-a) ;;
  first)
    # evo counts poses, we count seconds: N = matched samples with t - t0 <= SECONDS.
    SECS="${3:?first needs SECONDS}"
    N=$(awk -v s="$SECS" '!/^#/ && NF==8 { if (!n) t0=$1; if ($1 - t0 <= s) c++; n++ } END { print c+0 }' "$GT")
    ALIGN=(-a --n_to_align "$N")
    ;;
  *) echo "unknown alignment '$MODE'" >&2; exit 2 ;;
esac

CMDS=(
  # ATE = APE translation part after the alignment; must equal ate_* of the same alignment.
  "evo_ape tum $GT $EST -r trans_part ${ALIGN[*]:-} ${SYNC[*]}"
  # Same numbers from the file we aligned ourselves (no evo alignment): works for every mode.
  "evo_ape tum $GT $ESTA -r trans_part ${SYNC[*]}"
  # RPE by travelled ground-truth distance, consecutive pairs (our default RpePairsFrom::Reference).
  # Full-pose RPE is invariant to a rigid alignment, so -a is not needed.
  "evo_rpe tum $GT $ESTA -r trans_part -d 1 -u m --pairs_from_reference ${SYNC[*]}"
  "evo_rpe tum $GT $ESTA -r trans_part -d 5 -u m --pairs_from_reference ${SYNC[*]}"
  # Without --pairs_from_reference evo picks the pairs along the estimate: compare with
  # MetricOptions::rpe_pairs_from = RpePairsFrom::Estimate.
  "evo_rpe tum $GT $ESTA -r trans_part -d 1 -u m ${SYNC[*]}"
)

if ! command -v evo_ape >/dev/null 2>&1; then
  echo "evo not found; commands to run (pip install evo):"
  printf '  %s\n' "${CMDS[@]}"
  exit 0
fi
for c in "${CMDS[@]}"; do
  echo "== $c"
  # shellcheck disable=SC2086
  $c
done
