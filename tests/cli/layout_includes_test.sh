#!/bin/bash
# Issue 20: the build's arrows. bin/check-includes passes on the tree, and fails, naming the
# file and the header, on a tree where the control law includes the renderer and the
# simulator service includes the meeting place.
set -u
src=$1
"$src/bin/check-includes" "$src" || { echo "FAIL: the tree has an include across a forbidden arrow"; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$tmp/servo/control" "$tmp/sim/app" "$tmp/sim/render" "$tmp/sim/loop"
printf '#include "servo/control/control_law.hpp"\n#include "sim/render/renderer.hpp"\n' > "$tmp/servo/control/law.cpp"
printf '#include "sim/render/renderer.hpp"\n#include "sim/loop/experiment.hpp"\n' > "$tmp/sim/app/sim_service.cpp"
printf '#include "servo/pipeline/servo_pipeline.hpp"\n' > "$tmp/sim/loop/runner.cpp"
out=$("$src/bin/check-includes" "$tmp"); rc=$?
[ $rc -eq 1 ] || { echo "FAIL: exit $rc on forbidden includes"; echo "$out"; exit 1; }
for want in "servo/control/law.cpp:2: includes sim/render/renderer.hpp" "sim/app/sim_service.cpp:2: includes sim/loop/experiment.hpp"; do
  grep -qF "$want" <<<"$out" || { echo "FAIL: no line '$want' in:"; echo "$out"; exit 1; }
done
[ "$(grep -c 'across an arrow' <<<"$out")" -eq 2 ] || { echo "FAIL: expected exactly the two forbidden includes:"; echo "$out"; exit 1; }
echo "ok: the layout's arrows hold, and a crossing is named"
