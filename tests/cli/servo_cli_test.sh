#!/usr/bin/env bash
# `servo decode` and the servo's configuration files as a user meets them: bad input is one line.
set -u
servo="$1"; cellsim="$2"; src="$3"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
source "$(dirname "$0")/lib.sh"
pattern="$src/servo/pattern/data/marray_20x20_k3_w3.txt"

"$cellsim" render "$src/sim/scenarios/plane.yaml" -o "$tmp/plane.png" >/dev/null || fail "render"
out=$("$servo" decode "$tmp/plane.png" --pattern "$pattern" --json "$tmp/d.json" --overlay "$tmp/o.png") || fail "decode: $out"
grep -q '"decoded": 388' "$tmp/d.json" || fail "decoded count: $(grep decoded "$tmp/d.json")"
[ -s "$tmp/o.png" ] || fail "no overlay"

printf 'not an image' > "$tmp/bad.png"
one_line_error "unreadable image" "cannot read image" "$servo" decode "$tmp/bad.png" --pattern "$pattern"
: > "$tmp/empty.png"
one_line_error "empty image" "cannot read image" "$servo" decode "$tmp/empty.png" --pattern "$pattern"
# a grey image decodes to zero spots, not an error
"$cellsim" render "$src/sim/scenarios/plane.yaml" -o "$tmp/g.png" >/dev/null
/usr/bin/python3 -c "
import matplotlib.image as m, numpy as n
a = m.imread('$tmp/g.png'); g = a[..., :3].mean(axis=2); m.imsave('$tmp/grey.png', n.dstack([g, g, g]))" || fail "grey image"
out=$("$servo" decode "$tmp/grey.png" --pattern "$pattern" --json "$tmp/g.json") || fail "grey: $out"
grep -q '"decoded": 0' "$tmp/g.json" || fail "grey image decoded spots"

printf 'model: desired\ngian: 0.5\n' > "$tmp/bad.yaml"
one_line_error "config typo" "gian: unknown key" "$servo" run --pattern "$pattern" --config "$tmp/bad.yaml"
printf 'fx: 1500\n' > "$tmp/proj.yaml"
one_line_error "calibration" "fy: missing" "$servo" run --pattern "$pattern" --projector "$tmp/proj.yaml"
one_line_error "model name" "expected desired-constant-depth" "$servo" run --pattern "$pattern" --model Current
echo "servo CLI: all checks passed"
