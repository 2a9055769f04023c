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
# --quiet and --verbose, before or after the subcommand; progress in a log file is whole lines
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
plane="$(dirname "$0")/../../sim/scenarios/plane.yaml"
campaign=("$bin/cellsim" campaign "$plane" --runs 2 --models desired --threads 1 --no-plot)
"${campaign[@]}" -o "$tmp/a" 2>"$tmp/a.err" >/dev/null || fail "campaign: exit $?"
grep -q "campaign plane: 2/2 runs" "$tmp/a.err" || fail "no progress line: $(cat "$tmp/a.err")"
grep -q $'\r' "$tmp/a.err" && fail "progress into a file rewrites its line with \\r"
"${campaign[@]}" -o "$tmp/q" -q 2>"$tmp/q.err" >/dev/null || fail "campaign -q: exit $?"
grep -q "runs" "$tmp/q.err" && fail "--quiet still says: $(cat "$tmp/q.err")"
"$bin/cellsim" --verbose "${campaign[@]:1}" -o "$tmp/v" 2>"$tmp/v.err" >/dev/null || fail "campaign --verbose: exit $?"
[ "$(grep -c "campaign plane: run [01], desired: converged after [0-9]* iterations" "$tmp/v.err")" -eq 2 ] ||
  fail "--verbose does not say each run: $(cat "$tmp/v.err")"
one_line_error "-q with -v" "excludes" "$bin/cellsim" -q -v campaign "$plane"
echo "help: --quiet says nothing but results, --verbose each run, progress in a file in whole lines"
