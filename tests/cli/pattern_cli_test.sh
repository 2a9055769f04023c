#!/usr/bin/env bash
# The `pattern` CLI as a user runs it: check the committed pattern, generate, refuse the impossible.
set -u
pattern="$1"; src="$2"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

out=$("$pattern" check "$src/servo/pattern/data/marray_20x20_k3_w3.txt") || fail "committed pattern check: $out"
grep -q "window property: holds" <<<"$out" || fail "no verdict: $out"
grep -q "distinct windows: 324 of 324" <<<"$out" || fail "window count: $out"

out=$("$pattern" generate --rows 64 --cols 64 --colours 3 --window 3 --seed 5 -o "$tmp/p64.txt") || fail "64x64: $out"
grep -q "generated in" <<<"$out" || fail "no timing: $out"
"$pattern" check "$tmp/p64.txt" >/dev/null || fail "64x64 does not pass check"

printf '012\n120\n201\n012\n120\n201\n' > "$tmp/rep.txt"
out=$("$pattern" check "$tmp/rep.txt"); rc=$?
[ $rc -eq 1 ] || fail "repeated window: exit $rc"
grep -q "window property: FAILS" <<<"$out" || fail "repeat verdict: $out"

err=$("$pattern" generate --rows 300 --cols 300 --colours 3 --seed 1 -o "$tmp/x.txt" 2>&1); rc=$?
[ $rc -ne 0 ] || fail "impossible request succeeded"
[ "$(wc -l <<<"$err")" -eq 1 ] || fail "error is not one line: $err"
grep -q "cannot be satisfied" <<<"$err" || fail "impossible request: $err"

err=$("$pattern" generate --rows 20 --cols 20 --colours 3 --min-hamming 4 --time-budget 1 --seed 1 -o "$tmp/x.txt" 2>&1); rc=$?
[ $rc -ne 0 ] || fail "over-budget request succeeded"
grep -q "time budget" <<<"$err" || fail "budget: $err"

printf '01a\n' > "$tmp/bad.txt"
err=$("$pattern" check "$tmp/bad.txt" 2>&1); rc=$?
[ $rc -ne 0 ] || fail "bad digit accepted"
grep -q "bad.txt:1: wrong digit 'a'" <<<"$err" || fail "bad digit: $err"

"$pattern" render "$src/servo/pattern/data/marray_20x20_k3_w3.txt" -o "$tmp/p.png" >/dev/null || fail "render"
[ -s "$tmp/p.png" ] || fail "render wrote nothing"
echo "pattern CLI: all checks passed"
