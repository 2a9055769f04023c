#!/usr/bin/env bash
# `servo view` headless: with the two services running, it writes PNG frames of the camera
# with decoded ids.
set -u
bin="$1"; src="$2"
export ROS_DOMAIN_ID=$(( $$ % 150 + 50 ))
tmp=$(mktemp -d)
cleanup() { kill -INT $servo $sim 2>/dev/null; sleep 1; kill -KILL $servo $sim 2>/dev/null; rm -rf "$tmp"; }
trap cleanup EXIT
"$bin/servo" run --pattern "$src/servo/pattern/data/marray_20x20_k3_w3.txt" --z-hat 0.9 > "$tmp/servo.log" 2>&1 &
servo=$!
"$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --autorun --mode realtime --max-frames 300 > "$tmp/sim.log" 2>&1 &
sim=$!
timeout 120 "$bin/servo" view --output "$tmp/frames" --frames 5 || { echo "FAIL: servo view"; exit 1; }
n=$(ls "$tmp/frames"/frame_*.png 2>/dev/null | wc -l)
[ "$n" -eq 5 ] || { echo "FAIL: $n frames written"; exit 1; }
echo "servo view: $n frames"
