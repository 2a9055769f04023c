#!/usr/bin/env bash
# Discovery through Fast DDS's Discovery Server (Debian fastdds-tools: `fastdds discovery`),
# selected by ROS_DISCOVERY_SERVER as ROS 2 does (issue 11, item 4). With
# ROS_AUTOMATIC_DISCOVERY_RANGE=OFF the server is the only way the two services can find each
# other: without it they never meet, with it the run converges. Loopback only.
set -u
bin="$1"; src="$2"
# Issue 40, item 12: "OFF finds nobody" held only on a machine where no other DDS application
# used the domain this test drew: another cell on that domain (its LOCALHOST participants probe
# every participant port of it on 127.0.0.1) was found, and its servo taken for ours. The test
# runs in network and mount namespaces of its own (loopback only, a /dev/shm of its own), so no
# participant outside it can reach it; where namespaces cannot be made it runs as before, and
# says so.
# A foreign servo (LOCALHOST) is started outside, on the very domain the test draws: the
# test holds only if it cannot reach it.
source "$(dirname "$0")/services.sh"
if [ -z "${CELL_DISCOVERY_ISOLATED:-}" ]; then
  if unshare --net --mount --propagation private true 2>/dev/null; then
    claim_domain
    ROS_DOMAIN_ID="$cell_domain" ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST "$bin/servo" run \
      --pattern "$src/servo/pattern/data/marray_20x20_k3_w3.txt" --z-hat 0.9 >/dev/null 2>&1 &
    export CELL_FOREIGN_SERVO=$! CELL_DISCOVERY_DOMAIN="$cell_domain"
    exec unshare --net --mount --propagation private bash -c \
      'ip link set lo up && mount -t tmpfs -o size=1g tmpfs /dev/shm && CELL_DISCOVERY_ISOLATED=1 exec bash "$0" "$@"' \
      "$0" "$@"
  fi
  echo "note: no network namespace here: another DDS application on this test's domain could reach it"
fi
# the server itself (`fastdds discovery` is a wrapper that would outlive a signal to it)
server=$(command -v fast-discovery-server) || { echo "SKIP: no fast-discovery-server (Debian fastdds-tools)"; exit 77; }
unset ROS_STATIC_PEERS ROS_LOCALHOST_ONLY ROS_DISCOVERY_SERVER
export ROS_AUTOMATIC_DISCOVERY_RANGE=OFF
# the domain claimed outside (its lock inherited), or one claimed now
if [ -n "${CELL_DISCOVERY_DOMAIN:-}" ]; then cell_domain=$CELL_DISCOVERY_DOMAIN; else claim_domain; fi
export ROS_DOMAIN_ID="$cell_domain"
port=$(( 12000 + cell_domain ))
tmp=$(mktemp -d)
pids=()
[ -n "${CELL_FOREIGN_SERVO:-}" ] && pids+=("$CELL_FOREIGN_SERVO")
trap 'kill -INT "${pids[@]}" 2>/dev/null; sleep 1; kill -KILL "${pids[@]}" 2>/dev/null; rm -rf "$tmp"' EXIT
pattern="$src/servo/pattern/data/marray_20x20_k3_w3.txt"

# without a server: OFF finds nobody, autorun waits for a servo that never appears
"$bin/servo" run --pattern "$pattern" --z-hat 0.9 > "$tmp/servo0.log" 2>&1 &
pids+=($!)
timeout 8 "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --autorun --exit-on-converged --max-frames 600 \
  > "$tmp/sim0.log" 2>&1
grep -q " 0 frames, 0 twists applied" "$tmp/sim0.log" || { echo "FAIL: OFF discovered the servo without a server"; tail -2 "$tmp/sim0.log"; exit 1; }
kill -INT "${pids[@]}" 2>/dev/null; wait "${pids[@]}" 2>/dev/null; pids=()

"$server" -i 0 -l 127.0.0.1 -p "$port" > "$tmp/server.log" 2>&1 &
pids+=($!)
export ROS_DISCOVERY_SERVER="127.0.0.1:$port"
"$bin/servo" run --pattern "$pattern" --z-hat 0.9 > "$tmp/servo.log" 2>&1 &
pids+=($!)
timeout 120 "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" --autorun --exit-on-converged --max-frames 800 \
  > "$tmp/sim.log" 2>&1; rc=$?
if ! ended_at_goal "$rc" "$tmp/sim.log"; then
  echo "FAIL: no convergence through the discovery server (exit $rc, $final)"
  tail -n 8 "$tmp/sim.log" "$tmp/servo.log" "$tmp/server.log"
  exit 1
fi
echo "discovery server: OFF alone found nobody; through the server: $final"
