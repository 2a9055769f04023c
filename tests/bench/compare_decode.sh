#!/usr/bin/env bash
# The decoder of one build against another's on the same frames, in one run (issue 41's decode
# time): NEW's simulator renders FRAMES noise draws of SCENARIO at its desired pose once; each
# build's `servo decode` decodes them all five times, with the projector's calibration, in turns
# on one core, ROUNDS times; printed: each round's medians per frame and their ratio, then the
# median ratio. The same images for both builds (decode_bench renders its scenes with its own
# build's simulator, whose frames change as the simulator does). Also printed: the spots each
# build names a frame, on average (a decoder that names other spots does other work).
# NOISE, when given, is the camera's noise sigma the frames are rendered with instead of the
# scenario's (a noisy frame's segmentation takes two passes: docs/decoding.md, Segmentation).
#   tests/bench/compare_decode.sh OLD_BIN_DIR NEW_BIN_DIR SOURCE_DIR [ROUNDS] [SCENARIO] [FRAMES] [NOISE]
# e.g. git worktree add /tmp/pre41 cc53ed1 && cmake -S /tmp/pre41 -B /tmp/pre41/build -G Ninja \
#        -DCMAKE_BUILD_TYPE=Release && ninja -C /tmp/pre41/build servo
#      tests/bench/compare_decode.sh /tmp/pre41/build/bin build/bin . 6 sim/scenarios/ham.yaml
set -euo pipefail
old="$1"; new="$2"; src="$3"; rounds="${4:-6}"; scenario="${5:-$src/sim/scenarios/ham.yaml}"; frames="${6:-20}"
export OPENCV_FOR_THREADS_NUM=1
core="$(cut -d, -f1 <<<"$(taskset -pc $$ | sed 's/.*: //')" | cut -d- -f1)"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
if [[ -n "${7:-}" ]]; then  # a copy of the scenario in the work folder, its paths made absolute
  [[ "$7" =~ ^[0-9]{1,3}([.][0-9]+)?$ ]] || { echo "compare_decode.sh: NOISE must be a sigma in 8-bit levels, got '$7'" >&2; exit 2; }
  /usr/bin/python3 - "$scenario" "$work/scenario.yaml" "$7" <<'EOF'
import os, re, sys
source, copy, sigma = sys.argv[1], sys.argv[2], float(sys.argv[3])
here = os.path.dirname(os.path.abspath(source))
text = open(source, encoding="utf-8").read()
text = re.sub(r"((?:\.\./)+[\w./-]+)", lambda m: os.path.normpath(os.path.join(here, m.group(1))), text)
text, n = re.subn(r"(\n\s+noise_sigma:\s*)[0-9.]+", lambda m: m.group(1) + repr(sigma), text, count=1)
if n != 1:
    sys.exit(f"compare_decode.sh: {source}: its camera has no noise_sigma to change")
open(copy, "w", encoding="utf-8").write(text)
EOF
  scenario="$work/scenario.yaml"
fi
for ((f = 0; f < frames; ++f)); do
  "$new/cellsim" render "$scenario" --pose desired --frame "$f" -o "$work/frame_$f.png" --truth "$work/truth_$f.json" >/dev/null
done
"$new/cellsim" calibration "$scenario" -o "$work/projector.yaml" >/dev/null
# the camera's intrinsics from the scenario (as the simulator reads them), its pose from the truth
mapfile -t camera < <(/usr/bin/python3 - "$scenario" "$work/truth_0.json" <<'EOF'
import json, math, sys, yaml
cam = yaml.safe_load(open(sys.argv[1], encoding="utf-8"))["camera"]
w, h = cam["resolution"]
fx, fy = cam["focal_px"] if "focal_px" in cam else [0.5 * w / math.tan(math.radians(0.5 * cam["fov_deg"]))] * 2
cx, cy = cam.get("principal_point_px", [0.5 * (w - 1), 0.5 * (h - 1)])
k = list(cam.get("distortion", [0, 0, 0, 0, 0])) + [0] * 5
pose = json.load(open(sys.argv[2], encoding="utf-8"))["camera_pose"]
for x in ["--camera", fx, fy, cx, cy, *k[:5], "--camera-pose", *pose["position_m"], *pose["orientation_xyzw"]]:
    print(repr(x) if isinstance(x, float) else x)
EOF
)
pattern="$(/usr/bin/python3 -c "import sys, yaml; print(yaml.safe_load(open(sys.argv[1]))['projector']['pattern'])" "$scenario")"
pattern="$(cd "$(dirname "$scenario")" && realpath "$pattern")"
images=()
for ((k = 0; k < 5; ++k)); do for ((f = 0; f < frames; ++f)); do images+=("$work/frame_$f.png"); done; done
decode() {  # decode BIN OUT_DIR: the median time per frame
  taskset -c "$core" "$1/servo" decode "${images[@]}" --pattern "$pattern" --projector "$work/projector.yaml" \
    "${camera[@]}" --json-dir "$2" 2>&1 | sed -n 's/.*median \([0-9.]*\) ms.*/\1/p'
}
ratios=()
for ((r = 1; r <= rounds; ++r)); do
  o="$(decode "$old" "$work/old")"; n="$(decode "$new" "$work/new")"
  ratio="$(awk -v o="$o" -v n="$n" 'BEGIN { printf "%.3f", n / o }')"
  ratios+=("$ratio")
  echo "round $r: previous $o ms, this $n ms a frame: ${ratio}x"
done
spots() {  # spots BIN_OUT_DIR: the mean number of spots named a frame
  /usr/bin/python3 -c "import json, sys; n = [len(json.load(open(f))['spots']) for f in sys.argv[1:]]; print(f'{sum(n) / len(n):.1f}')" "$1"/*.json
}
median="$(printf '%s\n' "${ratios[@]}" | sort -g | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2] + a[NR/2+1]) / 2}')"
echo "this against previous, median of $rounds rounds: ${median}x; spots named a frame: previous $(spots "$work/old"), this $(spots "$work/new")"
