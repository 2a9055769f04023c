#!/usr/bin/env bash
# The outside client drives a run: sim and servo started without --autorun, the client sends
# TEACH, RESET initial and START, and exits 0 only when it hears CONVERGED on rt/servo/status.
set -u
bin="$1"; src="$2"
export ROS_DOMAIN_ID=$(( $$ % 150 + 50 ))
tmp=$(mktemp -d)
cleanup() { kill -INT $servo $sim 2>/dev/null; sleep 1; kill -KILL $servo $sim 2>/dev/null; rm -rf "$tmp"; }
trap cleanup EXIT
"$bin/servo" run --pattern "$src/servo/pattern/data/marray_20x20_k3_w3.txt" --z-hat 0.9 > "$tmp/servo.log" 2>&1 &
servo=$!
"$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --max-frames 1500 > "$tmp/sim.log" 2>&1 &
sim=$!
if timeout 240 "$bin/cell_client" --timeout 200; then
  echo "external client: converged"
  exit 0
fi
echo "FAIL: the external client did not see convergence"; tail -5 "$tmp/sim.log" "$tmp/servo.log"
exit 1
