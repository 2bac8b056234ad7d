# shellcheck shell=bash
# Phases of a long script, each with an estimate: the plan before anything runs,
# one line when a phase starts and one when it ends, and a table of estimate
# against actual at the end. Sourced by scripts/example.sh; bash 5 (EPOCHREALTIME).
#   phase_add TITLE DETAIL SECONDS   add a phase to the plan (SECONDS: the estimate;
#                                    0: already done, nothing to run)
#   phase_plan HEADING               print the plan
#   phase_start N TEXT               "== N/M TEXT (about 2 min) ..."; N counts from 1
#   phase_end                        "   N/M TITLE: done in 1 min 52 s"
#   phase_skip N TEXT                "== N/M TEXT: already done" (a phase with nothing to run)
#   phase_summary                    the table of every phase and the total
# A phase that fails is named by the EXIT trap this file sets.

phase_titles=()
phase_details=()
phase_estimates=()  # seconds
phase_actuals=()    # microseconds; empty until the phase ends
phase_current=0     # the running phase, 1-based; 0 when none runs
phase_started_us=0

phase_now_us() { local t=${EPOCHREALTIME/[.,]/}; echo $((10#$t)); }

# "already done", "seconds", "about 40 s", "about 3.5 min", "about 12 min"
phase_estimate_text() {
  local s=$1
  if ((s == 0)); then
    echo "already done"
  elif ((s < 10)); then
    echo "seconds"
  elif ((s < 90)); then
    echo "about $(((s + 5) / 10 * 10)) s"
  elif ((s < 600)); then
    local halves=$(((s + 15) / 30))
    if ((halves % 2)); then echo "about $((halves / 2)).5 min"; else echo "about $((halves / 2)) min"; fi
  else
    echo "about $(((s + 30) / 60)) min"
  fi
}

# "0.4 s", "41 s", "8 min 41 s"
phase_duration_text() {
  local us=$1
  local s=$((us / 1000000))
  if ((s < 10)); then
    echo "$s.$((us / 100000 % 10)) s"
  elif ((s < 60)); then
    echo "$s s"
  else
    echo "$((s / 60)) min $((s % 60)) s"
  fi
}

phase_add() {
  phase_titles+=("$1")
  phase_details+=("$2")
  phase_estimates+=("$3")
  phase_actuals+=("")
}

phase_total_estimate() {
  local total=0 e
  for e in "${phase_estimates[@]}"; do total=$((total + e)); done
  echo "$total"
}

phase_plan() {
  local n=${#phase_titles[@]} i
  echo "$1: ${n} phases, $(phase_estimate_text "$(phase_total_estimate)") in all"
  for ((i = 0; i < n; i++)); do
    printf '  %d/%d %-22s %-44s %s\n' $((i + 1)) "$n" "${phase_titles[i]}" "${phase_details[i]}" \
      "$(phase_estimate_text "${phase_estimates[i]}")"
  done
}

phase_start() {
  phase_current=$1
  local i=$(($1 - 1))
  echo "== $1/${#phase_titles[@]} $2 ($(phase_estimate_text "${phase_estimates[i]}")) ..."
  phase_started_us=$(phase_now_us)
}

phase_end() {
  local i=$((phase_current - 1))
  phase_actuals[i]=$(($(phase_now_us) - phase_started_us))
  echo "   $phase_current/${#phase_titles[@]} ${phase_titles[i]}: done in $(phase_duration_text "${phase_actuals[i]}")"
  phase_current=0
}

phase_skip() {
  phase_actuals[$1 - 1]=0
  echo "== $1/${#phase_titles[@]} $2: already done"
}

phase_summary() {
  local n=${#phase_titles[@]} i total=0
  echo "== time by phase"
  printf '  %-26s %-16s %s\n' "phase" "estimate" "actual"
  for ((i = 0; i < n; i++)); do
    printf '  %-26s %-16s %s\n' "$((i + 1))/$n ${phase_titles[i]}" "$(phase_estimate_text "${phase_estimates[i]}")" \
      "$(phase_duration_text "${phase_actuals[i]:-0}")"
    total=$((total + ${phase_actuals[i]:-0}))
  done
  printf '  %-26s %-16s %s\n' "total" "$(phase_estimate_text "$(phase_total_estimate)")" "$(phase_duration_text "$total")"
}

phase_on_exit() {
  local status=$?
  if ((status != 0 && phase_current > 0)); then
    local i=$((phase_current - 1))
    echo "== $phase_current/${#phase_titles[@]} ${phase_titles[i]} FAILED after $(phase_duration_text $(($(phase_now_us) - phase_started_us))) (exit status $status)" >&2
  fi
}
trap phase_on_exit EXIT
