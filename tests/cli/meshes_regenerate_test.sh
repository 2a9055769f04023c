#!/usr/bin/env bash
# The committed meshes are exactly what the committed generator writes.
set -u
tool="$1"; committed="$2"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
"$tool" "$tmp" >/dev/null || { echo "FAIL: make_meshes"; exit 1; }
for m in plane elliptic_cylinder ham; do
  cmp -s "$tmp/$m.obj" "$committed/$m.obj" || { echo "FAIL: meshes/$m.obj differs from make_meshes output (run: make_meshes meshes/)"; exit 1; }
done
echo "meshes: committed files match the generator"
