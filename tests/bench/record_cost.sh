#!/usr/bin/env bash
# What recording costs the lockstep loop (issue 21): the plane demo's loop (servo run and
# cellsim serve --autorun as two processes over DDS, with images) run in alternation without
# and with --record, PAIRS times each (default 5); prints each run's loop rate (cellsim's
# summary line), the medians and their ratio. Alternating pairs keep a machine's drift out of
# the ratio; the median keeps one noisy run out of it.
#   tests/bench/record_cost.sh BIN_DIR SOURCE_DIR [PAIRS]
set -euo pipefail
bin="$1"; src="$2"; pairs="${3:-5}"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
# loopback only, whatever the caller's ROS 2 environment says
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( $$ % 100 + 120 ))}" ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
unset ROS_STATIC_PEERS ROS_LOCALHOST_ONLY
pattern="$src/servo/pattern/data/marray_20x20_k3_w3.txt"
one_run() {  # prints the loop rate of one run; $@: extra cellsim flags
  local dir; dir="$(mktemp -d "$work/run.XXXX")"
  "$bin/servo" run --pattern "$pattern" --z-hat 0.9 --reference "$dir/reference.json" >"$dir/servo.log" 2>&1 &
  local servo=$!
  timeout 300 "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --autorun --exit-on-converged --max-frames 800 \
    "$@" >"$dir/sim.log" 2>&1 || true
  kill -INT "$servo" 2>/dev/null || true; wait "$servo" 2>/dev/null || true
  local rate; rate="$(sed -n 's/^cellsim: loop rate \([0-9.]*\) iterations.*/\1/p' "$dir/sim.log")"
  [ -n "$rate" ] || { echo "record_cost: a run gave no loop rate ($dir/sim.log):" >&2; tail -3 "$dir/sim.log" >&2; exit 1; }
  rm -rf "$dir"
  echo "$rate"
}
plain=(); recorded=()
for ((i = 1; i <= pairs; ++i)); do
  plain+=("$(one_run)")
  recorded+=("$(one_run --record "$work/run.mcap")")
  echo "pair $i: without --record ${plain[-1]} iterations/s, with --record ${recorded[-1]} iterations/s"
done
median() { printf '%s\n' "$@" | sort -n | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2] + a[NR/2+1]) / 2}'; }
mp="$(median "${plain[@]}")"; mr="$(median "${recorded[@]}")"
awk -v p="$mp" -v r="$mr" 'BEGIN {printf "record_cost: median loop rate %.0f iterations/s without --record, %.0f with (images recorded): %.2fx, recording costs %.1f %%\n", p, r, r / p, 100 * (1 - r / p)}'
