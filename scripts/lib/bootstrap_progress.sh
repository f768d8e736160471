# Progress lines of scripts/bootstrap.sh while a long step runs quietly into its log.
# Source this file; then:   some_command 2>&1 | tee LOG | ird_bootstrap_progress NAME
# reads the step's output and prints, with the seconds since the step started:
#   - pip: the first package collected and every 25th after it, "installing N packages" when pip
#     starts unpacking, "installed N packages" at the end;
#   - uv: its "Resolved / Prepared / Installed N packages" lines;
#   - cmake: "configured" and the build at 25, 50, 75 and 100 %.
# Everything else stays in the log only. Event driven: a line is printed when the step's own
# output says something happened, never on a timer.

_ird_packages() { (( $1 == 1 )) && echo "1 package" || echo "$1 packages"; }

ird_bootstrap_progress() {
  local name="$1" start=$SECONDS line collected=0 quarter=-1 pct what n
  while IFS= read -r line; do
    case "$line" in
      "Collecting "*|"Processing "*)
        collected=$((collected + 1))
        if (( collected == 1 || collected % 25 == 0 )); then
          what="${line#* }"; what="${what%% (*}"; what="${what##*/}"
          printf '[bootstrap]   %s: %s collected, latest %s [%ds]\n' "$name" "$(_ird_packages "$collected")" "$what" \
            $((SECONDS - start))
        fi ;;
      "Installing collected packages: "*)
        n=$(tr -cd ',' <<<"$line" | wc -c)
        printf '[bootstrap]   %s: installing %s [%ds]\n' "$name" "$(_ird_packages $((n + 1)))" $((SECONDS - start)) ;;
      "Successfully installed "*)
        n=$(wc -w <<<"${line#Successfully installed }")
        printf '[bootstrap]   %s: installed %s [%ds]\n' "$name" "$(_ird_packages $((n)))" $((SECONDS - start)) ;;
      "Resolved "*|"Prepared "*|"Installed "*|"Uninstalled "*)
        printf '[bootstrap]   %s: %s [%ds]\n' "$name" "${line,}" $((SECONDS - start)) ;;
      "-- Configuring done"*)
        printf '[bootstrap]   %s: configured [%ds]\n' "$name" $((SECONDS - start)) ;;
      "["*"%]"*)
        pct="${line#[}"; pct="${pct%%\%]*}"; pct="${pct// /}"
        if [[ "$pct" =~ ^[0-9]+$ ]] && (( 10#$pct / 25 > quarter )); then
          quarter=$(( 10#$pct / 25 ))
          printf '[bootstrap]   %s: %d%% [%ds]\n' "$name" $((10#$pct)) $((SECONDS - start))
        fi ;;
    esac
  done
}
