#!/usr/bin/env bash
# `servo view` headless: with the two services running, it writes PNG frames of the camera
# with decoded ids.
set -u
bin="$1"; src="$2"
source "$(dirname "$0")/services.sh"
start_services "$bin" "$src" "--autorun --mode realtime --max-frames 300"
timeout 120 "$bin/servo" view --output "$tmp/frames" --frames 5 || { echo "FAIL: servo view"; exit 1; }
n=$(ls "$tmp/frames"/frame_*.png 2>/dev/null | wc -l)
[ "$n" -eq 5 ] || { echo "FAIL: $n frames written"; exit 1; }
echo "servo view: $n frames"
