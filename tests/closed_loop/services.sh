# Sourced by the closed-loop scripts: starts `servo run` and `cellsim serve` on a domain of
# this test's own, logs in a temporary folder, both stopped (then killed) on exit.
# usage: start_services BIN SRC "cellsim serve arguments..."
# Sets cell_domain to a domain no other test uses while this shell lives (the same flock
# as watcher.hpp's unique_domain); the lock's descriptor stays open in this shell.
claim_domain() {
  local start=$(( $$ % 200 )) i d
  for ((i = 0; i < 200; i++)); do
    d=$(( 20 + (start + i) % 200 ))
    exec {cell_domain_fd}>"/tmp/cell_dds_domain_$d.lock" || continue
    if flock -n "$cell_domain_fd"; then cell_domain=$d; return 0; fi
    exec {cell_domain_fd}>&-
  done
  cell_domain=$(( 20 + start ))
}

start_services() {
  # tests talk over loopback only, whatever the caller's ROS 2 environment says
  export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
  unset ROS_STATIC_PEERS ROS_LOCALHOST_ONLY
  local bin="$1" src="$2" sim_args="$3"
  claim_domain
  export ROS_DOMAIN_ID="$cell_domain"
  tmp=$(mktemp -d)
  trap 'kill -INT $servo $sim 2>/dev/null; sleep 1; kill -KILL $servo $sim 2>/dev/null; rm -rf "$tmp"' EXIT
  "$bin/servo" run --pattern "$src/servo/pattern/data/marray_20x20_k3_w3.txt" --z-hat 0.9 > "$tmp/servo.log" 2>&1 &
  servo=$!
  # shellcheck disable=SC2086
  "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" $sim_args > "$tmp/sim.log" 2>&1 &
  sim=$!
}

# converged_at_goal SIM_LOG: true when cellsim's summary says the camera ended under 1 mm and
# 0.1 deg from the desired pose; sets `final` to that part of the summary
converged_at_goal() {
  final=$(grep -o 'final error [0-9.]* mm, [0-9.]* deg' "$1")
  local mm deg
  mm=$(awk '{print $3}' <<<"$final"); deg=$(awk '{print $5}' <<<"$final")
  [ -n "$mm" ] && awk -v m="$mm" -v d="$deg" 'BEGIN{exit !(m < 1 && d < 0.1)}'
}

# ended_at_goal EXIT_CODE SIM_LOG: cellsim exited 0 and its summary says converged_at_goal;
# sets `final` whatever the outcome ("no final error" when the summary has none), for the
# message that says why not
ended_at_goal() {
  local at_goal=0
  converged_at_goal "$2" && at_goal=1
  final=${final:-no final error}
  [ "$1" -eq 0 ] && [ "$at_goal" -eq 1 ]
}

# A test's own cell: loopback discovery whatever the caller's environment, no static peers,
# no enclave override, and a domain no other test of this machine holds (ROS_DOMAIN_ID).
isolated_cell_domain() {
  export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
  unset ROS_STATIC_PEERS ROS_LOCALHOST_ONLY ROS_SECURITY_ENCLAVE_OVERRIDE
  claim_domain
  export ROS_DOMAIN_ID="$cell_domain"
}
