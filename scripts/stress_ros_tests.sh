#!/usr/bin/env bash
# The ROS tests under load: bash scripts/stress_ros_tests.sh [RUNS] [pytest arguments]
# Starts one busy process per core (a pure-Python spin loop at normal priority), then runs
# `bash scripts/test.sh tests/ros` RUNS times in a row (default 10), each in a fresh private ROS
# domain, and stops at the first failing run. Prints one line per run (exit code, passed/failed
# counts, minutes) and a final verdict; each run's full output is kept in $STRESS_LOG_DIR
# (default: a new folder under /tmp). The busy processes are stopped on exit, however it ends.
# --help / -h prints the usage and starts nothing; RUNS must be a positive whole number.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

usage() {
  cat <<'EOF'
usage: bash scripts/stress_ros_tests.sh [RUNS] [pytest arguments]

Runs the ROS tests (bash scripts/test.sh tests/ros) RUNS times in a row (default 10) with one
busy process per core, each run in a fresh private ROS domain; stops at the first failing run.
Each run's output is kept in $STRESS_LOG_DIR (default: a new folder under /tmp).

  -h, --help    show this help and exit (nothing is started)
EOF
}

for arg in "$@"; do
  case "$arg" in
    -h|--help) usage; exit 0 ;;
    --) break ;;
  esac
done

runs=10
if [[ $# -gt 0 && "$1" != -* ]]; then
  runs="$1"
  shift
fi
if ! [[ "$runs" =~ ^[1-9][0-9]*$ ]]; then
  echo "stress_ros_tests.sh: RUNS must be a positive whole number, got '$runs' (see --help)" >&2
  exit 2
fi
cd "$ROOT"
log_dir="${STRESS_LOG_DIR:-$(mktemp -d /tmp/ird_stress.XXXXXX)}"
mkdir -p "$log_dir"

bash scripts/bootstrap.sh

cores="$(nproc)"
hogs=()
stop_hogs() { for pid in "${hogs[@]}"; do kill "$pid" 2>/dev/null || true; done; }
trap stop_hogs EXIT
for _ in $(seq "$cores"); do
  python3 -c 'while True: pass' &
  hogs+=("$!")
done
echo "[stress] $cores busy processes (pids ${hogs[*]}); $runs runs of the ROS tests; logs in $log_dir"

for i in $(seq "$runs"); do
  start=$(date +%s)
  set +e
  bash scripts/test.sh tests/ros -q -p no:cacheprovider "$@" >"$log_dir/run_$i.log" 2>&1
  rc=$?
  set -e
  minutes=$(awk -v s="$start" -v e="$(date +%s)" 'BEGIN { printf "%.1f", (e - s) / 60 }')
  summary="$(grep -E '^(=+ )?[0-9]+ (passed|failed)' "$log_dir/run_$i.log" | tail -1 || true)"
  echo "[stress] run $i/$runs: exit $rc, ${summary:-no summary line}, $minutes min"
  if [[ $rc -ne 0 ]]; then
    echo "[stress] FAILED at run $i (log: $log_dir/run_$i.log)"
    exit 1
  fi
done
echo "[stress] all $runs runs passed under $cores busy processes"
