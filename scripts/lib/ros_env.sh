# Source this file, then call ird_ros_env: it prepares a private, localhost-only ROS 2
# environment for this shell and its children.
#   - DDS over loopback only (ird_dds_env, the same rule as ird_ros.graph.domains.dds_env; a test
#     holds the two equal): FASTRTPS_DEFAULT_PROFILES_FILE=msgs_config/dds/fastdds_localhost.xml
#     and ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT (the profile does localhost discovery;
#     LOCALHOST would make rmw_fastrtps add a UDP transport on every interface).
#     IRD_DDS_NETWORK=1: multi-machine, no profile, range SUBNET. A profile of your own
#     (FASTRTPS_/FASTDDS_DEFAULT_PROFILES_FILE naming another file, or SKIP_DEFAULT_XML_FILE=1)
#     is kept, with range LOCALHOST. ROS_LOCALHOST_ONLY is unset;
#   - ROS_DOMAIN_ID: kept (and exported) if already set, so `export ROS_DOMAIN_ID=85; source
#     scripts/lib/ros_env.sh && ird_ros_env` attaches this shell to the graph printed as domain 85
#     (a value outside 0..101 is refused); else leased in 0..101 by taking an flock on
#     ${IRD_DOMAIN_LOCK_DIR:-/tmp/ird_ros_domains}/domain_<N>.lock on file descriptor 9
#     (held while this shell or any child lives; the same lock files as
#     ird_ros.graph.domains.lease_domain, so concurrent runs never share a domain);
#     the search starts at IRD_TEST_DOMAIN_BASE if set, else at a pid-derived ID;
#   - ROS_LOG_DIR: kept if set, else a fresh temporary directory (IRD_ROS_LOG_TMP names it,
#     for the caller to remove).
# Also drops an inherited ros-wheels-bootstrapper guard, so the venv's python sets
# LD_LIBRARY_PATH for itself.

_IRD_DDS_PROFILE="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd -P)/msgs_config/dds/fastdds_localhost.xml"

ird_dds_env() {
  unset ROS_LOCALHOST_ONLY
  if [[ "${FASTRTPS_DEFAULT_PROFILES_FILE:-}" == "$_IRD_DDS_PROFILE" ]]; then
    unset FASTRTPS_DEFAULT_PROFILES_FILE  # ours, inherited: decided afresh below
  fi
  local network="${IRD_DDS_NETWORK:-}"
  case "${network,,}" in
    1|true|yes|on) export ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET ;;
    ""|0|false|no|off)
      if [[ -n "${FASTRTPS_DEFAULT_PROFILES_FILE:-}${FASTDDS_DEFAULT_PROFILES_FILE:-}" \
            || "${SKIP_DEFAULT_XML_FILE:-}" == 1 ]]; then
        export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST  # the user's own Fast DDS configuration
      else
        export FASTRTPS_DEFAULT_PROFILES_FILE="$_IRD_DDS_PROFILE"
        export ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT
      fi ;;
    *)
      echo "ird_dds_env: IRD_DDS_NETWORK must be one of 1, true, yes, on (multi-machine) or 0, false, no, off, empty (loopback only), got '${IRD_DDS_NETWORK}'" >&2
      return 1 ;;
  esac
}

ird_ros_env() {
  ird_dds_env || return 1
  unset _ROS_WHEELS_BOOTSTRAP_COMPLETE
  if [[ -n "${ROS_DOMAIN_ID:-}" ]]; then
    if ! [[ "$ROS_DOMAIN_ID" =~ ^[0-9]+$ ]] || (( 10#$ROS_DOMAIN_ID > 101 )); then
      echo "ird_ros_env: ROS_DOMAIN_ID must be an integer in 0..101, got '${ROS_DOMAIN_ID}'" >&2
      return 1
    fi
    export ROS_DOMAIN_ID
  else
    local dir="${IRD_DOMAIN_LOCK_DIR:-/tmp/ird_ros_domains}" n=102 start i id
    mkdir -p "$dir" && chmod 1777 "$dir" 2>/dev/null || true
    start="${IRD_TEST_DOMAIN_BASE:-$(( ($$ * 7919) % n ))}"
    for (( i = 0; i < n; i++ )); do
      id=$(( (start + i) % n ))
      exec 9>>"$dir/domain_$id.lock" || continue
      if flock -n 9; then
        export ROS_DOMAIN_ID="$id"
        break
      fi
      exec 9>&-
    done
    if [[ -z "${ROS_DOMAIN_ID:-}" ]]; then
      echo "ird_ros_env: all ROS domain IDs 0..101 are in use (locks in $dir)" >&2
      return 1
    fi
  fi
  if [[ -z "${ROS_LOG_DIR:-}" ]]; then
    IRD_ROS_LOG_TMP="$(mktemp -d "${TMPDIR:-/tmp}/ird_ros_log.XXXXXX")"
    export ROS_LOG_DIR="$IRD_ROS_LOG_TMP"
  fi
}
