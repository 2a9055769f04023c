#!/usr/bin/env bash
# Issue 43: every command's exit code follows one table (common/exit_codes.hpp,
# README.md): converged 0, refused 1, usage 2, diverged 4, capped 5, not taught 7, and
# `cellsim serve`'s session end the same way. A script or a Slurm job tells them apart.
set -u
bin="$1"; src="$2"
source "$(dirname "$0")/lib.sh"
source "$src/tests/closed_loop/services.sh"  # claim_domain
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
expect() {  # expect CODE WHAT COMMAND...
  local code="$1" what="$2"; shift 2
  "$@" >"$tmp/out" 2>&1; local rc=$?
  [ "$rc" -eq "$code" ] || fail "$what: exit $rc, not $code: $(tail -2 "$tmp/out")"
}
plane="$src/sim/scenarios/plane.yaml"
expect 0 "converged" "$bin/cellsim" experiment "$plane" --z-hat 0.9 --features ideal --no-plot -o "$tmp/run"
# the output names what was written, and no plot under --no-plot
grep -q "trace: $tmp/run/trace.csv" "$tmp/out" && [ -s "$tmp/run/trace.csv" ] || fail "no trace named: $(cat "$tmp/out")"
! grep -q "velocities.png" "$tmp/out" || fail "--no-plot named plots it never wrote: $(tail -1 "$tmp/out")"
expect 5 "capped" "$bin/cellsim" experiment "$plane" --z-hat 0.9 --features ideal --no-plot --max-iterations 5
expect 4 "diverged" "$bin/cellsim" experiment "$src/sim/scenarios/fig5.yaml" --features ideal --no-plot --divergence-ratio 1.2
expect 1 "refused (outside the workspace)" "$bin/cellsim" experiment "$plane" --initial "0 0 900 0 0 0" --no-plot
expect 2 "usage" "$bin/cellsim" experiment "$plane" --no-such-flag
expect 2 "usage (servo)" "$bin/servo" decode
# --help without the common bound every number is checked against (the options' own ranges stay)
for sub in "cellsim experiment" "cellsim render" "cellsim campaign" "servo run"; do
  # shellcheck disable=SC2086
  help=$("$bin/"$sub --help) || fail "$sub --help"
  ! grep -q "1e+09" <<<"$help" || fail "$sub --help shows the common bound: $(grep -m1 1e+09 <<<"$help")"
done
grep -q -- "--z-hat FLOAT in \[0, 100\]" <<<"$("$bin/cellsim" experiment --help)" || fail "--z-hat's own range is gone from --help"
for tool in cellsim servo; do
  expect 0 "$tool --version" "$bin/$tool" --version
  grep -qx "$tool [0-9]*\.[0-9]*\.[0-9]*" "$tmp/out" || fail "$tool --version said: $(cat "$tmp/out")"
done
# a camera looking away from the wall at its desired pose: nothing to teach on
sed -e "s#\.\./\.\./#$src/#g" \
    -e 's#^desired_pose: .*#desired_pose: {position_m: [0.5, 0.0, 0.4], look_at_m: [-1.4, 0.0, 0.4]}#' "$plane" >"$tmp/away.yaml"
expect 7 "not taught" "$bin/cellsim" experiment "$tmp/away.yaml" --z-hat 0.9 --no-plot
grep -q "not taught: teach frame has no decodable spots: no run" "$tmp/out" || fail "not taught said: $(cat "$tmp/out")"
! grep -q "send TEACH again\|final error" "$tmp/out" || fail "an in-process run that never ran spoke of TEACH or a final error"
# the service: the frame cap is the session asked for, unless convergence was asked to end it
claim_domain
export ROS_DOMAIN_ID="$cell_domain"
# loopback only, whatever the caller's ROS 2 environment says
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
unset ROS_STATIC_PEERS ROS_LOCALHOST_ONLY
expect 0 "serve to its frame cap" timeout 60 "$bin/cellsim" serve "$plane" --max-frames 3 --mode realtime
expect 5 "serve capped before converging" timeout 60 "$bin/cellsim" serve "$plane" --autorun --exit-on-converged \
  --max-frames 3 --mode realtime
echo "exit codes: converged 0, refused 1, usage 2, diverged 4, capped 5, not taught 7; serve's cap 0 or 5"
