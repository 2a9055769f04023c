#!/usr/bin/env bash
# The outside client drives a run: sim and servo started without --autorun, the client sends
# TEACH, RESET initial and START, and exits 0 only when it hears CONVERGED on rt/servo/status.
set -u
bin="$1"; src="$2"
source "$(dirname "$0")/services.sh"
start_services "$bin" "$src" "--max-frames 1500"
if timeout 240 "$bin/cell_client" --timeout 200; then
  echo "external client: converged"
  exit 0
fi
echo "FAIL: the external client did not see convergence"; tail -5 "$tmp/sim.log" "$tmp/servo.log"
exit 1
