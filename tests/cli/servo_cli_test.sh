#!/usr/bin/env bash
# `servo decode` and the servo's configuration files as a user meets them: bad input is one line.
set -u
servo="$1"; cellsim="$2"; src="$3"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
source "$(dirname "$0")/lib.sh"
pattern="$src/servo/pattern/data/marray_20x20_k3_w3.txt"
curved="$src/servo/pattern/data/marray_20x20_k3_w3_d3.txt"  # the one the cylinder scenario casts

"$cellsim" render "$src/sim/scenarios/plane.yaml" -o "$tmp/plane.png" >/dev/null || fail "render"
out=$("$servo" decode "$tmp/plane.png" --pattern "$pattern" --json "$tmp/d.json" --overlay "$tmp/o.png") || fail "decode: $out"
grep -q '"decoded": 388' "$tmp/d.json" || fail "decoded count: $(grep decoded "$tmp/d.json")"
[ -s "$tmp/o.png" ] || fail "no overlay"

printf 'not an image' > "$tmp/bad.png"
one_line_error "unreadable image" "cannot read image" "$servo" decode "$tmp/bad.png" --pattern "$pattern"
: > "$tmp/empty.png"
one_line_error "empty image" "cannot read image" "$servo" decode "$tmp/empty.png" --pattern "$pattern"
# a grey image decodes to zero spots, not an error
"$cellsim" render "$src/sim/scenarios/plane.yaml" -o "$tmp/g.png" >/dev/null
/usr/bin/python3 -c "
import matplotlib.image as m, numpy as n
a = m.imread('$tmp/g.png'); g = a[..., :3].mean(axis=2); m.imsave('$tmp/grey.png', n.dstack([g, g, g]))" || fail "grey image"
out=$("$servo" decode "$tmp/grey.png" --pattern "$pattern" --json "$tmp/g.json") || fail "grey: $out"
grep -q '"decoded": 0' "$tmp/g.json" || fail "grey image decoded spots"
# spots seen and none named: a warning that says what to check (issue 43), the exit still 0
err=$("$servo" decode "$tmp/plane.png" --pattern "$curved" 2>&1 >/dev/null) || fail "wrong pattern: exit $?"
grep -q "none named: is --pattern the pattern the projector casts" <<<"$err" || fail "no hint for a wrong pattern: $err"
err=$("$servo" decode "$tmp/plane.png" --pattern "$pattern" 2>&1 >/dev/null)
[ -z "$err" ] || fail "a good decode warned: $err"

printf 'model: desired\ngian: 0.5\n' > "$tmp/bad.yaml"
one_line_error "config typo" "gian: unknown key" "$servo" run --pattern "$pattern" --config "$tmp/bad.yaml"
printf 'fx: 1500\n' > "$tmp/proj.yaml"
one_line_error "calibration" "fy: missing" "$servo" run --pattern "$pattern" --projector "$tmp/proj.yaml"
one_line_error "model name" "expected desired-constant-depth" "$servo" run --pattern "$pattern" --model Current
# issue 9, items 5, 15, 16: accepted-but-invalid settings, bombs and unreadable values
cfg() { printf '%b' "$1" > "$tmp/c.yaml"; one_line_error "config: $1" "$2" "$servo" run --pattern "$pattern" --config "$tmp/c.yaml"; }
cfg 'gain_adaptive: [-1, 0.5, 10]\n' "gain_adaptive\[0\]: must be in"
cfg 'gain_adaptive: [.nan, 0.5, 10]\n' "gain_adaptive\[0\]: must be a finite number"
cfg 'min_points: 1e300\n' "min_points: must be an integer in 3..4096, got '1e300'"
cfg 'min_votes: 10\n' "min_votes: must be an integer in 1..9"
cfg 'min_island: 1e300\n' "min_island: must be an integer"
cfg 'gain: [1, 2]\n' "gain: must be a number, got a list"
cfg 'tolerant: maybe\n' "tolerant: must be true or false"
cfg 'interior_points: 2\n' "interior_points: must be true or false"
cfg 'taught_points: yes please\n' "taught_points: must be true or false"
cfg 'segment_length: 99\n' "segment_length: must be an integer in 0..15"
cfg 'crosstalk: 0.5\n' "crosstalk: must be in \\[0, 0.3\\], got '0.5'"
cfg 'epipolar_px: .nan\n' "epipolar_px: must be a finite number"
cfg 'propagate_sources: 0\n' "propagate_sources: must be an integer in 1..9"
cfg 'gain: 0.5\ngain: 0.6\n' "gain: key given twice"
cfg 'gain: "\\x01\\xff"\n' "gain: must be a number"
cfg 'gain: [\n' "YAML syntax error"
cfg 'visual_features: lines\n' "visual_features: must be points, moments, surface or plane, got 'lines'"
cfg 'visual_features: moments\nrobust: tukey\n' "robust weights are per point"
one_line_error "--visual-features" "visual-features" "$servo" run --pattern "$pattern" --visual-features lines
one_line_error "surface without depths" "need the spots' depths" "$servo" run --pattern "$pattern" --visual-features surface
one_line_error "taught points without depths" "need the projector's calibration" "$servo" run --pattern "$pattern" --taught-points
cfg 'taught_points: true\n' "need the projector's calibration"
cal() { printf '%b' "$1" > "$tmp/p.yaml"; one_line_error "calibration: $1" "$2" "$servo" run --pattern "$pattern" --projector "$tmp/p.yaml"; }
good='fx: 1500\nfy: 1500\ncx: 511.5\ncy: 383.5\nspot_pitch_px: 15\nposition_m: [0, 0, 0]\n'
cal "${good}rows: 20\ncols: 20\norientation_xyzw: [0, 0, 0, 0]\n" "orientation_xyzw: must be a unit quaternion"
cal "${good}rows: 20\ncols: 20\norientation_xyzw: [0, 0, 0, 2]\n" "orientation_xyzw"
cal "${good}rows: 7\ncols: 20\norientation_xyzw: [0, 0, 0, 1]\n" "7 x 20 spots, but the pattern"
# a pattern of more colours than the decoder separates
"$(dirname "$servo")/pattern" generate --rows 12 --cols 12 --colours 5 --seed 1 -o "$tmp/k5.txt" >/dev/null || fail "k5 pattern"
one_line_error "5 colours" "the decoder tells apart 3" "$servo" decode "$tmp/plane.png" --pattern "$tmp/k5.txt"
# an image header claiming 20000 x 20000: refused before decoding
/usr/bin/python3 - "$tmp/bomb.png" <<'PY'
import struct, sys, zlib
def chunk(t, d): return struct.pack('>I', len(d)) + t + d + struct.pack('>I', zlib.crc32(t + d) & 0xffffffff)
raw = zlib.compress(b'\0' * 4000, 9)
open(sys.argv[1], 'wb').write(b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', 20000, 20000, 8, 2, 0, 0, 0)) + chunk(b'IDAT', raw) + chunk(b'IEND', b''))
PY
one_line_error "png bomb" "20000 x 20000 px, beyond the limit" "$servo" decode "$tmp/bomb.png" --pattern "$pattern"
# a corrupt PNG: our line only, no 'libpng error:' line before it
head -c 100 "$tmp/plane.png" > "$tmp/cut.png"
one_line_error "cut png" "cannot read image" "$servo" decode "$tmp/cut.png" --pattern "$pattern"
one_line_error "lost-ms" "--lost-ms must be in" "$servo" run --pattern "$pattern" --lost-ms 0
one_line_error "z-hat nan" "--z-hat: .nan. is not a finite number" "$servo" run --pattern "$pattern" --z-hat nan
one_line_error "gain huge" "--gain: .1e300. is not a finite number" "$servo" run --pattern "$pattern" --gain 1e300
one_line_error "watchdog" "--watchdog-ms must be in" "$cellsim" serve "$src/sim/scenarios/plane.yaml" --watchdog-ms -5
one_line_error "republish nan" "--republish-ms.*nan" "$cellsim" serve "$src/sim/scenarios/plane.yaml" --republish-ms nan
# many images: a folder and a file, one JSON each with its warm time, the per-frame summary
mkdir -p "$tmp/frames"
"$cellsim" render "$src/sim/scenarios/plane.yaml" --pose initial -o "$tmp/frames/a.png" >/dev/null || fail "render a"
"$cellsim" render "$src/sim/scenarios/ham.yaml" -o "$tmp/frames/b.png" >/dev/null || fail "render b"
out=$("$servo" decode "$tmp/frames" "$tmp/plane.png" --pattern "$pattern" --json-dir "$tmp/json") || fail "decode many: $out"
for f in a b plane; do
  grep -q '"time_ms"' "$tmp/json/$f.json" || fail "no time_ms in $f.json"
done
grep -q '"decoded": 388' "$tmp/json/plane.json" || fail "plane decoded differently in a batch"
grep -q "decode: 3 images, warm decoder per frame (first image excluded): median [0-9.]* ms, max [0-9.]* ms" <<<"$out" ||
  fail "no per-frame summary: $out"
# a bad image among good ones: its line, the others decoded, exit 1
err=$("$servo" decode "$tmp/frames" "$tmp/bad.png" --pattern "$pattern" --json-dir "$tmp/json2" 2>&1 >/dev/null); rc=$?
[ $rc -ne 0 ] || fail "a batch with a bad image exited 0"
grep -q "bad.png" <<<"$err" || fail "the bad image was not named: $err"
[ -s "$tmp/json2/a.json" ] && [ -s "$tmp/json2/b.json" ] || fail "the good images of the batch were not decoded"
one_line_error "--json with several" "for several, --json-dir" "$servo" decode "$tmp/frames" --pattern "$pattern" --json "$tmp/x.json"
mkdir -p "$tmp/empty_dir"
one_line_error "empty folder" "no image files" "$servo" decode "$tmp/empty_dir" --pattern "$pattern"

# issue 12: decoding with the projector's calibration (the camera pose from the image's
# <stem>.json, as `cellsim render --truth` writes it, or --camera-pose)
"$cellsim" calibration "$src/sim/scenarios/cylinder.yaml" -o "$tmp/cyl_proj.yaml" >/dev/null || fail "calibration"
mkdir -p "$tmp/cal"
"$cellsim" render "$src/sim/scenarios/cylinder.yaml" --pose desired -o "$tmp/cal/cyl.png" --truth "$tmp/cal/cyl.json" >/dev/null ||
  fail "render cylinder"
cam=(--camera 800 800 319.5 239.5 -0.08 0.02 0 0 0)
plain=$("$servo" decode "$tmp/cal/cyl.png" --pattern "$curved" | grep -o '[0-9]* decoded' | cut -d' ' -f1)
calibrated=$("$servo" decode "$tmp/cal/cyl.png" --pattern "$curved" --projector "$tmp/cyl_proj.yaml" "${cam[@]}" |
  grep -o '[0-9]* decoded' | cut -d' ' -f1)
[ -n "$plain" ] && [ -n "$calibrated" ] && [ "$calibrated" -gt "$plain" ] ||
  fail "the calibration did not identify more spots: $plain without, $calibrated with"
pose=$(/usr/bin/python3 -c "
import json; c = json.load(open('$tmp/cal/cyl.json'))['camera_pose']; print(*c['position_m'], *c['orientation_xyzw'])")
given=$("$servo" decode "$tmp/cal/cyl.png" --pattern "$curved" --projector "$tmp/cyl_proj.yaml" "${cam[@]}" --camera-pose $pose |
  grep -o '[0-9]* decoded' | cut -d' ' -f1)
[ "$given" = "$calibrated" ] || fail "--camera-pose decoded $given, the sidecar pose $calibrated"
# without the calibration, --camera fits the frame's own epipolar lines (issue 41): the ham seen
# from a pose of decode-sweep's draw (seed 7, pose 29) whose spots at its lower silhouette spill
# onto the table; those ids are marked off their lines, none without --camera, the same ids
"$cellsim" render "$src/sim/scenarios/ham.yaml" --pose "-5.28216 4.04854 1.97328 4.2785 0.453495 5.89216" \
  -o "$tmp/cal/spill.png" >/dev/null || fail "render the ham"
"$servo" decode "$tmp/cal/spill.png" --pattern "$curved" --json "$tmp/cal/plain.json" >/dev/null || fail "decode the ham"
"$servo" decode "$tmp/cal/spill.png" --pattern "$curved" "${cam[@]}" --json "$tmp/cal/fitted.json" >/dev/null ||
  fail "decode the ham with --camera"
/usr/bin/python3 - "$tmp/cal/plain.json" "$tmp/cal/fitted.json" <<'PY' || fail "the ham's spills with --camera"
import json, sys
plain, fitted = (json.load(open(f))["spots"] for f in sys.argv[1:])
ids = lambda spots: [(s["row"], s["col"], s["u"], s["v"]) for s in spots]
assert ids(plain) == ids(fitted), "--camera changed the ids"
assert not any(s["off_line"] for s in plain), "off its line without a line"
off = [(s["row"], s["col"]) for s in fitted if s["off_line"]]
print("off their fitted lines:", off)
assert 1 <= len(off) <= 8 and all(r == 16 for r, c in off), off  # the spills of row 16
PY
# --fitted-lines: decoded again on those lines, as with a calibration: more ids, each blob's
# id the same where both name it, no id twice
"$servo" decode "$tmp/cal/spill.png" --pattern "$curved" "${cam[@]}" --fitted-lines --json "$tmp/cal/again.json" \
  >/dev/null || fail "decode the ham with --fitted-lines"
/usr/bin/python3 - "$tmp/cal/plain.json" "$tmp/cal/again.json" <<'PY' || fail "the ham with --fitted-lines"
import json, sys
plain, again = (json.load(open(f))["spots"] for f in sys.argv[1:])
print(f"--fitted-lines: {len(plain)} ids -> {len(again)}")
assert len(again) >= len(plain) + 10, (len(plain), len(again))
at = {(round(s["u"], 3), round(s["v"], 3)): (s["row"], s["col"]) for s in plain}
assert all(at.get((round(s["u"], 3), round(s["v"], 3)), (s["row"], s["col"])) == (s["row"], s["col"]) for s in again)
assert len({(s["row"], s["col"]) for s in again}) == len(again), "an id twice"
PY
one_line_error "--fitted-lines without --camera" "--fitted-lines needs --camera" \
  "$servo" decode "$tmp/cal/spill.png" --pattern "$curved" --fitted-lines
# a half-size image with the full-size intrinsics: the mismatch said (issue 43)
/usr/bin/python3 -c "
import matplotlib.image as m; m.imsave('$tmp/cal/half.png', m.imread('$tmp/cal/cyl.png')[::2, ::2])"
cp "$tmp/cal/cyl.json" "$tmp/cal/half.json"
err=$("$servo" decode "$tmp/cal/half.png" --pattern "$curved" --projector "$tmp/cyl_proj.yaml" "${cam[@]}" 2>&1 >/dev/null)
grep -q "half.png is 320 x 240 but --camera puts the principal point at (319.5, 239.5)" <<<"$err" ||
  fail "no warning for intrinsics of another size: $err"
# the camera's crosstalk (issue 41): a wedge seen through a crosstalk of 0.2 keeps more of its
# spots, decoded with the calibration, when the decoder is told the crosstalk; without the
# calibration the levels stay (the wash they would let in); out of range is one line
sed -e 's/^camera:$/camera:\n  crosstalk: 0.2/' -e "s#\.\./\.\./\.\./#$src/#g" "$src/sim/scenarios/compact/wedge.yaml" > "$tmp/wedge.yaml"
"$cellsim" render "$tmp/wedge.yaml" -o "$tmp/cal/wedge.png" --truth "$tmp/cal/wedge.json" >/dev/null || fail "render the wedge"
"$cellsim" calibration "$tmp/wedge.yaml" -o "$tmp/wedge_proj.yaml" >/dev/null || fail "the wedge's calibration"
detected() { "$servo" decode "$tmp/cal/wedge.png" --pattern "$curved" "$@" | sed -n 's/.*: \([0-9]*\) spots detected.*/\1/p'; }
plain=$(detected --projector "$tmp/wedge_proj.yaml" "${cam[@]}")
told=$(detected --projector "$tmp/wedge_proj.yaml" "${cam[@]}" --crosstalk 0.2)
[ -n "$plain" ] && [ -n "$told" ] && [ "$told" -gt $((plain * 6 / 5)) ] || fail "crosstalk told: $told spots, not told: $plain"
[ "$(detected --crosstalk 0.2)" = "$(detected)" ] || fail "without the calibration the crosstalk changed the spots"
one_line_error "--crosstalk" "--crosstalk: '0.31' is not a finite number in \\[0, 0.3\\]" "$servo" decode "$tmp/cal/wedge.png" --pattern "$curved" --crosstalk 0.31
sed -i 's/crosstalk: 0.2/crosstalk: 0.4/' "$tmp/wedge.yaml"
one_line_error "scenario crosstalk" "camera.crosstalk: must be in \\[0, 0.3\\]" "$cellsim" render "$tmp/wedge.yaml" -o "$tmp/w2.png"
one_line_error "projector without camera" "--projector needs --camera" \
  "$servo" decode "$tmp/cal/cyl.png" --pattern "$curved" --projector "$tmp/cyl_proj.yaml"
one_line_error "no pose" "no camera pose" \
  "$servo" decode "$tmp/plane.png" --pattern "$pattern" --projector "$tmp/cyl_proj.yaml" "${cam[@]}"
one_line_error "pose quaternion" "unit quaternion" \
  "$servo" decode "$tmp/cal/cyl.png" --pattern "$curved" --projector "$tmp/cyl_proj.yaml" "${cam[@]}" --camera-pose 0 0 1 0 0 0 0.5
one_line_error "pose 1e300" "finite" \
  "$servo" decode "$tmp/cal/cyl.png" --pattern "$curved" --projector "$tmp/cyl_proj.yaml" "${cam[@]}" --camera-pose 1e300 0 1 0 0 0 1
one_line_error "camera focal" "fx and fy must be > 0" \
  "$servo" decode "$tmp/cal/cyl.png" --pattern "$curved" --projector "$tmp/cyl_proj.yaml" --camera 0 800 319.5 239.5
cp "$tmp/cal/cyl.png" "$tmp/cal/broken.png"
printf '{"camera_pose": {"position_m": [0, 0]}}' > "$tmp/cal/broken.json"
one_line_error "short sidecar" "broken.json" \
  "$servo" decode "$tmp/cal/broken.png" --pattern "$curved" --projector "$tmp/cyl_proj.yaml" "${cam[@]}"
printf '{"camera_pose": ' > "$tmp/cal/broken.json"
one_line_error "sidecar not JSON" "broken.json" \
  "$servo" decode "$tmp/cal/broken.png" --pattern "$curved" --projector "$tmp/cyl_proj.yaml" "${cam[@]}"
# issue 41: the white reference frame (`cellsim render --white`, `servo decode --white`): the
# printed box decoded as its ratio to it names more spots; a white frame that is not the
# image's is one line naming it
"$cellsim" render "$src/sim/scenarios/printed_box.yaml" --pose initial -o "$tmp/box.png" --white "$tmp/box_white.png" \
  >/dev/null || fail "render --white"
[ -s "$tmp/box_white.png" ] || fail "render --white wrote no white frame"
box_pattern=$(sed -n 's/^ *pattern: *//p' "$src/sim/scenarios/printed_box.yaml")
box_pattern="$src/sim/scenarios/$box_pattern"
alone=$("$servo" decode "$tmp/box.png" --pattern "$box_pattern" | sed -n 's/.* \([0-9]*\) decoded in.*/\1/p')
white=$("$servo" decode "$tmp/box.png" --white "$tmp/box_white.png" --pattern "$box_pattern" |
  sed -n 's/.* \([0-9]*\) decoded in.*/\1/p')
[ -n "$alone" ] && [ -n "$white" ] && [ "$white" -gt "$alone" ] ||
  fail "the printed box: $white ids with the white frame, $alone without"
/usr/bin/python3 -c "from PIL import Image; Image.new('RGB', (320, 240)).save('$tmp/small.png')"
one_line_error "white frame of another size" "white .*plane.png: 640 x 480 px, but .*small.png is 320 x 240" \
  "$servo" decode "$tmp/small.png" --white "$tmp/plane.png" --pattern "$pattern"
one_line_error "white frame unreadable" "cannot read image" \
  "$servo" decode "$tmp/box.png" --white "$tmp/bad.png" --pattern "$pattern"
one_line_error "--white with several" "and --white take one image" \
  "$servo" decode "$tmp/frames" --white "$tmp/plane.png" --pattern "$pattern"
echo "servo CLI: all checks passed"
