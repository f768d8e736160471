#!/usr/bin/env bash
# The test command: bash scripts/test.sh [--fast] [pytest arguments]
# Sets up .venv (scripts/bootstrap.sh; seconds when nothing changed), picks a private
# ROS domain (scripts/lib/ros_env.sh), then runs: .venv/bin/python -m pytest tests "$@"
# (when the arguments name test files or directories, "tests" is left out so they run alone).
#
# Parallel: on IRD_TEST_WORKERS pytest-xdist workers (default 2; 0 or 1: one process), with
# --dist loadgroup (the ROS tests stay on one worker, tests/conftest.py). One process instead
# when the arguments pick single tests (file::test), or choose for themselves (-n, -p no:xdist,
# --pdb, --trace).
# --fast: the fast tier, -m "not slow and not ros" (about 1-2 min; the ROS and slow tests are left out).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

bash scripts/bootstrap.sh

# shellcheck source=lib/ros_env.sh
source scripts/lib/ros_env.sh
ird_ros_env
trap '[[ -n "${IRD_ROS_LOG_TMP:-}" ]] && rm -rf "$IRD_ROS_LOG_TMP"' EXIT
echo "[test] ROS_DOMAIN_ID=$ROS_DOMAIN_ID ROS_AUTOMATIC_DISCOVERY_RANGE=$ROS_AUTOMATIC_DISCOVERY_RANGE ROS_LOG_DIR=$ROS_LOG_DIR"

args=()
for arg in "$@"; do
  if [[ "$arg" == --fast ]]; then args+=(-m "not slow and not ros"); else args+=("$arg"); fi
done

targets=(tests)
workers="${IRD_TEST_WORKERS:-2}"
[[ "$workers" =~ ^[0-9]+$ ]] || { echo "[test] IRD_TEST_WORKERS must be a number, got '$workers'" >&2; exit 2; }
prev=""
for arg in ${args[@]+"${args[@]}"}; do
  if [[ "$arg" != -* && -e "${arg%%::*}" ]]; then
    targets=()
    [[ "$arg" == *::* ]] && workers=0   # single tests: one process
  fi
  case "$arg" in
    -n|-n[0-9]*|--numprocesses|--numprocesses=*|--pdb|--trace|no:xdist|-pno:xdist) workers=0 ;;
  esac
  [[ "$prev" == -p && "$arg" == no:xdist ]] && workers=0
  prev="$arg"
done
parallel=()
if (( workers > 1 )); then
  parallel=(-n "$workers" --dist loadgroup)
  echo "[test] $workers workers (pytest-xdist; IRD_TEST_WORKERS=1 for one process)"
fi

set +e
.venv/bin/python -m pytest ${targets[@]+"${targets[@]}"} ${parallel[@]+"${parallel[@]}"} ${args[@]+"${args[@]}"}
rc=$?
set -e
exit "$rc"
