#!/usr/bin/env bash
# Speed per core, one build against another in one run (issue 22, item 1): for each measure,
# the previous build's binaries and this one's in alternation, ROUNDS times (default 3), the
# median of each and their ratio. Everything but the DDS loop pinned to one core (taskset: a
# build whose OpenCV pool would take the second core cannot), so the ratios are per core.
#   tests/bench/compare_builds.sh OLD_BIN_DIR NEW_BIN_DIR SOURCE_DIR [ROUNDS]
# e.g. git worktree add /tmp/prev <previous commit> && BUILD_DIR=/tmp/prev/build /tmp/prev/bin/setup
#      tests/bench/compare_builds.sh /tmp/prev/build/bin build/bin . 3
# Measures: render per VGA frame (plane, cylinder, the arm in the projector's beam), the
# in-process iteration (cellsim experiment, cylinder with the arm), campaign runs per
# core-minute (cylinder, 4 runs), the lockstep DDS loop rate (plane, servo + cellsim).
set -euo pipefail
old="$1"; new="$2"; src="$3"; rounds="${4:-3}"
export OPENCV_FOR_THREADS_NUM=1
core="$(cut -d, -f1 <<<"$(taskset -pc $$ | sed 's/.*: //')" | cut -d- -f1)"
one_core() { taskset -c "$core" "$@"; }  # the first core this script may run on
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( $$ % 100 + 100 ))}" ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
unset ROS_STATIC_PEERS ROS_LOCALHOST_ONLY
median() { printf '%s\n' "$@" | sort -g | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2] + a[NR/2+1]) / 2}'; }
report() {  # report NAME UNIT HIGHER_IS_BETTER OLD_VALUES... -- NEW_VALUES...
  local name="$1" unit="$2" higher="$3"; shift 3
  local o=() n=() side=o
  for v in "$@"; do if [ "$v" = "--" ]; then side=n; elif [ $side = o ]; then o+=("$v"); else n+=("$v"); fi; done
  local mo mn; mo="$(median "${o[@]}")"; mn="$(median "${n[@]}")"
  awk -v name="$name" -v unit="$unit" -v o="$mo" -v n="$mn" -v h="$higher" 'BEGIN {
    r = h ? n / o : o / n
    printf "%-44s previous %10.3f %-14s this %10.3f %-14s %.2fx\n", name, o, unit, n, unit, r }'
}

# render per VGA frame: render_bench's own timings (one core)
render_ms() {  # render_ms BIN NAME: time per frame on one core (ms)
  one_core "$1/render_bench" --benchmark_filter="^$2\$" --benchmark_min_time=1 --benchmark_out="$work/bench.csv" \
    --benchmark_out_format=csv >/dev/null 2>&1
  awk -F, -v n="\"$2\"" '$1 == n {print $3}' "$work/bench.csv"
}
for b in render_vga/plane render_vga/cylinder render_arm_in_beam/with_arm; do
  o=(); n=()
  for ((i = 0; i < rounds; ++i)); do o+=("$(render_ms "$old" "$b")"); n+=("$(render_ms "$new" "$b")"); done
  report "render per VGA frame: ${b#*/}" "ms/frame" 0 "${o[@]}" -- "${n[@]}"
done

# the in-process iteration: cylinder experiments (the arm) of 80 and of 20 iterations; the
# difference of their wall times over 60 leaves the loading of the scene out
experiment_s() {  # experiment_s BIN ITERATIONS
  local t0 t1
  t0=$(date +%s.%N)
  one_core "$1/cellsim" experiment "$src/sim/scenarios/cylinder.yaml" --max-iterations "$2" --no-plot >/dev/null 2>&1 || true
  t1=$(date +%s.%N)
  awk -v a="$t0" -v b="$t1" 'BEGIN {print b - a}'
}
iteration_ms() {
  local long short
  long=$(experiment_s "$1" 80); short=$(experiment_s "$1" 20)
  awk -v l="$long" -v s="$short" 'BEGIN {print 1e3 * (l - s) / 60}'
}
experiment_s "$new" 1 >/dev/null  # the scene's files in the page cache for both
o=(); n=()
for ((i = 0; i < rounds; ++i)); do o+=("$(iteration_ms "$old")"); n+=("$(iteration_ms "$new")"); done
report "in-process iteration (cylinder, the arm)" "ms/iteration" 0 "${o[@]}" -- "${n[@]}"

# campaign runs per core-minute: 4 cylinder runs, one model, one thread
runs_per_core_minute() {
  local t0 t1
  t0=$(date +%s.%N)
  one_core "$1/cellsim" campaign "$src/sim/scenarios/cylinder.yaml" --runs 4 --models desired-constant-depth \
    --max-iterations 300 --threads 1 --no-plot -o "$work/campaign_$RANDOM" >/dev/null 2>&1 || true
  t1=$(date +%s.%N)
  awk -v a="$t0" -v b="$t1" 'BEGIN {print 4 * 60 / (b - a)}'
}
o=(); n=()
for ((i = 0; i < rounds; ++i)); do o+=("$(runs_per_core_minute "$old")"); n+=("$(runs_per_core_minute "$new")"); done
report "campaign runs per core-minute (cylinder)" "runs/core-min" 1 "${o[@]}" -- "${n[@]}"

# the lockstep DDS loop rate: the plane demo's two processes, cellsim's summary line
loop_rate() {
  local d; d="$(mktemp -d "$work/loop.XXXX")"
  "$1/servo" run --pattern "$src/servo/pattern/data/marray_20x20_k3_w3.txt" --z-hat 0.9 >"$d/servo.log" 2>&1 &
  local s=$!
  timeout 300 "$1/cellsim" serve "$src/sim/scenarios/plane.yaml" --autorun --exit-on-converged --max-frames 800 \
    >"$d/sim.log" 2>&1 || true
  kill -INT "$s" 2>/dev/null || true; wait "$s" 2>/dev/null || true
  sed -n 's/^cellsim: loop rate \([0-9.]*\) iterations.*/\1/p' "$d/sim.log"
}
o=(); n=()
for ((i = 0; i < rounds; ++i)); do o+=("$(loop_rate "$old")"); n+=("$(loop_rate "$new")"); done
report "lockstep DDS loop rate (plane)" "iterations/s" 1 "${o[@]}" -- "${n[@]}"
