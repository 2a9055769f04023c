#!/usr/bin/env bash
# Render per VGA frame, one build against another, the two at the same time: A on one core and
# B on the other, then swapped, ROUNDS times. A shared machine's load moves both alike, so the
# per-pair ratio holds where separate runs drift by 20 %. Prints, per frame, the fastest frame
# of each build (render_bench's fastest_ms: noise only ever adds) and the median of the
# per-pair ratios B / A (below 1: B is faster). Needs two cores.
#   tests/bench/paired_render.sh OLD_BIN_DIR NEW_BIN_DIR [ROUNDS] [FILTER]
# e.g. tests/bench/paired_render.sh /tmp/prev/build/bin build/bin 6
set -euo pipefail
old="$1/render_bench"; new="$2/render_bench"; rounds="${3:-6}"
filter="${4:-one_core_(plane|cylinder|arm_in_beam)/render}"
[ -x "$old" ] && [ -x "$new" ] || { echo "paired_render: no render_bench in $1 or $2" >&2; exit 2; }
[ "$(nproc)" -ge 2 ] || { echo "paired_render: needs two cores" >&2; exit 2; }
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
run() {  # run CORE BIN OUT
  taskset -c "$1" "$2" --benchmark_filter="$filter" --benchmark_min_time=0.5 --benchmark_out="$3" \
    --benchmark_out_format=csv >/dev/null 2>&1
}
for ((i = 0; i < rounds; ++i)); do
  for swap in 0 1; do
    run "$swap" "$old" "$work/a.csv" & run "$((1 - swap))" "$new" "$work/b.csv" & wait
    paste -d, <(grep '^"' "$work/a.csv") <(grep '^"' "$work/b.csv") >>"$work/pairs.csv"
  done
done
/usr/bin/python3 - "$work/pairs.csv" <<'PY'
import csv, statistics, sys, collections
pairs = collections.defaultdict(list)
for row in csv.reader(open(sys.argv[1])):
    n = len(row) // 2
    a, b = row[:n], row[n:]
    pairs[a[0]].append((float(a[-1]), float(b[-1]), float(a[2]), float(b[2])))
for name, v in pairs.items():
    print(f"{name:28s} fastest frame: previous {min(x[0] for x in v):.3f} ms, this {min(x[1] for x in v):.3f} ms; "
          f"this / previous, median of {len(v)} pairs: fastest {statistics.median(x[1] / x[0] for x in v):.3f}, "
          f"mean {statistics.median(x[3] / x[2] for x in v):.3f}")
PY
