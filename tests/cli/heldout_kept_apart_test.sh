#!/usr/bin/env bash
# The held-out scenes stay held out (docs/decoding.md, Today's figures): no decoder source, no
# stage test and no saved spot fixture is made from them, so no number can be set on them
# through a test; bin/decode-heldout alone sweeps them, and it sweeps exactly the five of
# sim/scenarios/heldout, each a shape of meshes/heldout.
set -u
src="$1"
source "$(dirname "$0")/lib.sh"
names="pyramid|bowl|arch|dumbbell|bottle"
hits=$(grep -rlE "(scenarios|meshes)/heldout|heldout_($names)" "$src/servo" "$src/tests/unit/vision" \
  "$src/tests/data/vision" "$src/sim/experiment" "$src/sim/app" 2>/dev/null)
[ -z "$hits" ] || fail "made from a held-out scene (tune on sim/scenarios and sim/scenarios/compact only): $hits"
shipped=$(cd "$src/sim/scenarios/heldout" && ls -- *.yaml | sed 's/\.yaml$//' | sort | paste -sd' ')
[ "$shipped" = "arch bottle bowl dumbbell pyramid" ] || fail "sim/scenarios/heldout holds: $shipped"
swept=$(grep -oE 'for s in \("pyramid", "bowl", "arch", "dumbbell", "bottle"\)' "$src/bin/decode-heldout")
[ -n "$swept" ] || fail "bin/decode-heldout does not sweep the five held-out scenes"
for s in arch bottle bowl dumbbell pyramid; do
  grep -q "mesh: \.\./\.\./\.\./meshes/heldout/$s\.obj" "$src/sim/scenarios/heldout/$s.yaml" ||
    fail "sim/scenarios/heldout/$s.yaml: its object is not meshes/heldout/$s.obj"
  grep -q "^# Never used to set a decoder parameter" "$src/sim/scenarios/heldout/$s.yaml" ||
    fail "sim/scenarios/heldout/$s.yaml does not say it is held out"
done
echo "held-out scenes: used by bin/decode-heldout alone"
