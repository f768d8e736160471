#!/usr/bin/env bash
# The demo command: bash scripts/demo.sh [demo arguments]
# Sets up .venv (scripts/bootstrap.sh), picks a private ROS domain, runs scripts/demo.py.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

bash scripts/bootstrap.sh

# shellcheck source=lib/ros_env.sh
source scripts/lib/ros_env.sh
ird_ros_env
trap '[[ -n "${IRD_ROS_LOG_TMP:-}" ]] && rm -rf "$IRD_ROS_LOG_TMP"' EXIT
echo "[demo] ROS_DOMAIN_ID=$ROS_DOMAIN_ID"

set +e
.venv/bin/python scripts/demo.py "$@"
rc=$?
set -e
exit "$rc"
