#!/usr/bin/env bash
# `servo view` headless: with no cell it says what it waits for (issue 43: "ready", then nothing);
# with the two services running, it writes PNG frames of the camera with decoded ids and counts
# what it received, dropped and refused.
set -u
bin="$1"; src="$2"
source "$(dirname "$0")/services.sh"
# no cell on a domain of its own: the viewer says it waits, and its summary received nothing
claim_domain
lonely=$(mktemp -d)
ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID="$cell_domain" \
  "$bin/servo" view --output "$lonely/frames" > "$lonely/view.log" 2>&1 &
view=$!
for _ in $(seq 600); do grep -q "waiting for images" "$lonely/view.log" && break; sleep 0.1; done
kill -INT $view; wait $view
grep -q "servo view: waiting for images on rt/camera/image_raw (domain $cell_domain): is a cellsim serving there?" \
  "$lonely/view.log" || { echo "FAIL: no word while waiting: $(cat "$lonely/view.log")"; exit 1; }
grep -q "0 frames written to .*; 0 images received, 0 dropped" "$lonely/view.log" ||
  { echo "FAIL: summary: $(tail -1 "$lonely/view.log")"; exit 1; }
rm -rf "$lonely"
exec {cell_domain_fd}>&-

start_services "$bin" "$src" "--autorun --mode realtime --max-frames 300"
timeout 120 "$bin/servo" view --output "$tmp/frames" --frames 5 > "$tmp/view.log" || { echo "FAIL: servo view"; exit 1; }
n=$(ls "$tmp/frames"/frame_*.png 2>/dev/null | wc -l)
[ "$n" -eq 5 ] || { echo "FAIL: $n frames written"; exit 1; }
grep -q "servo view: 5 frames written to .*; [0-9]* images received, [0-9]* dropped" "$tmp/view.log" ||
  { echo "FAIL: summary: $(tail -1 "$tmp/view.log")"; exit 1; }
echo "servo view: $n frames; $(tail -1 "$tmp/view.log")"
