#!/usr/bin/env bash
# Build the documentation site: bash scripts/build_docs.sh [OUTPUT_DIR]
# (default docs/_build/html; open OUTPUT_DIR/index.html). Sets up .venv first (seconds when
# nothing changed), checks that docs/architecture.md's graph tables match the graph's records
# (scripts/gen_graph_table.py --check), then runs Sphinx strictly: -W --keep-going (every warning
# is an error, all of them are reported), nitpicky references (docs/conf.py).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
OUT="${1:-docs/_build/html}"

bash scripts/bootstrap.sh
unset _ROS_WHEELS_BOOTSTRAP_COMPLETE
.venv/bin/python scripts/gen_graph_table.py --check
start=$SECONDS
echo "[docs] sphinx -W --keep-going -b html docs $OUT"
.venv/bin/python -m sphinx -W --keep-going -q -b html docs "$OUT"
echo "[docs] built $OUT/index.html in $((SECONDS - start)) s"
