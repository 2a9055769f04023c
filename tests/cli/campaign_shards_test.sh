#!/usr/bin/env bash
# A campaign run as two shards and merged equals the unsharded run, row for row (issue 11,
# item 5); bad shard arguments and wrong folders are refused in one line.
set -u
cellsim="$1"; src="$2"
source "$(dirname "$0")/lib.sh"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
args=("$src/sim/scenarios/fig5.yaml" --features ideal --runs 5 --models desired,current --max-iterations 80 --threads 2)
progress=$("$cellsim" campaign "${args[@]}" -o "$tmp/whole" 2>&1 >/dev/null) || fail "unsharded campaign"
# issue 13, item 6: progress with the time left, and the plot beside the table
grep -q "10/10 runs, [0-9]* s, about 0 s left" <<<"$progress" || fail "no progress with the time left: $progress"
[ -s "$tmp/whole/campaign.png" ] || fail "no campaign.png"
"$cellsim" campaign "${args[@]}" --shard 1/2 -o "$tmp/a" >/dev/null 2>&1 || fail "shard 1/2"
"$cellsim" campaign "${args[@]}" --shard 2/2 -o "$tmp/b" >/dev/null 2>&1 || fail "shard 2/2"
[ "$(($(wc -l < "$tmp/a/campaign.csv") + $(wc -l < "$tmp/b/campaign.csv")))" -eq 12 ] || fail "the shards do not hold 10 runs between them"
"$cellsim" campaign merge "$tmp/b" "$tmp/a" -o "$tmp/merged" >/dev/null || fail "merge"
[ -s "$tmp/merged/campaign.png" ] || fail "no campaign.png for the merged campaign"
cmp -s "$tmp/whole/campaign.csv" "$tmp/merged/campaign.csv" || fail "merged campaign.csv differs from the unsharded one"
cmp -s "$tmp/whole/summary.md" "$tmp/merged/summary.md" || fail "merged summary.md differs from the unsharded one"

one_line_error "shard beyond N" "expected I/N" "$cellsim" campaign "${args[@]}" --shard 3/2 -o "$tmp/x"
one_line_error "shard not a fraction" "expected I/N" "$cellsim" campaign "${args[@]}" --shard half -o "$tmp/x"
one_line_error "a shard missing" "1 of the 2 shards" "$cellsim" campaign merge "$tmp/a" -o "$tmp/x"
one_line_error "a shard twice" "given twice" "$cellsim" campaign merge "$tmp/a" "$tmp/a" -o "$tmp/x"
one_line_error "not a campaign folder" "campaign.json: cannot read" "$cellsim" campaign merge "$tmp" -o "$tmp/x"
"$cellsim" campaign "$src/sim/scenarios/fig5.yaml" --features ideal --runs 4 --models desired,current \
  --max-iterations 80 --shard 2/2 -o "$tmp/other" >/dev/null 2>&1 || fail "other campaign"
one_line_error "shards of two campaigns" "another campaign" "$cellsim" campaign merge "$tmp/a" "$tmp/other" -o "$tmp/x"
echo "campaign shards: merged equals unsharded; bad arguments refused"
