#!/usr/bin/env bash
# Issue 13 as a user runs it: a study over an axis writes its table and plot, the seeded
# Fig. 5 search finds the shipped configuration again, errors and delays given as flags are
# applied and named, and bad values are refused in one line before anything runs.
set -u
cellsim="$1"; src="$2"
source "$(dirname "$0")/lib.sh"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fig5="$src/sim/scenarios/fig5.yaml"

"$cellsim" study "$fig5" --features ideal --axis z_hat=0.6,0.9 --runs 2 --models desired-constant-depth,desired \
  --max-iterations 150 --divergence-ratio 2 -o "$tmp/study" >/dev/null 2>&1 || fail "study"
[ "$(grep -c . "$tmp/study/study.csv")" -eq 5 ] || fail "study.csv does not hold 2 points x 2 models"
head -1 "$tmp/study/study.csv" | grep -q "^z_hat,depth_spread_m,model," || fail "study.csv header: $(head -1 "$tmp/study/study.csv")"
[ -s "$tmp/study/study.png" ] || fail "no study.png"
[ -s "$tmp/study/summary.md" ] || fail "no summary.md"
[ -s "$tmp/study/z_hat=0.9/campaign.csv" ] || fail "no campaign folder per point"
# two axes: a grid, drawn as maps
"$cellsim" study "$fig5" --features ideal --axis gain=0.5,2 --axis processing_frames=0,2 --runs 1 \
  --models desired --max-iterations 50 -o "$tmp/grid" >/dev/null 2>&1 || fail "two-axis study"
[ "$(grep -c . "$tmp/grid/study.csv")" -eq 5 ] || fail "the grid's study.csv does not hold 4 points"
[ -s "$tmp/grid/study.png" ] || fail "no study.png for the grid"

# the shipped fig5 is try 706 of this search: the same seed finds it again, kept
"$cellsim" fig5-search "$fig5" --tries 707 --seed 1 --max-translation-cm 8 --max-tilt-deg 10 --max-roll-deg 180 \
  -o "$tmp/search" >/dev/null 2>&1 || fail "fig5-search found nothing"
grep -q '^706,"2:10 2:14 6:10 6:14 4:12",-2.82' "$tmp/search/candidates.csv" || fail "try 706 is not the shipped fig5"
grep '^706,' "$tmp/search/candidates.csv" | grep -q ',1,' || fail "try 706 was not kept"

# errors and delays as flags: named in the output, and they change the run
out=$("$cellsim" experiment "$fig5" --features ideal --model current --max-iterations 30 --error focal_pct=3 \
  --error hand_eye_rotation_deg=1 --latency processing_frames=2 --no-plot 2>&1)
grep -q "errors and delays: focal_pct=3 hand_eye_rotation_deg=1 processing_frames=2" <<<"$out" || fail "conditions not named: $out"

one_line_error "unknown axis" "unknown" "$cellsim" study "$fig5" --axis lens=1 -o "$tmp/x"
one_line_error "axis value out of range" "outside" "$cellsim" study "$fig5" --axis z_hat=0.5,1e300 -o "$tmp/x"
one_line_error "axis value not a number" "not a number" "$cellsim" study "$fig5" --axis gain=0.5,fast -o "$tmp/x"
one_line_error "three axes" "at most two" "$cellsim" study "$fig5" --axis gain=1 --axis z_hat=1 --axis focal_pct=1 -o "$tmp/x"
one_line_error "error out of range" "is outside .0, 50" "$cellsim" experiment "$fig5" --error focal_pct=80
one_line_error "unknown error" "unknown" "$cellsim" experiment "$fig5" --error lens_pct=1
# the white reference frame is a decoded run's
one_line_error "white frame, ideal features" "--white-frame needs --features decoded" \
  "$cellsim" experiment "$fig5" --white-frame --features ideal
one_line_error "white frame, campaign of ideal features" "--white-frame needs --features decoded" \
  "$cellsim" campaign "$fig5" --white-frame --features ideal --runs 1 -o "$tmp/wc"
one_line_error "white frame axis, ideal features" "study axis white_frame: needs --features decoded" \
  "$cellsim" study "$fig5" --axis white_frame=0,1 --features ideal -o "$tmp/ws"
one_line_error "white frame, resolved features" "--white-frame needs --features decoded" \
  "$cellsim" experiment "$fig5" --white-frame --features resolved
# an injection the feature source would never see or would undo is refused, not run without it
one_line_error "losses into ideal features" "need decoded features" \
  "$cellsim" experiment "$fig5" --features ideal --losses 0.2
one_line_error "outliers into decoded ids" "outliers need decoded features" \
  "$cellsim" campaign "$fig5" --features decoded-ids --outliers 0.1 --runs 1 -o "$tmp/oc"
[ ! -e "$tmp/oc" ] || fail "the refused campaign left a folder"
# a run on the decoder's ids at their true positions has no wire form: refused before any file
one_line_error "recording decoded ids" "--record: a run with --features decoded-ids" \
  "$cellsim" experiment "$fig5" --features decoded-ids --record "$tmp/r.mcap"
[ ! -e "$tmp/r.mcap" ] || fail "the refused recording left a file"
one_line_error "unknown feature source" "expected decoded, ideal, resolved or decoded-ids" \
  "$cellsim" experiment "$fig5" --features truth
one_line_error "white frame lead without the white frame" "--white-frame-lead needs --white-frame" \
  "$cellsim" experiment "$fig5" --white-frame-lead 0.5
one_line_error "white frame lead out of range" "white-frame-lead" \
  "$cellsim" campaign "$fig5" --white-frame --white-frame-lead 2 --runs 1 -o "$tmp/wl"
one_line_error "white frame lead axis without the white frame" "study axis white_frame_lead: needs --white-frame" \
  "$cellsim" study "$fig5" --axis white_frame_lead=0,0.5 -o "$tmp/wl"
one_line_error "delay beyond the queue bound" "is outside .0, 50" "$cellsim" campaign "$fig5" --latency processing_frames=1000000 -o "$tmp/x"
one_line_error "an axis twice" "given twice" "$cellsim" study "$fig5" --axis gain=1 --axis gain=2 -o "$tmp/x"
one_line_error "a value twice" "value '1' given twice" "$cellsim" study "$fig5" --axis gain=1,2,1 -o "$tmp/x"
one_line_error "a shard count that wraps" "expected I/N" "$cellsim" campaign "$fig5" --shard 1/4294967297 -o "$tmp/x"
[ ! -e "$tmp/x" ] || fail "a refused study or campaign left a folder"

# issue 18, item 6: summaries say what stopped each run, and count rises and stalls as such
out=$("$cellsim" campaign "$fig5" --features ideal --runs 3 --models desired --max-iterations 3 --no-plot -o "$tmp/capped" 2>/dev/null)
grep -q "| desired | 0/3 (0 %) | 0 | 3 | 0 | 0 | 0 | - | - / - | - / - |" <<<"$out" || fail "runs stopped by the cap not counted as such: $out"
grep -qi "nan" <<<"$out" && fail "a campaign summary shows nan: $out"
out=$("$cellsim" study "$fig5" --features ideal --axis gain=16 --axis processing_frames=2 --models desired --runs 2 \
  --max-iterations 150 -o "$tmp/rising" 2>/dev/null)
grep -q "| 16 | 2 | [0-9.]* | desired | 0/2 | 0 | 2 | 0 | 0 | 2 |" <<<"$out" || fail "a study cell whose |e| rose does not say so: $out"
# issue 44: the visual features as an axis, by name
out=$("$cellsim" study "$src/sim/scenarios/plane.yaml" --axis visual_features=points,surface --models current --runs 1 \
  --no-plot -o "$tmp/features" 2>/dev/null) || fail "a study over the visual features: exit $?"
grep -q "^| points | 0.0 | current | 1/1 " <<<"$out" && grep -q "^| surface | 0.0 | current | 1/1 " <<<"$out" ||
  fail "a study over the visual features does not name them: $out"
[ -d "$tmp/features/visual_features=surface" ] || fail "no folder visual_features=surface"
one_line_error "an unknown feature set" "expected points, moments, surface or plane" \
  "$cellsim" study "$src/sim/scenarios/plane.yaml" --axis visual_features=lines -o "$tmp/y"
# issue 41: the interior of the matched spots as an axis, 0 or 1
out=$("$cellsim" study "$src/sim/scenarios/plane.yaml" --axis interior_points=0,1 --models current --runs 1 \
  --max-iterations 50 --no-plot -o "$tmp/interior" 2>/dev/null) || fail "a study over interior_points: exit $?"
grep -q "^| 0 | " <<<"$out" && grep -q "^| 1 | " <<<"$out" || fail "a study over interior_points has no row per value: $out"
one_line_error "interior_points=0.5" "study axis interior_points" \
  "$cellsim" study "$src/sim/scenarios/plane.yaml" --axis interior_points=0.5 -o "$tmp/z"
# the taught points as an axis, 0 or 1
out=$("$cellsim" study "$src/sim/scenarios/plane.yaml" --axis taught_points=0,1 --models current --runs 1 \
  --max-iterations 50 --no-plot -o "$tmp/taught" 2>/dev/null) || fail "a study over taught_points: exit $?"
grep -q "^| 0 | " <<<"$out" && grep -q "^| 1 | " <<<"$out" || fail "a study over taught_points has no row per value: $out"
one_line_error "taught_points=2" "study axis taught_points" \
  "$cellsim" study "$src/sim/scenarios/plane.yaml" --axis taught_points=2 -o "$tmp/t2"
echo "studies: tables and plots written, fig5 search reproducible, errors and delays applied, bad values refused"
