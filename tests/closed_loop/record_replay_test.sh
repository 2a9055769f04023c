#!/usr/bin/env bash
# Record, inspect, replay (issue 21): a recorded bin/demo run (lockstep, plane, with images)
# is read back by an independent reader, Foxglove's @mcap/core (tests/interop/mcap): every
# channel there, every message count what cellsim's summary reported, every schema ROS 2
# .msg text that decodes every message. `servo replay` of it reproduces the recorded twists
# bit for bit (bin/demo --record checks it), and a replay with another configuration writes
# a differing trace. A broken recording is one line naming the file and offset.
#   record_replay_test.sh SOURCE_DIR BUILD_DIR
set -u
src="$1"; build="$2"; bin="$build/bin"
source "$src/tests/cli/lib.sh"
source "$src/tests/closed_loop/services.sh"
isolated_cell_domain
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
command -v node >/dev/null || fail "no node (bin/setup installs Node.js)"
[ -d "$build/mcap-check/node_modules/@mcap/core" ] || fail "no @mcap/core in $build/mcap-check (bin/setup installs it)"

CELL_OUT="$tmp" SETUP_NO_BUILD=1 BUILD_DIR="$build" timeout 280 "$src/bin/demo" plane --record >"$tmp/demo.log" 2>&1 ||
  fail "bin/demo plane --record: $(tail -5 "$tmp/demo.log")"
run="$tmp/demo/plane"
mcap="$run/run.mcap"
[ -s "$mcap" ] || fail "no recording at $mcap"
grep -q "^cellsim: recorded .*/run.mcap ([0-9.]* MB, [0-9]* messages on [0-9]* topics)" "$tmp/demo.log" ||
  fail "cellsim's summary does not give the recording's path and size: $(grep recorded "$tmp/demo.log")"

# the counts cellsim reported, as JSON for the independent reader
counts=$(sed -n 's/^cellsim: recorded messages: //p' "$tmp/demo.log")
[ -n "$counts" ] || fail "no 'recorded messages' line in cellsim's summary"
json="{$(sed -E 's|(/[^ ,]+) ([0-9]+)|"\1": \2|g' <<<"$counts")}"
for topic in /camera/image_raw /camera/camera_info /clock /joint_states /tf /robot_description /sim/status \
             /sim/camera_pose /sim/control /servo/cmd_twist /servo/status /servo/spots; do
  grep -q "\"$topic\": [1-9]" <<<"$json" || fail "the recording has no messages on $topic: $json"
done
report=$(node "$src/tests/interop/mcap/check_mcap.mjs" "$build/mcap-check" "$mcap" "$json" 2>&1) ||
  fail "@mcap/core: $report"
echo "mcap: @mcap/core read $(grep -o '"messages":[0-9]*' <<<"$report"), $(grep -o '"chunks":[0-9]*' <<<"$report") of $mcap, every count as cellsim reported"

# bin/demo --record replayed it with the recorded configuration
grep -q "servo replay: .*every one identical bit for bit; 0 recorded twists not answered" "$tmp/demo.log" ||
  fail "the replay did not reproduce the recorded twists: $(grep 'servo replay' "$tmp/demo.log")"
[ -s "$run/replay/replay.csv" ] && [ -s "$run/replay/replay.png" ] || fail "no replay.csv and replay.png"
grep 'servo replay: .*compared' "$tmp/demo.log"

# the two services race at start-up: the servo's "ready" twist may be heard before the first
# frame, after it, or not at all. The recording with it heard after the first frame (moved
# there, or added) replays bit for bit too.
out=$(node "$src/tests/interop/mcap/ready_after_first_frame.mjs" "$build/mcap-check" "$mcap" "$tmp/ready_late.mcap") ||
  fail "ready_after_first_frame.mjs: $out"
pattern="$src/servo/pattern/data/marray_20x20_k3_w3.txt"
out=$("$bin/servo" replay "$tmp/ready_late.mcap" --pattern "$pattern" --z-hat 0.9 --no-plot --expect-identical) ||
  fail "a recording with the ready twist heard after the first frame does not replay bit for bit: $out"
grep -q "0 recorded twists not answered, 0 replayed twists not recorded" <<<"$out" || fail "ready twist heard late: $out"
echo "replay: the ready twist heard after the first frame: $out"

# a bag `ros2 bag record` makes of the live cell holds the messages as they arrive: each
# frame's image can come ahead of its sim status and pose. That order replays bit for bit too.
out=$(node "$src/tests/interop/mcap/arrival_order.mjs" "$build/mcap-check" "$mcap" "$tmp/arrival.mcap") ||
  fail "arrival_order.mjs: $out"
moved=$out
out=$("$bin/servo" replay "$tmp/arrival.mcap" --pattern "$pattern" --z-hat 0.9 --no-plot --expect-identical) ||
  fail "a recording in arrival order does not replay bit for bit ($moved): $out"
# the same counts as the file's own order (a twist sent after the recording closed is in
# neither: the last frame's answer, when cellsim ended on CONVERGED first)
in_order=$("$bin/servo" replay "$mcap" --pattern "$pattern" --z-hat 0.9 --no-plot)
[ "${out#*.mcap: }" = "${in_order#*.mcap: }" ] && grep -q "0 recorded twists not answered" <<<"$out" ||
  fail "arrival order: $out; in the file's order: $in_order"
echo "replay: in arrival order ($moved): $out"

# a recording that stopped mid-run (a full disk, the size limit) between a frame's twist and its
# image, which the recorder queues a moment later: with the recorder's "recording_stopped"
# record the twist is counted apart and the replay is identical; without it, it is unanswered
for meta in "" --no-metadata; do
  out=$(node "$src/tests/interop/mcap/stopped_before_its_image.mjs" "$build/mcap-check" "$mcap" "$tmp/stopped.mcap" 20 $meta) ||
    fail "stopped_before_its_image.mjs: $out"
  if out=$("$bin/servo" replay "$tmp/stopped.mcap" --pattern "$pattern" --z-hat 0.9 --no-plot --expect-identical); then
    [ -z "$meta" ] && grep -q "the recording stopped before the run ended (stopped at the size limit (a test))" <<<"$out" &&
      grep -q "0 recorded twists not answered, .*; 1 recorded twists answer images past the cut" <<<"$out" ||
      fail "stopped before its image${meta:+ ($meta)}: $out"
  else
    [ -n "$meta" ] && grep -q "1 recorded twists not answered" <<<"$out" || fail "stopped before its image${meta:+ ($meta)}: $out"
  fi
  rm -f "$tmp/stopped.mcap"
done
echo "replay: a recording stopped between a twist and its image: its twist counted apart when the file says it stopped"

# the live servo's LOST notice (no image for 500 ms on a loaded machine: a LOST status and a
# zero twist at the last frame's stamp) answers no image: counted apart, never compared
out=$(node "$src/tests/interop/mcap/lost_notice.mjs" "$build/mcap-check" "$mcap" "$tmp/lost.mcap" 30) || fail "lost_notice.mjs: $out"
out=$("$bin/servo" replay "$tmp/lost.mcap" --pattern "$pattern" --z-hat 0.9 --no-plot --expect-identical) &&
  grep -q "0 recorded twists not answered, .*; LOST notices (not compared): 1 recorded, 0 replayed" <<<"$out" ||
  fail "a recorded LOST notice: $out"
rm -f "$tmp/lost.mcap"
echo "replay: a recorded LOST notice counted apart: $out"

# another configuration commands otherwise, on the same frames
out=$("$bin/servo" replay "$mcap" --pattern "$pattern" --z-hat 0.6 --robust huber -o "$tmp/other" --no-plot) ||
  fail "servo replay --z-hat 0.6: $out"
grep -q "compared: [0-9]* differ, max |difference| [0-9.e-]*" <<<"$out" || fail "a replay with --z-hat 0.6 differs in nothing: $out"
cmp -s "$run/replay/replay.csv" "$tmp/other/replay.csv" && fail "the two replays wrote the same trace"
awk -F, '!/^#/ && NR > 2 && $NF == 0 {n++} END {exit !(n > 0)}' "$tmp/other/replay.csv" || fail "no row of the --z-hat 0.6 replay differs"
echo "replay: $out" | head -1
out=$("$bin/servo" replay "$mcap" --pattern "$pattern" --z-hat 0.6 --no-plot --expect-identical 2>&1) &&
  fail "--expect-identical passed a replay that differs"

# the in-process experiment records the same topics in simulated time, and replays bit for bit
exp=$("$bin/cellsim" experiment "$src/sim/scenarios/plane.yaml" --z-hat 0.9 --no-plot -o "$tmp/exp" \
      --record "$tmp/exp.mcap" 2>&1) || fail "cellsim experiment --record: $exp"
counts=$(sed -n 's/^ *recorded messages: //p' <<<"$exp")
json="{$(sed -E 's|(/[^ ,]+) ([0-9]+)|"\1": \2|g' <<<"$counts")}"
report=$(node "$src/tests/interop/mcap/check_mcap.mjs" "$build/mcap-check" "$tmp/exp.mcap" "$json" 2>&1) ||
  fail "@mcap/core on the experiment's recording: $report"
out=$("$bin/servo" replay "$tmp/exp.mcap" --pattern "$pattern" --z-hat 0.9 --no-plot --expect-identical) ||
  fail "the experiment's recording does not replay bit for bit: $out"
echo "experiment: $out"
exp=$("$bin/cellsim" experiment "$src/sim/scenarios/plane.yaml" --z-hat 0.9 --no-plot --max-iterations 20 \
      --record "$tmp/noimg.mcap" --record-no-images 2>&1)
grep -q "recorded messages: .*/camera/image_raw" <<<"$exp" && fail "--record-no-images recorded images: $exp"
report=$(node "$src/tests/interop/mcap/check_mcap.mjs" "$build/mcap-check" "$tmp/noimg.mcap" 2>&1) ||
  fail "@mcap/core on a recording without images: $report"
grep -q '"/camera/image_raw"' <<<"$report" && fail "images in a --record-no-images recording: $report"
echo "experiment: --record-no-images leaves the images out ($(stat -c %s "$tmp/noimg.mcap") bytes for 20 iterations)"

# a truncated recording (a recorder killed, a disk that filled): its complete chunks replay,
# and the replay says it is truncated
size=$(stat -c %s "$mcap")
head -c $((size / 2)) "$mcap" >"$tmp/truncated.mcap"
out=$(timeout 60 "$bin/servo" replay "$tmp/truncated.mcap" --pattern "$pattern" --z-hat 0.9 --no-plot --expect-identical 2>&1) ||
  fail "a truncated recording does not replay its complete chunks: $out"
grep -q "truncated.mcap: offset [0-9]*: truncated: .* complete chunks" <<<"$out" || fail "a truncated recording is not named so: $out"
grep -q "every one identical bit for bit" <<<"$out" || fail "a truncated recording's twists differ: $out"
echo "replay: $(head -1 <<<"$out")"

# A servo and a recording cellsim (autorun), signalled with SIG once the recording's partial
# file passes BYTES; sets rc to cellsim's exit code
record_then_signal() {  # NAME BYTES SIG
  local name="$1" bytes="$2" sig="$3" servo_pid sim_pid i
  "$bin/servo" run --pattern "$pattern" --z-hat 0.9 >"$tmp/${name}_servo.log" 2>&1 &
  servo_pid=$!
  "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --autorun --max-frames 100000 --record "$tmp/$name.mcap" \
    >"$tmp/${name}_sim.log" 2>&1 &
  sim_pid=$!
  for ((i = 0; i < 600; i++)); do  # bounded: 60 s
    [ "$(stat -c %s "$tmp/$name.mcap.partial" 2>/dev/null || echo 0)" -gt "$bytes" ] && break
    kill -0 $sim_pid 2>/dev/null || break
    sleep 0.1
  done
  kill "-$sig" $sim_pid 2>/dev/null; wait $sim_pid; rc=$?
  kill -INT $servo_pid 2>/dev/null; wait $servo_pid 2>/dev/null
}

# a recording killed with SIGKILL mid-run: FILE.partial holds its complete chunks
record_then_signal killed 30000000 KILL
[ -e "$tmp/killed.mcap" ] && fail "a killed recorder left a file under the recording's own name"
[ -s "$tmp/killed.mcap.partial" ] || fail "no killed.mcap.partial: $(tail -3 "$tmp/killed_sim.log")"
# (not --expect-identical: the frame at the cut may have its twist recorded and not be answered)
out=$(timeout 120 "$bin/servo" replay "$tmp/killed.mcap.partial" --pattern "$pattern" --z-hat 0.9 --no-plot 2>&1) ||
  fail "a recording killed mid-run does not replay its complete chunks: $out"
grep -q "truncated: " <<<"$out" || fail "a killed recording is not named truncated: $out"
grep -q "[1-9][0-9]* images, [1-9][0-9]* recorded twists compared: every one identical" <<<"$out" ||
  fail "a killed recording replayed nothing: $out"
echo "replay after SIGKILL: $(tail -1 <<<"$out")"

# SIGHUP (a closed terminal or ssh session) stops a recording service as SIGINT does: the file
# is closed whole under its own name
record_then_signal hup 10000000 HUP
[ $rc -eq 0 ] || fail "SIGHUP: cellsim exit $rc: $(tail -2 "$tmp/hup_sim.log")"
[ -s "$tmp/hup.mcap" ] && [ ! -e "$tmp/hup.mcap.partial" ] || fail "SIGHUP left no whole recording: $(ls "$tmp" | grep hup)"
out=$("$bin/servo" replay "$tmp/hup.mcap" --pattern "$pattern" --z-hat 0.9 --no-plot 2>&1) || fail "the SIGHUP recording: $out"
grep -q "truncated" <<<"$out" && fail "the recording closed on SIGHUP is truncated: $out"
echo "record: SIGHUP closes the recording whole: $(tail -1 <<<"$out")"

# a disk that fills (a file-size limit: writes fail with EFBIG as they would with ENOSPC): the
# run converges and keeps its exit code, the cause is said once, and the file is readable
"$bin/servo" run --pattern "$pattern" --z-hat 0.9 >"$tmp/f_servo.log" 2>&1 &
f_servo=$!
( ulimit -f 20480; exec timeout 120 "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --autorun --exit-on-converged \
    --max-frames 800 --record "$tmp/full.mcap" ) >"$tmp/f_sim.log" 2>&1
rc=$?
kill -INT $f_servo 2>/dev/null; wait $f_servo 2>/dev/null
[ $rc -eq 0 ] || fail "a full disk changed the session's exit code to $rc: $(tail -3 "$tmp/f_sim.log")"
grep -q "session ended: converged" "$tmp/f_sim.log" || fail "the run with a full disk did not converge: $(tail -3 "$tmp/f_sim.log")"
[ "$(grep -c 'File too large' "$tmp/f_sim.log")" -eq 1 ] || fail "the cause is not said once: $(grep -i 'record\|large' "$tmp/f_sim.log")"
grep -q "size limit" "$tmp/f_sim.log" && fail "a full disk was called the size limit: $(grep recorded "$tmp/f_sim.log")"
out=$("$bin/servo" replay "$tmp/full.mcap" --pattern "$pattern" --z-hat 0.9 --no-plot --expect-identical 2>&1) ||
  fail "the recording of a full disk does not replay: $out"
grep -q "the recording stopped before the run ended (.*full.mcap: write failed: File too large" <<<"$out" ||
  fail "the replay does not say the recording of a full disk stopped: $out"
echo "record: a full disk: converged, exit 0, said once; the recording replays: $(tail -1 <<<"$out")"

# a recording never replaces a file: an existing one, a scenario, stays as it was
cp "$src/sim/scenarios/plane.yaml" "$tmp/plane.yaml"
one_line_error "--record onto an existing file" "plane.yaml: exists" \
  "$bin/cellsim" experiment "$src/sim/scenarios/plane.yaml" --max-iterations 2 --no-plot --record "$tmp/plane.yaml"
cmp -s "$src/sim/scenarios/plane.yaml" "$tmp/plane.yaml" || fail "--record changed the file it was refused"
one_line_error "--record ''" "--record: an empty file name" \
  "$bin/cellsim" experiment "$src/sim/scenarios/plane.yaml" --max-iterations 2 --no-plot --record ""
one_line_error "serve --record onto an existing file" "plane.yaml: exists" \
  "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --max-frames 1 --record "$tmp/plane.yaml"
cmp -s "$src/sim/scenarios/plane.yaml" "$tmp/plane.yaml" || fail "serve --record changed the file it was refused"
# start-up that fails (security files missing) leaves neither the file nor its .partial
out=$(ROS_SECURITY_ENABLE=true ROS_SECURITY_STRATEGY=Enforce ROS_SECURITY_KEYSTORE="$tmp/no_keystore" \
      "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --max-frames 1 --record "$tmp/nostart.mcap" 2>&1) &&
  fail "cellsim started with no keystore: $out"
[ -e "$tmp/nostart.mcap" ] || [ -e "$tmp/nostart.mcap.partial" ] && fail "a start-up that failed left a recording"
echo "record: an existing file, an empty name and a failed start-up leave every file as it was"

# a broken recording: one line naming the file and the offset, no crash, no hang
printf 'NOTMCAP!' | cat - <(tail -c +9 "$mcap" | head -c 100000) >"$tmp/magic.mcap"
one_line_error "a wrong magic" "magic.mcap: offset 0: wrong magic" \
  timeout 60 "$bin/servo" replay "$tmp/magic.mcap" --pattern "$pattern" --no-plot
mkfifo "$tmp/fifo.mcap"
one_line_error "a FIFO" "fifo.mcap" timeout 60 "$bin/servo" replay "$tmp/fifo.mcap" --pattern "$pattern" --no-plot
echo "replay: a wrong magic and a FIFO are one line each"
