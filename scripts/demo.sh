#!/usr/bin/env bash
# The demo command: bash scripts/demo.sh [demo arguments]
# Sets up .venv (scripts/bootstrap.sh), picks a private ROS domain (or keeps an exported
# ROS_DOMAIN_ID: scripts/lib/ros_env.sh), runs scripts/demo.py, which starts the graph in that one
# domain and prints it with the line a second shell needs to attach.
# --help / -h prints the usage below without setting anything up (a test holds its options,
# choices and defaults equal to the parser of ird_ros.apps.demo).
# Relative paths (--world FILE, --out DIR) are taken from the directory you run it in: the script
# does not change directory.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

usage() {
  cat <<'EOF'
usage: bash scripts/demo.sh [options]

The demo mission: Rob, a proxy reward, and lava the designer never saw. Sets up .venv on
first use, runs the whole ROS 2 graph in one ROS domain (an exported ROS_DOMAIN_ID is kept,
else a free one is leased; it is printed with the line a second shell needs to attach), sends
Rob the literal and the IRD navigation goals (/ird/navigate), prints the results and the
20-seed survey, and writes out/demo/run-<time>/ (mission.png, bag/, logs/).

options:
  -h, --help            show this help and exit (nothing is set up)
  --condition {side_effects,reward_hacking,latent_raw,latent_classifier,pot_of_gold}
                        the Lavaland condition (default latent_raw)
  --world FILE          a world file (worlds/*.yaml) instead of a generated Lavaland
  --seed SEED           world seed (maps, proxy; also the designer's; default 0)
  --method {maxent_z,sample_z}
                        the IRD posterior's approximation (default maxent_z)
  --beta BETA           designer rationality (default: the experiments')
  --num-samples NUM_SAMPLES
                        posterior samples (default: the experiments')
  --rate RATE           Rob's speed, cells per second (default 10)
  --out OUT             output folder (a run folder is made inside; default out/demo)
  --no-survey           skip the 20-seed survey
  --viz                 also start the viz node (live view over the Foxglove protocol; its
                        ws:// URL is printed)
  --viz-port PORT       with --viz: the live view's port (0 = any free port; without it 8766,
                        the params file's)

questions to the designer (after the IRD plan):
  --queries QUERIES     rounds of questions (0 = none: the plain mission)
  --designer {simulated,web}
                        who answers: the simulated designer node, or a person on the web page
  --num-options NUM_OPTIONS
                        paths per question (default 2)
  --strategy {evoi,max_regret,info_gain,random}
                        how the options are chosen (default evoi)
  --designer-beta DESIGNER_BETA
                        simulated designer's rationality on the options' true returns
  --port PORT           web designer's port on 127.0.0.1 (default 8765)
EOF
}

for arg in "$@"; do
  case "$arg" in
    -h|--help) usage; exit 0 ;;
    --) break ;;
  esac
done

bash "$ROOT/scripts/bootstrap.sh"

# shellcheck source=lib/ros_env.sh
source "$ROOT/scripts/lib/ros_env.sh"
ird_ros_env
trap '[[ -n "${IRD_ROS_LOG_TMP:-}" ]] && rm -rf "$IRD_ROS_LOG_TMP"' EXIT
# the demo prints the domain (this shell's ROS_DOMAIN_ID) once, with the line to attach to it

set +e
"$ROOT/.venv/bin/python" "$ROOT/scripts/demo.py" "$@"
rc=$?
set -e
exit "$rc"
