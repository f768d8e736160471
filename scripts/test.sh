#!/usr/bin/env bash
# The test command: bash scripts/test.sh [pytest arguments]
# Sets up .venv (scripts/bootstrap.sh; seconds when nothing changed), picks a private
# ROS domain (scripts/lib/ros_env.sh), then runs: .venv/bin/python -m pytest tests "$@"
# (when the arguments name test files or directories, "tests" is left out so they run alone).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

bash scripts/bootstrap.sh

# shellcheck source=lib/ros_env.sh
source scripts/lib/ros_env.sh
ird_ros_env
trap '[[ -n "${IRD_ROS_LOG_TMP:-}" ]] && rm -rf "$IRD_ROS_LOG_TMP"' EXIT
echo "[test] ROS_DOMAIN_ID=$ROS_DOMAIN_ID ROS_AUTOMATIC_DISCOVERY_RANGE=$ROS_AUTOMATIC_DISCOVERY_RANGE ROS_LOG_DIR=$ROS_LOG_DIR"

targets=(tests)
for arg in "$@"; do
  if [[ "$arg" != -* && -e "${arg%%::*}" ]]; then targets=(); break; fi
done

set +e
.venv/bin/python -m pytest "${targets[@]}" "$@"
rc=$?
set -e
exit "$rc"
