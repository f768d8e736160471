#!/usr/bin/env bash
# Set up (or bring up to date) the project's venv in .venv:
#   1. create .venv from python3 (3.11),
#   2. install the pinned requirements.txt (ROS 2 Jazzy wheels, numpy, ...) with uv,
#   3. install the pinned requirements-docs.txt (Sphinx, myst-parser, furo: the docs site) with uv,
#   4. build msgs_config/ird_msgs with cmake and install it into the venv,
#   5. install this project (ird_core, ird_ros) editable.
# Each step keeps a stamp (a hash of its inputs) in .venv/.ird-stamps and is skipped
# when its inputs did not change, so a second run takes about a second.
# Each step prints a line when it starts and when it ends; while pip or cmake runs, a line
# now and then says how far it got (scripts/lib/bootstrap_progress.sh; the full output goes to
# .venv/build/logs/); the last line gives the total time.
# Environment: IRD_PYTHON (interpreter to create the venv from, default python3),
#              IRD_BOOTSTRAP_FORCE=1 (redo every step), IRD_BOOTSTRAP_VERBOSE=1 (full logs).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
PY="$VENV/bin/python"
STAMPS="$VENV/.ird-stamps"
MSGS_SRC="$ROOT/msgs_config/ird_msgs"
MSGS_BUILD="$VENV/build/ird_msgs"
LOG_DIR="$VENV/build/logs"

START_NS="$(date +%s%N)"
say() { printf '[bootstrap] %s\n' "$*"; }
since() { # seconds since the given date +%s%N, one decimal
  local ns=$(( $(date +%s%N) - $1 ))
  printf '%d.%d s' $((ns / 1000000000)) $(( (ns / 100000000) % 10 ))
}
# shellcheck source=lib/bootstrap_progress.sh
source "$ROOT/scripts/lib/bootstrap_progress.sh"
die() { printf '[bootstrap] ERROR: %s\n' "$*" >&2; exit 1; }
hash_files() { # hash of the names and contents of the given files (sorted)
  (cd "$ROOT" && LC_ALL=C sort -z | xargs -0 sha256sum) | sha256sum | cut -d' ' -f1
}
stamp_ok() { [[ "${IRD_BOOTSTRAP_FORCE:-0}" != 1 && -f "$STAMPS/$1" && "$(cat "$STAMPS/$1")" == "$2" ]]; }
stamp_set() { mkdir -p "$STAMPS"; printf '%s\n' "$2" > "$STAMPS/$1"; }
# Run a step into its log, printing progress lines (ird_bootstrap_progress) and the step's time;
# on failure show the tail of its log and stop.
run_logged() {
  local name="$1"; shift
  local log="$LOG_DIR/$name.log" t0
  t0="$(date +%s%N)"
  mkdir -p "$LOG_DIR"
  if [[ "${IRD_BOOTSTRAP_VERBOSE:-0}" == 1 ]]; then
    "$@" 2>&1 | tee "$log"
  elif ! "$@" 2>&1 | tee "$log" | ird_bootstrap_progress "$name"; then
    tail -n 40 "$log" >&2
    die "step '$name' failed (full log: $log). Fix the cause, or start over with: rm -rf .venv"
  fi
  say "  $name: done in $(since "$t0")"
}

# A venv python that inherited another venv's bootstrap guard would skip setting
# LD_LIBRARY_PATH for this venv (see ros-wheels-bootstrapper): let it redo that.
unset _ROS_WHEELS_BOOTSTRAP_COMPLETE

# One bootstrap at a time per checkout (two test runs may start together).
exec 8> "$ROOT/.bootstrap.lock"
if ! flock -n 8; then
  say "waiting for another bootstrap of this checkout to finish (.bootstrap.lock)"
  flock 8 || die "cannot lock $ROOT/.bootstrap.lock"
fi

# --- 1. the venv ---------------------------------------------------------------
BASE_PY="${IRD_PYTHON:-python3}"
if [[ ! -x "$PY" ]] || ! "$PY" -c 'import sys; assert sys.version_info[:2] == (3, 11)' 2>/dev/null; then
  command -v "$BASE_PY" >/dev/null || die "'$BASE_PY' not found; install Python 3.11 or set IRD_PYTHON"
  "$BASE_PY" -c 'import sys; assert sys.version_info[:2] == (3, 11), sys.version' 2>/dev/null \
    || die "'$BASE_PY' is $("$BASE_PY" -V 2>&1), but the ROS 2 Jazzy wheels need Python 3.11 (set IRD_PYTHON)"
  [[ -e "$VENV" ]] && { say "removing unusable $VENV"; rm -rf "$VENV"; }
  say "creating .venv from $("$BASE_PY" -c 'import sys; print(sys.executable)')"
  "$BASE_PY" -m venv "$VENV" || die "python -m venv failed (Debian: apt-get install python3-venv)"
fi
PY_TAG="$("$PY" -c 'import sys; print(sys.version)')"

# --- uv: installs the pinned wheels (steps 2, 3) -------------------------------------
# uv, pinned, into the venv with pip: it installs the ~190 pinned wheels of requirements.txt in
# about 18 s (bytecode included) where pip took about 50 s on a fresh 2-core machine (downloads in parallel, no
# per-package Python start-up). Same pins, same wheels: only the installer differs.
UV_VERSION="0.13.9"
UV="$VENV/bin/uv"
if [[ "$("$UV" --version 2>/dev/null)" != "uv $UV_VERSION"* ]]; then
  say "uv $UV_VERSION: pip install (the installer of steps 2 and 3)"
  run_logged uv-install "$PY" -m pip install --disable-pip-version-check --no-input "uv==$UV_VERSION"
fi
# --compile-bytecode: as pip does. uv leaves it out by default, and with PYTHONDONTWRITEBYTECODE set
# (as on CI machines) every process would then compile numpy, scipy and rclpy from source at each
# start: the suite took 30% more CPU that way.
uv_install() { "$UV" pip install --python "$PY" --no-progress --compile-bytecode "$@"; }

# --- 2. pinned requirements -----------------------------------------------------
REQ_HASH="$( { printf '%s\0' requirements.txt | hash_files; echo "$PY_TAG"; declare -f uv_install; } | sha256sum | cut -d' ' -f1)"
if stamp_ok requirements "$REQ_HASH"; then
  say "requirements: up to date"
else
  say "requirements: uv pip install -r requirements.txt ($(grep -c '^[A-Za-z]' "$ROOT/requirements.txt") pinned packages: the ROS 2 Jazzy wheels, numpy, scipy, ...)"
  run_logged pip-install uv_install -r "$ROOT/requirements.txt"
  # ird_msgs is rebuilt (step 4) only if a pin it builds against changed (its stamp hashes them),
  # not for a new test plugin: a rebuild removes ird_msgs for a while under running tests.
  stamp_set requirements "$REQ_HASH"
fi

# --- 3. the docs site's requirements ----------------------------------------------------
# Constrained by requirements.txt, so they never move one of its pins.
DOCS_HASH="$( { printf '%s\0' requirements-docs.txt | hash_files; echo "$REQ_HASH"; } | sha256sum | cut -d' ' -f1)"
if stamp_ok docs "$DOCS_HASH"; then
  say "docs requirements: up to date"
else
  say "docs requirements: uv pip install -r requirements-docs.txt (Sphinx, myst-parser, furo: the docs site)"
  run_logged pip-install-docs uv_install -r "$ROOT/requirements-docs.txt" -c "$ROOT/requirements.txt"
  stamp_set docs "$DOCS_HASH"
fi

# --- 4. ird_msgs ------------------------------------------------------------------
# What ird_msgs is built against: the ROS wheels, numpy (rosidl's Python typesupport), the
# rosidl generators' own dependencies, and the interpreter.
MSGS_PINS_HASH="$( { grep -E '^(ros-|numpy==|catkin-pkg==|empy==|lark-parser==)' "$ROOT/requirements.txt" | LC_ALL=C sort; \
  echo "$PY_TAG"; } | sha256sum | cut -d' ' -f1)"
MSGS_HASH="$( { (cd "$ROOT" && find msgs_config/ird_msgs -type f -print0) | hash_files; echo "$MSGS_PINS_HASH"; } \
  | sha256sum | cut -d' ' -f1)"
if stamp_ok ird_msgs "$MSGS_HASH"; then
  say "ird_msgs: up to date"
else
  command -v cmake >/dev/null || die "cmake (>= 3.22) not found: apt-get install cmake"
  command -v c++ >/dev/null || die "a C/C++ compiler is needed to build ird_msgs: apt-get install g++"
  "$PY" -c 'import sysconfig, os, sys; sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))' \
    || die "Python.h not found for $PY (install the Python 3.11 development headers)"
  say "ird_msgs: building with cmake (about 20 s)"
  # Remove what an earlier build installed, so deleted interfaces do not linger.
  if [[ -f "$MSGS_BUILD/install_manifest.txt" ]]; then
    xargs -d '\n' rm -f < "$MSGS_BUILD/install_manifest.txt"
    rm -rf "$VENV/lib/python3.11/site-packages/ird_msgs" "$VENV"/lib/python3.11/site-packages/ird_msgs-*.egg-info
  fi
  rm -rf "$MSGS_BUILD"
  # Only the venv's ROS: a sourced system ROS must not leak into this build.
  export AMENT_PREFIX_PATH="$VENV" CMAKE_PREFIX_PATH="$VENV"
  run_logged ird_msgs-configure cmake -S "$MSGS_SRC" -B "$MSGS_BUILD" \
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_INSTALL_PREFIX="$VENV" -DPython3_EXECUTABLE="$PY" \
    -DBUILD_TESTING=OFF -DIRD_MSGS_PIP_VENV=ON
  run_logged ird_msgs-build cmake --build "$MSGS_BUILD" --parallel "$(nproc 2>/dev/null || echo 2)"
  run_logged ird_msgs-install cmake --install "$MSGS_BUILD"
  unset AMENT_PREFIX_PATH CMAKE_PREFIX_PATH
  "$PY" -c 'import ird_msgs.msg, ird_msgs.srv, ird_msgs.action' || die "ird_msgs was installed but does not import"
  stamp_set ird_msgs "$MSGS_HASH"
fi

# --- 5. the project, editable -------------------------------------------------------
PROJ_HASH="$( { printf '%s\0' pyproject.toml | hash_files; echo "$REQ_HASH"; } | sha256sum | cut -d' ' -f1)"
if stamp_ok project "$PROJ_HASH"; then
  say "project: up to date"
else
  say "project: pip install -e . (ird_core, ird_ros)"
  run_logged project-install "$PY" -m pip install --disable-pip-version-check --no-input \
    --no-deps --no-build-isolation -e "$ROOT"
  stamp_set project "$PROJ_HASH"
fi

# --- sanity: the pieces import together ---------------------------------------------
"$PY" -c 'import rclpy, ird_msgs.msg, ird_core, ird_ros' \
  || die "the venv is incomplete (see the error above); start over with: rm -rf .venv && bash scripts/bootstrap.sh"
say "ready: $PY (set-up took $(since "$START_NS"))"
