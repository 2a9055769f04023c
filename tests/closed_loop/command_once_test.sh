#!/usr/bin/env bash
# Issue 43, item 5: a command published once reaches the run, whichever reader matched first.
# The servo starts first and is ready; then a client that sends TEACH, RESET initial and START
# the moment the first reader of rt/sim/control matches (as `ros2 topic pub --once -w 1`); then
# cellsim. The simulator is that topic's one reader (the servo learns the commands it obeyed on
# rt/sim/accepted): when the servo read rt/sim/control too, the client matched it first and
# cellsim never heard the commands.
set -u
bin="$1"; src="$2"
source "$(dirname "$0")/services.sh"
isolated_cell_domain
tmp=$(mktemp -d)
servo= sim= client=
trap 'kill -INT $servo $sim $client 2>/dev/null; sleep 1; kill -KILL $servo $sim $client 2>/dev/null; rm -rf "$tmp"' EXIT
"$bin/servo" run --pattern "$src/servo/pattern/data/marray_20x20_k3_w3.txt" --z-hat 0.9 > "$tmp/servo.log" 2>&1 &
servo=$!
for _ in $(seq 600); do grep -q "servo: ready" "$tmp/servo.log" && break; sleep 0.1; done
grep -q "servo: ready" "$tmp/servo.log" || { echo "FAIL: the servo did not start: $(cat "$tmp/servo.log")"; exit 1; }
"$bin/cell_client" --first-match --timeout 200 > "$tmp/client.log" 2>&1 &
client=$!
for _ in $(seq 600); do grep -q "waiting for" "$tmp/client.log" && break; sleep 0.1; done
"$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --max-frames 1500 > "$tmp/sim.log" 2>&1 &
sim=$!
if wait $client; then
  client=
  grep "sent\|converged" "$tmp/client.log" | tr '\n' ' '; echo
  kill -INT $sim; wait $sim
  sim=
  # cellsim heard the three commands, and the PAUSE the client sends at the end
  grep -q " 4 commands (0 refused)" "$tmp/sim.log" ||
    { echo "FAIL: cellsim's summary: $(tail -2 "$tmp/sim.log")"; exit 1; }
  echo "command once: converged; $(grep -o '[0-9]* commands ([0-9]* refused)' "$tmp/sim.log")"
  exit 0
fi
client=
echo "FAIL: no convergence with commands sent on the first match"
for f in client sim servo; do echo "-- $f"; tail -n 3 "$tmp/$f.log"; done
exit 1
