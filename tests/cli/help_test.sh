#!/usr/bin/env bash
# Issue 43, item 4: --help without validator noise. Every subcommand's help of cellsim, servo
# and pattern names each value by its kind and range ("INT in [1, 1000000] (default 20)"), not
# CLI11's validator chain ("INT:INT in [1 - 1000000]=20", "UINT:WHOLE", "FLOAT:finite in").
set -u
bin="$1"
source "$(dirname "$0")/lib.sh"
n=0
for c in cellsim servo pattern; do
  subs=$("$bin/$c" --help | awk '/^Subcommands:/{on=1; next} on && NF{print $1}')
  [ -n "$subs" ] || fail "$c --help lists no subcommand"
  for s in "" $subs; do
    # shellcheck disable=SC2086
    help=$("$bin/$c" $s --help) || fail "$c $s --help: exit $?"
    noise=$(grep -E ':(INT|UINT|FLOAT|TEXT|WHOLE|POSITIVE|NONNEGATIVE|finite)\b|\[[^] ]+ - [^] ]+\]|(TEXT|INT|UINT|FLOAT)=' <<<"$help" |
            grep -E '^\s+-' | head -3)
    [ -z "$noise" ] || fail "$c $s --help: $noise"
    n=$((n + 1))
  done
done
grep -q -- "--runs INT in \[1, 1000000\] (default 20)" <<<"$("$bin/cellsim" campaign --help)" ||
  fail "cellsim campaign --help does not say --runs' range and default"
echo "help: $n pages, each value by its kind, range and default"
