#!/usr/bin/env bash
# Discovery through Fast DDS's Discovery Server (Debian fastdds-tools: `fastdds discovery`),
# selected by ROS_DISCOVERY_SERVER as ROS 2 does (issue 11, item 4). With
# ROS_AUTOMATIC_DISCOVERY_RANGE=OFF the server is the only way the two services can find each
# other: without it they never meet, with it the run converges. Loopback only.
set -u
bin="$1"; src="$2"
source "$(dirname "$0")/services.sh"
# the server itself (`fastdds discovery` is a wrapper that would outlive a signal to it)
server=$(command -v fast-discovery-server) || { echo "SKIP: no fast-discovery-server (Debian fastdds-tools)"; exit 77; }
unset ROS_STATIC_PEERS ROS_LOCALHOST_ONLY ROS_DISCOVERY_SERVER
export ROS_AUTOMATIC_DISCOVERY_RANGE=OFF
claim_domain
export ROS_DOMAIN_ID="$cell_domain"
port=$(( 12000 + cell_domain ))
tmp=$(mktemp -d)
pids=()
trap 'kill -INT "${pids[@]}" 2>/dev/null; sleep 1; kill -KILL "${pids[@]}" 2>/dev/null; rm -rf "$tmp"' EXIT
pattern="$src/servo/pattern/data/marray_20x20_k3_w3.txt"

# without a server: OFF finds nobody, autorun waits for a servo that never appears
"$bin/servo" run --pattern "$pattern" --z-hat 0.9 > "$tmp/servo0.log" 2>&1 &
pids+=($!)
timeout 8 "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --autorun --exit-on-converged --max-frames 600 \
  > "$tmp/sim0.log" 2>&1
grep -q " 0 frames, 0 twists applied" "$tmp/sim0.log" || { echo "FAIL: OFF discovered the servo without a server"; tail -2 "$tmp/sim0.log"; exit 1; }
kill -INT "${pids[@]}" 2>/dev/null; wait 2>/dev/null; pids=()

"$server" -i 0 -l 127.0.0.1 -p "$port" > "$tmp/server.log" 2>&1 &
pids+=($!)
export ROS_DISCOVERY_SERVER="127.0.0.1:$port"
"$bin/servo" run --pattern "$pattern" --z-hat 0.9 > "$tmp/servo.log" 2>&1 &
pids+=($!)
timeout 120 "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --autorun --exit-on-converged --max-frames 800 \
  > "$tmp/sim.log" 2>&1; rc=$?
if [ "$rc" -ne 0 ] || ! converged_at_goal "$tmp/sim.log"; then
  echo "FAIL: no convergence through the discovery server (exit $rc, $final)"; tail -3 "$tmp/sim.log" "$tmp/servo.log" "$tmp/server.log"
  exit 1
fi
echo "discovery server: OFF alone found nobody; through the server: $final"
