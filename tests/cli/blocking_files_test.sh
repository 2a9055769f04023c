#!/usr/bin/env bash
# Files named on a command line are opened as regular files only (issue 18, item 9): a FIFO,
# a /proc file (directly or through a link in a folder) and a FIFO sidecar are refused at
# once in one line, where they used to hang `servo decode` and `cellsim render` for good.
set -u
servo="$1"; cellsim="$2"; src="$3"
source "$(dirname "$0")/lib.sh"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
pattern="$src/servo/pattern/data/marray_20x20_k3_w3.txt"
mkfifo "$tmp/fifo.png" "$tmp/fifo.yaml"
# every command below must answer within its bound: a hang is a failure, not a wait
bounded() { timeout 30 "$@"; }
one_line_error "decode a FIFO" "fifo.png: image is a FIFO, not a regular file" bounded "$servo" decode "$tmp/fifo.png" --pattern "$pattern"
one_line_error "decode /proc" "kernel file" bounded "$servo" decode /proc/self/status --pattern "$pattern"
one_line_error "pattern a FIFO" "pattern file is a FIFO" bounded "$servo" decode "$tmp/fifo.png" --pattern "$tmp/fifo.yaml"
one_line_error "render a FIFO scenario" "fifo.yaml: scenario file is a FIFO" bounded "$cellsim" render "$tmp/fifo.yaml" -o "$tmp/x.png"
one_line_error "render a /proc scenario" "kernel file" bounded "$cellsim" render /proc/self/status -o "$tmp/x.png"
one_line_error "render a folder" "scenario file is a folder, not a regular file" bounded "$cellsim" render "$tmp" -o "$tmp/x.png"
one_line_error "experiment on a FIFO" "scenario file is a FIFO" bounded "$cellsim" experiment "$tmp/fifo.yaml" --no-plot
# a folder with a good image, a link to /proc/kmsg, and an image whose sidecar pose is a FIFO
mkdir -p "$tmp/frames"
"$cellsim" render "$src/sim/scenarios/plane.yaml" --pose desired -o "$tmp/frames/a.png" >/dev/null || fail "render"
ln -s /proc/kmsg "$tmp/frames/b.png"
err=$(bounded "$servo" decode "$tmp/frames" --pattern "$pattern" 2>&1 >/dev/null); rc=$?
[ $rc -lt 124 ] || fail "decode of a folder with a link to /proc/kmsg: exit $rc"
grep -q "b.png: image is a kernel file" <<<"$err" || fail "the /proc link was not named: $err"
cp "$tmp/frames/a.png" "$tmp/c.png"; mkfifo "$tmp/c.json"
"$cellsim" calibration "$src/sim/scenarios/plane.yaml" -o "$tmp/cal.yaml" >/dev/null || fail "calibration"
one_line_error "a FIFO sidecar" "c.json: camera pose file is a FIFO" bounded "$servo" decode "$tmp/c.png" --pattern "$pattern" \
  --projector "$tmp/cal.yaml" --camera 800 800 319.5 239.5
echo "blocking files: refused at once"
