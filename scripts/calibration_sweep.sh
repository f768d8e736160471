#!/usr/bin/env bash
# The designer-calibration sweep behind the default temperature (docs/experiments.md,
# "The calibrated designer"): paper-scale trials on tuning seeds SEED..SEED+N-1 (default
# 400-449, never the seeds 0-99 the committed results use), one run per temperature with the
# calibrated prior sigma = 1 / temperature (the samples scaled by their training spread, the
# planners' default), plus two ablations at temperature 0.2: the old prior sigma 1, and
# unscaled samples; then one table (scripts/calibration_table.py).
#   bash scripts/calibration_sweep.sh [--trials N] [--seed S] [--out DIR] [--conditions C ...]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
TRIALS=50 SEED=400 OUT="$PWD/out/calibration" CONDITIONS=(side_effects reward_hacking)
while [[ $# -gt 0 ]]; do
  case "$1" in
    --trials) TRIALS="$2"; shift 2 ;;
    --seed) SEED="$2"; shift 2 ;;
    --out) OUT="$2"; shift 2 ;;
    --conditions) shift; CONDITIONS=(); while [[ $# -gt 0 && "$1" != --* ]]; do CONDITIONS+=("$1"); shift; done ;;
    -h|--help) sed -n '2,7p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "calibration_sweep.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
PY="$ROOT/.venv/bin/python"
run() { # name temperature sigma sample-scale
  echo "[calibration] $1: temperature $2, prior sigma $3, sample scale $4"
  "$PY" "$ROOT/scripts/run_experiments.py" --trials "$TRIALS" --seed "$SEED" --conditions "${CONDITIONS[@]}" \
    --no-factorial --temperature "$2" --prior-sigma "$3" --sample-scale "$4" --out "$OUT/$1"
}
run tau1 1 1 training_spread
run tau0.5 0.5 2 training_spread
run tau0.2 0.2 5 training_spread
run tau0.1 0.1 10 training_spread
run tau0.2_sigma1 0.2 1 training_spread
run tau0.2_unscaled 0.2 5 none
"$PY" "$ROOT/scripts/calibration_table.py" "$OUT"/tau* > "$OUT/calibration.md"
cat "$OUT/calibration.md"
