#!/usr/bin/env bash
# The committed meshes (scene objects and the arms' links) are exactly what the committed
# generator writes: the same words, and numbers within the cross-machine tolerance
# (tests/support/numeric_text.hpp; another CPU's libm may round a last digit differently).
set -u
tool="$1"; committed="$2"; robots="$3"; numeric_diff="$4"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
"$tool" "$tmp" >/dev/null || { echo "FAIL: make_meshes"; exit 1; }
for m in plane elliptic_cylinder ham heldout/pyramid heldout/bowl heldout/arch heldout/dumbbell heldout/bottle \
    compact/egg compact/can compact/wedge compact/sphere compact/torus compact/cone compact/box compact/step; do
  "$numeric_diff" "$tmp/$m.obj" "$committed/$m.obj" >/dev/null || { echo "FAIL: meshes/$m.obj differs from make_meshes output (run: make_meshes meshes/)"; exit 1; }
done
"$tool" --robots "$tmp/robots" >/dev/null || { echo "FAIL: make_meshes --robots"; exit 1; }
for f in "$tmp"/robots/*/meshes/*.obj; do
  rel="${f#$tmp/robots/}"
  "$numeric_diff" "$f" "$robots/$rel" >/dev/null || { echo "FAIL: sim/robots/$rel differs from make_meshes output (run: make_meshes --robots sim/robots)"; exit 1; }
done
echo "meshes: committed files match the generator"
