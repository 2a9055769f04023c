#!/usr/bin/env bash
# Issue 43: the run live in Foxglove. `cellsim serve --foxglove 0` serves the run over
# Foxglove's WebSocket protocol on loopback, and `cellsim bridge` serves any cell on the domain
# the same way; a client of the protocol (ours, as Foxglove speaks it) connects to each,
# subscribes, decodes what it receives, and clients that break the protocol are refused with
# their reasons while it receives on; then Foxglove's own client library watches the served run
# converge.
set -u
bin="$1"; src="$2"
source "$(dirname "$0")/services.sh"
start_services "$bin" "$src" "--autorun --mode realtime --max-frames 3000 --foxglove 0"
"$bin/cellsim" bridge --port 0 > "$tmp/bridge.log" 2>&1 &
bridge=$!
trap 'kill -INT $servo $sim $bridge 2>/dev/null; sleep 1; kill -KILL $servo $sim $bridge 2>/dev/null; rm -rf "$tmp"' EXIT
port_in() {  # the port a log's line names, once it is there
  for _ in $(seq 600); do grep -q "ws://127.0.0.1:" "$1" && break; sleep 0.1; done
  grep -o "ws://127.0.0.1:[0-9]*" "$1" | head -1 | cut -d: -f3
}
for who in sim bridge; do
  port=$(port_in "$tmp/$who.log")
  [ -n "$port" ] || { echo "FAIL: $who said no address: $(cat "$tmp/$who.log")"; exit 1; }
  echo "-- $who (port $port)"
  /usr/bin/python3 "$(dirname "$0")/foxglove_client.py" "$port" || { echo "$who log: $(cat "$tmp/$who.log")"; exit 1; }
done
# Foxglove's own client library (@foxglove/ws-protocol, pinned by tests/interop/mcap's lockfile,
# installed by bin/setup) on the served run: every message decoded with its advertised schema,
# until the servo says CONVERGED
modules="$bin/../mcap-check"
[ -d "$modules/node_modules/@foxglove/ws-protocol" ] || { echo "FAIL: no @foxglove/ws-protocol in $modules (bin/setup installs it)"; exit 1; }
node "$src/tests/interop/mcap/foxglove_client.mjs" "$modules" "$(port_in "$tmp/sim.log")" 120 ||
  { echo "sim log: $(tail -3 "$tmp/sim.log")"; exit 1; }
kill -INT $bridge; wait $bridge
grep -q "cellsim bridge: stopped; [1-9][0-9]* messages sent" "$tmp/bridge.log" ||
  { echo "FAIL: summary: $(tail -1 "$tmp/bridge.log")"; exit 1; }
echo "$(tail -1 "$tmp/bridge.log")"
