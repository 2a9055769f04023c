#!/usr/bin/env bash
# A bin/demo that fails keeps the previous results (issue 18, item 3): the run goes into a
# folder of its own and replaces the old results only once it has run.
set -u
src="$1"; build="$2"
source "$(dirname "$0")/lib.sh"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
mkdir -p "$tmp/demo/plane"
echo "earlier run" > "$tmp/demo/plane/trace.csv"
# a domain no participant can join: the demo fails after its set-up
err=$(CELL_OUT="$tmp" SETUP_NO_BUILD=1 BUILD_DIR="$build" ROS_DOMAIN_ID=999 timeout 120 "$src/bin/demo" plane 2>&1 >/dev/null)
rc=$?
[ $rc -ne 0 ] || fail "bin/demo with ROS_DOMAIN_ID=999 succeeded"
[ $rc -lt 124 ] || fail "bin/demo: exit $rc: $err"
[ "$(cat "$tmp/demo/plane/trace.csv")" = "earlier run" ] || fail "the previous results were deleted: $err"
[ -d "$tmp/demo/plane.failed" ] || fail "no plane.failed folder with the failed run's logs"
grep -q "previous results in .* are kept" <<<"$err" || fail "the demo did not say the previous results were kept: $err"
echo "demo: a failed run keeps the previous results"
