#!/usr/bin/env bash
# Every numeric flag of every command refuses NaN, infinities and 1e300 in one line, before
# anything runs, and nothing aborts (issue 18, item 16: `--gain nan` once ended a campaign
# with "terminate called without an active exception"). The flags are found in each
# command's --help, so a flag added later is walked too.
set -u
bin="$1"; src="$2"
source "$(dirname "$0")/lib.sh"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
scenario="$src/sim/scenarios/plane.yaml"
checked=0
walk() {  # walk PROGRAM SUBCOMMAND...
  local help
  help=$("$bin/$1" "${@:2}" --help 2>&1) || fail "$1 ${*:2} --help"
  # options shown as "--name FLOAT..." / "--name INT..." / "--name UINT..."
  while read -r flag type; do
    for bad in nan inf -inf 1e300; do
      case "$type" in INT*|UINT*) [ "$bad" = 1e300 ] || [ "$bad" = nan ] || continue ;; esac
      err=$(timeout 60 "$bin/$1" "${@:2}" "$scenario" "$flag" "$bad" -o "$tmp/out" 2>&1 >/dev/null); rc=$?
      [ $rc -ne 0 ] || fail "$1 ${*:2} $flag $bad: accepted"
      [ $rc -lt 124 ] || fail "$1 ${*:2} $flag $bad: exit $rc (a crash or a hang): $err"
      [ "$(printf '%s\n' "$err" | wc -l)" -eq 1 ] || fail "$1 ${*:2} $flag $bad: not one line: $err"
      grep -q -- "${flag}" <<<"$err" || fail "$1 ${*:2} $flag $bad: the error does not name the flag: $err"
      checked=$((checked + 1))
    done
  done < <(grep -oE -- '--[a-z0-9,-]+ (FLOAT|INT|UINT)[^ ]*' <<<"$help" | awk '{split($1, a, ","); print a[1], $2}' | sort -u)
}
for sub in render decode-sweep experiment fig5-search campaign study serve calibration; do walk cellsim "$sub"; done
for sub in decode run view; do walk servo "$sub"; done
for sub in generate check render; do walk pattern "$sub"; done
[ "$checked" -ge 60 ] || fail "only $checked flag values checked: is --help still listing the types?"
echo "numeric flags: $checked bad values refused in one line"
