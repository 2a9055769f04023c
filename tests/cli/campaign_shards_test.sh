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
grep -q "/10 runs, [0-9]* s, about [0-9]* s left" <<<"$progress" && grep -q "10/10 runs, [0-9]* s$" <<<"$progress" ||
  fail "no progress with the time left: $progress"
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
one_line_error "a shard missing" "1 of the 2 shards given; missing: shard 2/2" "$cellsim" campaign merge "$tmp/a" -o "$tmp/x"
one_line_error "a shard twice" "given twice" "$cellsim" campaign merge "$tmp/a" "$tmp/a" -o "$tmp/x"
one_line_error "not a campaign folder" "campaign.json: cannot read" "$cellsim" campaign merge "$tmp" -o "$tmp/x"
"$cellsim" campaign "$src/sim/scenarios/fig5.yaml" --features ideal --runs 4 --models desired,current \
  --max-iterations 80 --shard 2/2 -o "$tmp/other" >/dev/null 2>&1 || fail "other campaign"
one_line_error "shards of two campaigns" "another campaign" "$cellsim" campaign merge "$tmp/a" "$tmp/other" -o "$tmp/x"

# issue 18, item 17: shards of another run, or tampered with, are refused naming the shard and the field
"$cellsim" campaign "${args[@]}" --gain 0.7 --shard 2/2 -o "$tmp/gain" >/dev/null 2>&1 || fail "gain shard"
one_line_error "another gain" "gain.*parameters.gain" "$cellsim" campaign merge "$tmp/a" "$tmp/gain" -o "$tmp/x"
"$cellsim" campaign "${args[@]}" --divergence-ratio 3 --shard 2/2 -o "$tmp/ratio" >/dev/null 2>&1 || fail "ratio shard"
one_line_error "another divergence ratio" "ratio/campaign.json.*parameters.divergence_ratio" "$cellsim" campaign merge "$tmp/a" "$tmp/ratio" -o "$tmp/x"
"$cellsim" campaign "${args[@]}" --visual-features moments --shard 2/2 -o "$tmp/moments" >/dev/null 2>&1 || fail "moments shard"
one_line_error "other visual features" "parameters.visual_features" "$cellsim" campaign merge "$tmp/a" "$tmp/moments" -o "$tmp/x"
# another scene under the same name:
sed "s|\.\./\.\./|$src/|g; s|albedo: 0.8|albedo: 0.7|" "$src/sim/scenarios/fig5.yaml" > "$tmp/fig5_other.yaml"
cmp -s "$tmp/fig5_other.yaml" "$src/sim/scenarios/fig5.yaml" && fail "the other scene is not another"
"$cellsim" campaign "$tmp/fig5_other.yaml" "${args[@]:1}" --shard 2/2 -o "$tmp/scene" >/dev/null 2>&1 || fail "scene shard"
one_line_error "another scene, same name" "scenario_sha" "$cellsim" campaign merge "$tmp/a" "$tmp/scene" -o "$tmp/x"
tamper() {  # tamper NAME SED-EXPRESSION EXPECTED
  rm -rf "$tmp/t"; cp -r "$tmp/b" "$tmp/t"
  sed -i "$2" "$tmp/t/campaign.csv"
  one_line_error "$1" "$3" "$cellsim" campaign merge "$tmp/a" "$tmp/t" -o "$tmp/x"
}
tamper "a duplicated row" '3s/.*/'"$(sed -n 2p "$tmp/b/campaign.csv" | sed 's/[\/&]/\\&/g')"'/' "given twice"
tamper "a run of another shard" '2s/^\([a-z-]*\),1,/\1,2,/' "belongs to shard 1/2"
tamper "an unknown model" '2s/^[a-z-]*,/teleport,/' "model 'teleport' is not one of the campaign's"
tamper "a NaN metric" '2s/^\(\([^,]*,\)\{10\}\)[^,]*,/\1nan,/' "final_translation_mm 'nan'"
tamper "a row removed" '2d' "rows, shard 2/2 has"
echo "campaign shards: merged equals unsharded; bad arguments, other runs and tampered tables refused"
