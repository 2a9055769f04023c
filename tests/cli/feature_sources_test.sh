#!/usr/bin/env bash
# bin/feature-sources as a user runs it (issue 41: where a closed loop is lost), on 2 short runs
# of three scenes: every source's campaign run as named (decoded-ids and resolved as such, the
# calibrated one with the calibration), the table, the CSV and the plot written; an existing
# output folder, an unknown scene and a list of models refused, nothing written over.
set -u
src="$1"; build="$2"
source "$(dirname "$0")/lib.sh"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
run() { env BUILD_DIR="$build" "$src/bin/feature-sources" "$@"; }
out=$(run -o "$tmp/s" --scenes plane,wedge,bowl --runs 2 --max-iterations 60 2>&1) || fail "bin/feature-sources: $out"
for f in sources.csv sources.md sources.png; do [ -s "$tmp/s/$f" ] || fail "no $f"; done
rows=$(($(wc -l <"$tmp/s/sources.csv") - 1))
[ "$rows" -eq 15 ] || fail "$rows rows in sources.csv, not 3 scenes x 5 sources"
grep -q "^| held out: bowl | [0-9] | [0-9] | [0-9] | [0-9] | [0-9] |" "$tmp/s/sources.md" || fail "no bowl row: $(cat "$tmp/s/sources.md")"
# each campaign ran what its column names
features() { /usr/bin/python3 -c "import json,sys; j=json.load(open(sys.argv[1])); print(j['features'], j['parameters']['epipolar'], j['runs'], j['max_iterations'])" "$1"; }
[ "$(features "$tmp/s/heldout/bowl/decoded-ids/campaign.json")" = "decoded-ids False 2 60" ] || fail "decoded-ids: $(features "$tmp/s/heldout/bowl/decoded-ids/campaign.json")"
[ "$(features "$tmp/s/tuning/wedge/resolved/campaign.json")" = "resolved False 2 60" ] || fail "resolved: $(features "$tmp/s/tuning/wedge/resolved/campaign.json")"
[ "$(features "$tmp/s/tuning/plane/decoded-calibrated/campaign.json")" = "decoded True 2 60" ] || fail "calibrated: $(features "$tmp/s/tuning/plane/decoded-calibrated/campaign.json")"
one_line_error "an existing output folder" "exists" run -o "$tmp/s" --scenes plane --runs 1
one_line_error "an unknown scene" "unknown" run -o "$tmp/u" --scenes plane,teapot
[ ! -e "$tmp/u" ] || fail "an unknown scene made its output folder"
one_line_error "two models" "one model" run -o "$tmp/m" --model desired,current
[ ! -e "$tmp/m" ] || fail "a list of models made its output folder"
one_line_error "runs that are no number" "--runs" run -o "$tmp/n" --runs nan
[ ! -e "$tmp/n" ] || fail "a bad --runs made its output folder"
echo "feature-sources: 15 campaigns as named, table and plot written; bad arguments refused"
