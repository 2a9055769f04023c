# Sourced by the closed-loop scripts: starts `servo run` and `cellsim serve` on a domain of
# this test's own, logs in a temporary folder, both stopped (then killed) on exit.
# usage: start_services BIN SRC "cellsim serve arguments..."
start_services() {
  local bin="$1" src="$2" sim_args="$3"
  export ROS_DOMAIN_ID=$(( $$ % 150 + 50 ))
  tmp=$(mktemp -d)
  trap 'kill -INT $servo $sim 2>/dev/null; sleep 1; kill -KILL $servo $sim 2>/dev/null; rm -rf "$tmp"' EXIT
  "$bin/servo" run --pattern "$src/servo/pattern/data/marray_20x20_k3_w3.txt" --z-hat 0.9 > "$tmp/servo.log" 2>&1 &
  servo=$!
  # shellcheck disable=SC2086
  "$bin/cellsim" serve "$src/sim/scenarios/plane.yaml" $sim_args > "$tmp/sim.log" 2>&1 &
  sim=$!
}
