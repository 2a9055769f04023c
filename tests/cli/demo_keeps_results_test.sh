#!/usr/bin/env bash
# A bin/demo that fails keeps the previous results (issue 18, item 3): the run goes into a
# folder of its own and replaces the old results only once it has run, and only if the demo
# wrote all they hold.
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
# a run that succeeds replaces the previous results only if the demo wrote all they hold: a
# user's note there is named and kept, and the run's own results wait in plane.failed
mkdir -p "$tmp/ok/demo/plane"; echo "my notes" > "$tmp/ok/demo/plane/notes.md"
err=$(CELL_OUT="$tmp/ok" SETUP_NO_BUILD=1 BUILD_DIR="$build" timeout 200 "$src/bin/demo" plane 2>&1 >/dev/null)
rc=$?
[ $rc -eq 1 ] || fail "bin/demo over a folder with a user's note: exit $rc: $err"
[ "$(cat "$tmp/ok/demo/plane/notes.md")" = "my notes" ] || fail "the user's note was deleted"
grep -q "holds 'notes.md', which the demo did not write" <<<"$err" || fail "the note was not named: $err"
[ -s "$tmp/ok/demo/plane.failed/trace.csv" ] || fail "the run's results are not in plane.failed"
# the note moved away, the next run replaces the folder (and its plane.failed, the demo's own)
mv "$tmp/ok/demo/plane/notes.md" "$tmp/notes.md"
CELL_OUT="$tmp/ok" SETUP_NO_BUILD=1 BUILD_DIR="$build" timeout 200 "$src/bin/demo" plane >/dev/null 2>&1 ||
  fail "bin/demo after the note was moved away"
[ -s "$tmp/ok/demo/plane/trace.csv" ] && [ ! -e "$tmp/ok/demo/plane.failed" ] || fail "the results were not replaced"
echo "demo: a failed run keeps the previous results; a user's file among them is never deleted"
