#!/usr/bin/env bash
# `cellsim render` as a user runs it: every shipped scenario renders, bad input is one line.
set -u
cellsim="$1"; src="$2"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
source "$(dirname "$0")/lib.sh"

for s in plane cylinder ham fig5; do
  out=$("$cellsim" render "$src/sim/scenarios/$s.yaml" --pose initial -o "$tmp/$s.png" --truth "$tmp/$s.json") || fail "$s: $out"
  [ -s "$tmp/$s.png" ] || fail "$s: no image"
  grep -q '"camera_pose"' "$tmp/$s.json" || fail "$s: truth has no camera_pose"
  grep -q '"depth_m"' "$tmp/$s.json" || fail "$s: truth has no visible spot"
done
out=$("$cellsim" render "$src/sim/scenarios/plane.yaml" --pose "1 -2 3 4 -5 6" -o "$tmp/p.png") || fail "numeric pose: $out"
# --pose moves along the scenario's offset frame, as --help says: on the plane its Z points back
# from the wall, so +5 cm puts the wall 5 cm farther (issue 43: the help spoke of the camera axes)
for z in 0 5; do
  "$cellsim" render "$src/sim/scenarios/plane.yaml" --pose "0 0 $z 0 0 0" -o "$tmp/z$z.png" --truth "$tmp/z$z.json" >/dev/null ||
    fail "pose z $z"
done
farther=$(/usr/bin/python3 -c "
import json
depth = lambda f: sorted(s['depth_m'] for s in json.load(open(f))['spots'] if s['visible'])[0]
print(round(100 * (depth('$tmp/z5.json') - depth('$tmp/z0.json')), 3))")
[ "$farther" = "5.0" ] || fail "--pose 0 0 5 moved the wall's nearest spot by $farther cm, not 5 farther"
"$cellsim" render --help | grep -q "Z points back" || fail "render --help does not say which way Z points"

# bad input: one line on stderr naming the problem, non-zero exit, no image
sed 's/focal_px: \[800, 800\]/focal_px: [0, 800]/' "$src/sim/scenarios/plane.yaml" | sed "s#\.\./\.\./#$src/#" > "$tmp/bad.yaml"
one_line_error "zero focal" "camera.focal_px\[0\]: must be in \[1, 100000\], got .0." "$cellsim" render "$tmp/bad.yaml" -o "$tmp/x.png"
one_line_error "bad pose" "expected desired, initial or six numbers" "$cellsim" render "$src/sim/scenarios/plane.yaml" --pose "1 2" -o "$tmp/x.png"
one_line_error "missing scenario" "scenario file not found" "$cellsim" render "$tmp/none.yaml" -o "$tmp/x.png"
printf 'v 0 0 0\nv 1 0 0\nf 1 2 7\n' > "$tmp/broken.obj"
sed "s#\.\./\.\./meshes/plane.obj#$tmp/broken.obj#" "$src/sim/scenarios/plane.yaml" | sed "s#\.\./\.\./#$src/#" > "$tmp/badmesh.yaml"
one_line_error "corrupt mesh" "broken.obj: line 3: face corner '7' refers to no vertex" "$cellsim" render "$tmp/badmesh.yaml" -o "$tmp/x.png"
[ ! -e "$tmp/x.png" ] || fail "an image was written despite bad input"
# decode-sweep: rates against the decodable spots and against all visible ones, per pose in the CSV
out=$("$cellsim" decode-sweep "$src/sim/scenarios/plane.yaml" --poses 4 -o "$tmp/sweep") || fail "decode-sweep: $out"
grep -q "against the decodable spots (visible, in a fully visible 3 x 3 window): [0-9]* of [0-9]* identified" <<<"$out" ||
  fail "no decodable rate: $out"
head -1 "$tmp/sweep/sweep.csv" | grep -q ",decodable,correct_decodable,resolved,readable,correct_readable,readable_segmented,readable_linked,readable_windowed,readable_one_object,correct_readable_one_object,readable_apart,correct_readable_apart,lost_other_id,lost_border,lost_no_growth,lost_dropped,lost_unlike_claim,lost_dissent,lost_no_direct,lost_few_sources,lost_unlike_sources,lost_taken,lost_residual,lost_neighbour_fits,lost_nearer_line,lost_nearer_blob,lost_alone,lost_unclaimed,off_line,off_line_right,off_line_mislocated,off_line_partial,off_line_wrong,to_law,to_law_right,to_law_mislocated,to_law_partial,to_law_wrong,off_taught,off_taught_right,off_taught_mislocated,off_taught_partial,off_taught_wrong$" ||
  fail "sweep.csv lacks the decodable, loss, off-line, to-the-law and taught-point columns"
grep -q "against the readable spots" <<<"$out" || fail "no readable rate: $out"
grep -q "against the readable spots apart in the image (.*): [0-9]* of [0-9]* identified" <<<"$out" ||
  fail "no rate against the readable spots apart in the image: $out"
[ -f "$tmp/sweep/wrong_ids.csv" ] || fail "no wrong_ids.csv"
# spills.csv: a row per id given to a spill, as many as the log counts (the ham's silhouette has some)
out=$("$cellsim" decode-sweep "$src/sim/scenarios/ham.yaml" --poses 20 -o "$tmp/ham_sweep") || fail "ham sweep: $out"
partial=$(grep -o 'partial [0-9]*' <<<"$out" | head -1 | cut -d' ' -f2)
[ "$(head -1 "$tmp/ham_sweep/spills.csv")" = "pose,row,col,u,v,centre_u,centre_v,centre_visible,step,off_line,to_law,off_taught" ] ||
  fail "spills.csv's header: $(head -1 "$tmp/ham_sweep/spills.csv")"
[ "${partial:-0}" -gt 0 ] && [ "$(($(wc -l <"$tmp/ham_sweep/spills.csv") - 1))" -eq "$partial" ] ||
  fail "spills.csv has $(($(wc -l <"$tmp/ham_sweep/spills.csv") - 1)) rows, the log $partial spills"
# with the projector's calibration: more spots identified, none wrong (the exit code says so)
"$cellsim" calibration "$src/sim/scenarios/cylinder.yaml" -o "$tmp/cyl.yaml" >/dev/null || fail "calibration"
count() { grep -o 'decoded [0-9]* of' <<<"$1" | cut -d' ' -f2; }
plain=$("$cellsim" decode-sweep "$src/sim/scenarios/cylinder.yaml" --poses 6) || fail "sweep without calibration"
cal=$("$cellsim" decode-sweep "$src/sim/scenarios/cylinder.yaml" --poses 6 --projector "$tmp/cyl.yaml") ||
  fail "sweep with calibration (wrong ids?): $cal"
[ "$(count "$cal")" -gt "$(count "$plain")" ] || fail "calibration decoded $(count "$cal"), without $(count "$plain")"
grep -q "wrong ids 0," <<<"$cal" || fail "wrong ids with the calibration: $cal"
# why the segmented readable spots have no id: without the calibration no step 6 ran; with it,
# its refusals are named
grep -q "why the segmented readable spots without an id have none:.* no_growth [0-9]" <<<"$plain" ||
  fail "no loss causes without the calibration: $plain"
grep -q "why the segmented readable spots without an id have none:" <<<"$cal" &&
  ! grep -q "no_growth" <<<"$cal" || fail "loss causes with the calibration: $cal"
# a decoder number set for one sweep reaches the decoder: step 6 with no slack grows nothing
tight=$("$cellsim" decode-sweep "$src/sim/scenarios/cylinder.yaml" --poses 6 --projector "$tmp/cyl.yaml" \
  --decoder-option growth.slack=0 --decoder-option edge_run.length=1000) || fail "sweep with --decoder-option: $tight"
[ "$(count "$tight")" -lt "$(count "$cal")" ] || fail "growth.slack=0 decoded $(count "$tight"), by default $(count "$cal")"
for bad in "growth.nothing=1" "growth.slack=-1" "growth.slack=nan" "growth.slack=1e10" "growth.slack=" "growth.slack" \
  "edge_run.length=2.5" "growth.slack=1x" "segmentation.local_window_px=0"; do
  one_line_error "--decoder-option $bad" "--decoder-option" "$cellsim" decode-sweep "$src/sim/scenarios/plane.yaml" \
    --poses 1 --decoder-option "$bad"
done
# the decoder is told the scenario camera's crosstalk (issue 41): a wedge seen through 0.2,
# decoded with the calibration, names more than with a crosstalk calibration of 0.06
sed -e 's/^camera:$/camera:\n  crosstalk: 0.2/' -e "s#\.\./\.\./\.\./#$src/#g" "$src/sim/scenarios/compact/wedge.yaml" > "$tmp/wedge.yaml"
"$cellsim" calibration "$tmp/wedge.yaml" -o "$tmp/wedge_cal.yaml" >/dev/null || fail "the wedge's calibration"
told=$("$cellsim" decode-sweep "$tmp/wedge.yaml" --poses 6 --projector "$tmp/wedge_cal.yaml") || fail "wedge sweep: $told"
off=$("$cellsim" decode-sweep "$tmp/wedge.yaml" --poses 6 --projector "$tmp/wedge_cal.yaml" --crosstalk 0.06) ||
  fail "wedge sweep told 0.06: $off"
[ "$(count "$told")" -gt "$(count "$off")" ] || fail "told the camera's crosstalk $(count "$told"), told 0.06 $(count "$off")"
one_line_error "sweep --crosstalk" "--crosstalk: '0.4' is not a finite number in \\[0, 0.3\\]" \
  "$cellsim" decode-sweep "$src/sim/scenarios/plane.yaml" --poses 1 --crosstalk 0.4
printf 'fx: 1500\n' > "$tmp/badcal.yaml"
one_line_error "sweep calibration" "fy: missing" "$cellsim" decode-sweep "$src/sim/scenarios/plane.yaml" --poses 1 --projector "$tmp/badcal.yaml"
echo "cellsim render: all checks passed"
