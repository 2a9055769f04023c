#!/usr/bin/env bash
# Issue 43: the run live in Foxglove. `cellsim bridge` serves the cell's topics over Foxglove's
# WebSocket protocol on loopback; a client of the protocol (ours, as Foxglove speaks it)
# connects, subscribes, decodes what it receives, and clients that break the protocol are
# refused with their reasons while it receives on.
set -u
bin="$1"; src="$2"
source "$(dirname "$0")/services.sh"
start_services "$bin" "$src" "--autorun --mode realtime --max-frames 3000"
"$bin/cellsim" bridge --port 0 > "$tmp/bridge.log" 2>&1 &
bridge=$!
trap 'kill -INT $servo $sim $bridge 2>/dev/null; sleep 1; kill -KILL $servo $sim $bridge 2>/dev/null; rm -rf "$tmp"' EXIT
for _ in $(seq 600); do grep -q "ws://127.0.0.1:" "$tmp/bridge.log" && break; sleep 0.1; done
port=$(grep -o "ws://127.0.0.1:[0-9]*" "$tmp/bridge.log" | cut -d: -f3)
[ -n "$port" ] || { echo "FAIL: the bridge said no address: $(cat "$tmp/bridge.log")"; exit 1; }
/usr/bin/python3 "$(dirname "$0")/foxglove_client.py" "$port" || { echo "bridge log: $(cat "$tmp/bridge.log")"; exit 1; }
kill -INT $bridge; wait $bridge
grep -q "cellsim bridge: stopped; [1-9][0-9]* messages sent" "$tmp/bridge.log" ||
  { echo "FAIL: summary: $(tail -1 "$tmp/bridge.log")"; exit 1; }
echo "$(tail -1 "$tmp/bridge.log")"
