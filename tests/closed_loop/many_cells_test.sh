#!/usr/bin/env bash
# Three cells on one DDS domain, each under its own ROS 2 namespace (--namespace cellN: its
# topics are rt/cellN/...): three cellsim and three servo processes at once, each pair
# converging on its own scenario, none hearing another's twists (issue 11, item 4).
set -u
bin="$1"; src="$2"
source "$(dirname "$0")/services.sh"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
unset ROS_STATIC_PEERS ROS_LOCALHOST_ONLY
claim_domain
export ROS_DOMAIN_ID="$cell_domain"
tmp=$(mktemp -d)
pids=()
trap 'kill -INT "${pids[@]}" 2>/dev/null; sleep 1; kill -KILL "${pids[@]}" 2>/dev/null; rm -rf "$tmp"' EXIT
scenarios=(plane ham plane)
zhat=(0.9 0.6 0.9)
patterns=(marray_20x20_k3_w3 marray_20x20_k3_w3_d3 marray_20x20_k3_w3)  # the one each scenario casts
sims=()
for i in 0 1 2; do
  ns="cell$((i + 1))"
  "$bin/servo" run --namespace "$ns" --pattern "$src/servo/pattern/data/${patterns[$i]}.txt" --z-hat "${zhat[$i]}" \
    > "$tmp/servo_$ns.log" 2>&1 &
  pids+=($!)
  "$bin/cellsim" serve "$src/sim/scenarios/${scenarios[$i]}.yaml" --namespace "$ns" --autorun --exit-on-converged \
    --max-frames 1500 > "$tmp/sim_$ns.log" 2>&1 &
  sims+=($!)
  pids+=($!)
done
status=0
for i in 0 1 2; do
  ns="cell$((i + 1))"
  wait "${sims[$i]}"; rc=$?
  summary=$(grep "twists applied" "$tmp/sim_$ns.log")
  if ! ended_at_goal "$rc" "$tmp/sim_$ns.log"; then
    echo "FAIL: $ns (${scenarios[$i]}) did not converge (exit $rc, $final)"
    tail -n 8 "$tmp/sim_$ns.log" "$tmp/servo_$ns.log"
    status=1
  fi
  # another cell's twists would arrive by the hundred, for frames this cell never awaited (a
  # TEACH resent under load may leave one or two stale answers of its own)
  stale=$(grep -o '[0-9]* stale' <<<"$summary" | awk '{print $1}')
  if ! grep -q " 0 wrong frame," <<<"$summary" || [ "${stale:-999}" -gt 3 ]; then
    echo "FAIL: $ns heard twists not meant for it: $summary"; status=1
  fi
  echo "$ns (${scenarios[$i]}): $final"
done
exit $status
