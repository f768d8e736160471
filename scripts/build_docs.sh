#!/usr/bin/env bash
# Build the documentation site: bash scripts/build_docs.sh [OUTPUT_DIR]
# (default docs/_build/html; open OUTPUT_DIR/index.html). Sets up .venv first (seconds when
# nothing changed), checks that docs/architecture.md's graph tables match the graph's records
# (scripts/gen_graph_table.py --check), then runs Sphinx strictly: -W --keep-going (every warning
# is an error, all of them are reported), nitpicky references (docs/conf.py).
# --help / -h prints the usage and builds nothing; a relative OUTPUT_DIR is taken from the
# directory you run it in.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

usage() {
  cat <<'EOF'
usage: bash scripts/build_docs.sh [OUTPUT_DIR]

Builds the documentation site with Sphinx (-W --keep-going: every warning is an error) into
OUTPUT_DIR (default docs/_build/html in the repository; open OUTPUT_DIR/index.html), after
checking docs/architecture.md's graph tables (scripts/gen_graph_table.py --check).

  -h, --help    show this help and exit (nothing is built)
EOF
}

case "${1:-}" in
  -h|--help) usage; exit 0 ;;
  -*) echo "build_docs.sh: unknown option '$1' (see --help)" >&2; exit 2 ;;
esac
if [[ $# -gt 1 ]]; then
  echo "build_docs.sh: expected at most one OUTPUT_DIR, got $# arguments (see --help)" >&2
  exit 2
fi
if [[ -n "${1:-}" ]]; then
  OUT="$(realpath -m -- "$1")"
else
  OUT="$ROOT/docs/_build/html"
fi
cd "$ROOT"

bash scripts/bootstrap.sh
unset _ROS_WHEELS_BOOTSTRAP_COMPLETE
.venv/bin/python scripts/gen_graph_table.py --check
start=$SECONDS
echo "[docs] sphinx -W --keep-going -b html docs $OUT"
.venv/bin/python -m sphinx -W --keep-going -q -b html docs "$OUT"
echo "[docs] built $OUT/index.html in $((SECONDS - start)) s"
