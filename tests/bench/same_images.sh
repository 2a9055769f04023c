#!/usr/bin/env bash
# Whether a change to the renderer kept every byte: every shipped scenario at its taught and
# initial poses, rendered by two builds' cellsim, compared byte for byte (PNG files, which
# encode the same pixels the same way). Exits 1 naming each frame that differs.
#   tests/bench/same_images.sh OLD_BIN_DIR NEW_BIN_DIR SOURCE_DIR
set -euo pipefail
old="$1/cellsim"; new="$2/cellsim"; src="$3"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
frames=0; differ=0
for scenario in "$src"/sim/scenarios/*.yaml; do
  for pose in desired initial; do
    "$old" render "$scenario" --pose "$pose" -o "$work/old.png" >/dev/null
    "$new" render "$scenario" --pose "$pose" -o "$work/new.png" >/dev/null
    frames=$((frames + 1))
    if ! cmp -s "$work/old.png" "$work/new.png"; then
      differ=$((differ + 1))
      echo "same_images: $(basename "$scenario") at $pose differs"
    fi
  done
done
echo "same_images: $frames frames, $differ differ"
[ "$differ" = 0 ]
