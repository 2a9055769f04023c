#!/usr/bin/env bash
# Issue 41: the white reference frame over DDS, as a user runs it. `bin/demo printed_box
# --white-frame --record`: cellsim publishes each frame's white frame on
# rt/camera/white/image_raw before the frame, the servo decodes their ratio, and the printed box
# (which the pattern frame alone leaves 0.8 mm off after 400 steps) converges. The recording holds
# one white frame per image and replays bit for bit with --white-frame; without it the replay
# says what it left out. A servo that asks for white frames beside a simulator that sends none
# says so in one line; a replay that asks for them of a recording without them is refused.
#   white_frame_test.sh SOURCE_DIR BUILD_DIR
set -u
src="$1"; build="$2"; bin="$build/bin"
source "$src/tests/cli/lib.sh"
source "$src/tests/closed_loop/services.sh"
isolated_cell_domain
tmp=$(mktemp -d)
servo= sim=
trap 'kill -INT $servo $sim 2>/dev/null; sleep 1; kill -KILL $servo $sim 2>/dev/null; rm -rf "$tmp"' EXIT
pattern="$src/servo/pattern/data/marray_20x20_k3_w3_d3.txt"

CELL_OUT="$tmp" SETUP_NO_BUILD=1 BUILD_DIR="$build" timeout 280 "$src/bin/demo" printed_box --white-frame --record \
  >"$tmp/demo.log" 2>&1 || fail "bin/demo printed_box --white-frame --record: $(tail -5 "$tmp/demo.log")"
grep -q "session ended: converged" "$tmp/demo.log" || fail "the printed box did not converge: $(grep 'session ended' "$tmp/demo.log")"
converged_at_goal "$tmp/demo.log" || fail "the printed box ended away from the goal: $final"
echo "DDS, white frame: $(grep -o 'pose error .*' "$tmp/demo.log")"
# the service renders the white frames the in-process loop renders: the same run, to the printed digit
dds=$(grep -o 'final error [0-9.]* mm, [0-9.]* deg' "$tmp/demo.log")
inproc=$("$bin/cellsim" experiment "$src/sim/scenarios/printed_box.yaml" --z-hat 0.6 --white-frame --no-plot \
         -o "$tmp/inproc" 2>/dev/null | sed -n 's/^  final error: /final error /p')
[ -n "$dds" ] && [ "$dds" = "$inproc" ] || fail "over DDS '$dds', in-process '$inproc'"
one_line_error "serve: a lead without the white frame" "--white-frame-lead needs --white-frame" \
  "$bin/cellsim" serve "$src/sim/scenarios/printed_box.yaml" --white-frame-lead 0.5

# one white frame per image, on its own topic
counts=$(sed -n 's/^cellsim: recorded messages: //p' "$tmp/demo.log")
images=$(grep -o '/camera/image_raw [0-9]*' <<<"$counts" | awk '{print $2}')
whites=$(grep -o '/camera/white/image_raw [0-9]*' <<<"$counts" | awk '{print $2}')
[ -n "$images" ] && [ "$images" -gt 100 ] && [ "$whites" = "$images" ] ||
  fail "white frames ${whites:-none} for ${images:-no} images: $counts"

# bin/demo replayed it with --white-frame, bit for bit; without it, the replay says so and differs
grep -q "servo replay: .*every one identical bit for bit; 0 recorded twists not answered" "$tmp/demo.log" ||
  fail "the replay with the white frames did not reproduce the run: $(grep 'servo replay' "$tmp/demo.log")"
mcap="$tmp/demo/printed_box/run.mcap"
out=$("$bin/servo" replay "$mcap" --pattern "$pattern" --z-hat 0.6 --no-plot 2>&1)
grep -q "holds white reference frames; replayed without them" <<<"$out" && grep -q "compared: [0-9]* differ" <<<"$out" ||
  fail "a replay without --white-frame: $out"
echo "replay without the white frames: $(tail -1 <<<"$out")"
rm -f "$mcap"

# a replay asking for white frames of a recording made without them: refused before it writes
"$bin/cellsim" experiment "$src/sim/scenarios/printed_box.yaml" --z-hat 0.6 --max-iterations 3 --no-plot \
  -o "$tmp/short" --record "$tmp/short.mcap" >/dev/null 2>&1  # exit 5: the cap, as asked
[ -s "$tmp/short.mcap" ] || fail "cellsim experiment --record wrote no recording"
one_line_error "replay --white-frame of a recording without" "no white reference frames (/camera/white/image_raw)" \
  "$bin/servo" replay "$tmp/short.mcap" --pattern "$pattern" --z-hat 0.6 --white-frame -o "$tmp/refused"
[ ! -e "$tmp/refused" ] || fail "a refused replay wrote its folder"

# --record-no-images leaves the white frames out with the images
out=$("$bin/cellsim" experiment "$src/sim/scenarios/printed_box.yaml" --z-hat 0.6 --white-frame --max-iterations 3 \
      --no-plot -o "$tmp/noimg" --record "$tmp/noimg.mcap" --record-no-images 2>&1)
grep -q "recorded messages: .*/sim/status" <<<"$out" && ! grep -q "image_raw" <<<"$out" ||
  fail "--record-no-images with --white-frame: $(grep 'recorded messages' <<<"$out")"

# a servo asking for white frames, a simulator sending none: said in one line, images rejected
"$bin/servo" run --pattern "$pattern" --z-hat 0.6 --white-frame > "$tmp/servo.log" 2>&1 &
servo=$!
"$bin/cellsim" serve "$src/sim/scenarios/printed_box.yaml" --autorun --max-frames 3 > "$tmp/sim.log" 2>&1 &
sim=$!
for _ in $(seq 600); do grep -q "no white reference frame has come" "$tmp/servo.log" && break; sleep 0.1; done
grep -q "rt/camera/white/image_raw: no white reference frame has come (--white-frame)" "$tmp/servo.log" ||
  fail "the servo did not say the white frames are missing: $(cat "$tmp/servo.log")"
echo "white frames missing: $(grep 'no white' "$tmp/servo.log")"
exit 0
